"""Campaign throughput: trials per second on a local process pool.

Runs the first trials of examples/campaigns/pushes.yaml into fresh directories and
prints the median over a few repeats.

    python bench/bench_campaign.py [--trials 8] [--processes 2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

from gracenav.campaign import load_campaign, run_campaign

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    base = load_campaign(HERE.parent / "examples" / "campaigns" / "pushes.yaml")
    campaign = dataclasses.replace(base, trials=args.trials)
    rates = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run_campaign(campaign, Path(tmp) / "out", processes=args.processes)
            rates.append(args.trials / (time.perf_counter() - t0))
    print(
        f"campaign pushes.yaml, {args.trials} trials, {args.processes} processes: "
        f"median {statistics.median(rates):.3f} trials/s over {args.repeats} repeats "
        f"({', '.join(f'{r:.3f}' for r in rates)})"
    )


if __name__ == "__main__":
    main()
