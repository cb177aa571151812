"""Campaign throughput: trials per second on a local process pool.

Runs the first trials of a campaign (default examples/campaigns/pushes.yaml) into
fresh directories, for each of its planners on its own, and prints the median over a
few repeats. A trial is one (planner, trial) row; the first trials of a worker include
its palette load and library build.

    OPENBLAS_NUM_THREADS=1 python bench/bench_campaign.py [--trials 20] [--processes 2]
        [--repeats 3] [--campaign FILE] [--planners gracenav decoupled]
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
    ap.add_argument(
        "--campaign", type=Path, default=HERE.parent / "examples" / "campaigns" / "pushes.yaml"
    )
    ap.add_argument("--planners", nargs="*", default=None, help="default: the campaign's")
    args = ap.parse_args()
    base = load_campaign(args.campaign)
    for planner in args.planners or base.planners:
        campaign = dataclasses.replace(base, trials=args.trials, planners=(planner,))
        rates = []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                run_campaign(campaign, Path(tmp) / "out", processes=args.processes)
                rates.append(args.trials / (time.perf_counter() - t0))
        print(
            f"campaign {args.campaign.name}, planner {planner}, {args.trials} trials, "
            f"{args.processes} processes: median {statistics.median(rates):.3f} trials/s "
            f"over {args.repeats} repeats ({', '.join(f'{r:.3f}' for r in rates)})"
        )


if __name__ == "__main__":
    main()
