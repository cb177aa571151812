"""Maneuvers designed online by their reach: gracenav on the random pairs, pair by pair.

Runs gracenav (``planner.kind: gracenav``) on the first ``--trials`` trials of
``examples/campaigns/random_pairs.yaml`` (the campaign's own draws,
:func:`gracenav.campaign.runner.trial_result`) once for each reach of ``--reach``
(``AHEAD:ACROSS[:LONGEST]``: the policies a start at rest may be launched onto lie 0.3 m
to AHEAD m ahead of it and at most ACROSS m across,
:class:`gracenav.execution.launch.LaunchOptions`; starts and ends designed online last
at most LONGEST s, ``LaunchOptions.longest`` and
:class:`gracenav.execution.arrival.ArrivalOptions` ``.longest``, by default
:data:`gracenav.execution.online.LONGEST`; the first reach is the reference), on a pool
of ``--processes`` worker processes. For each reach it prints the median time to goal
(trials that reached it), the medians of max and p95 jerk (true state), the largest
lean, the smallest clearance, verified recoveries and fallbacks and the median wall time
of a trial (its designs online included), then against the reference pair by pair: runs
sooner and later (by more than a tick), the sum of the differences and the largest loss.
``--jsonl FILE`` also writes every row. Progress goes to stderr, the tables to stdout.

    OPENBLAS_NUM_THREADS=1 python bench/bench_launches.py [--trials 200]
        [--reach 3.5:1.2:4.5,3.5:1.2:6.5] [--processes 2] [--jsonl rows.jsonl]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import functools
import json
import math
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
PAIRS = HERE.parent / "examples" / "campaigns" / "random_pairs.yaml"
TICK = 1.0 / 1024


def _reach(text: str) -> list[tuple[float, float, float]]:
    from gracenav.execution.online import LONGEST

    out = []
    for item in text.split(","):
        try:
            ahead, across, *rest = (float(v) for v in item.split(":"))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"a reach is AHEAD:ACROSS[:LONGEST] (m, m, s), got {item!r}"
            ) from None
        longest = rest[0] if rest else LONGEST
        if len(rest) > 1 or not all(map(math.isfinite, (ahead, across, longest))):
            raise argparse.ArgumentTypeError(
                f"a reach is AHEAD:ACROSS[:LONGEST] (m, m, s), got {item!r}"
            )
        if not (ahead > 0.3 and across > 0 and 0.5 <= longest <= 12.0):
            raise argparse.ArgumentTypeError(
                f"a reach needs AHEAD > 0.3 m, ACROSS > 0 m and LONGEST in 0.5..12 s, got {item!r}"
            )
        out.append((ahead, across, longest))
    return out


#: The end options' class, before a worker's first trial replaces it.
_ORIGINAL: dict[str, Any] = {}


def _trial(reach: tuple[float, float, float], index: int) -> dict[str, Any]:
    """gracenav's row of trial ``index`` with starts and ends of ``reach`` (in a
    worker)."""
    import gracenav.execution.arrival as arrival
    import gracenav.execution.controller as controller
    from gracenav.campaign import load_campaign
    from gracenav.campaign.runner import trial_result
    from gracenav.execution.launch import LaunchOptions

    ahead, across, longest = reach
    ends_options = _ORIGINAL.setdefault("ends", arrival.ArrivalOptions)
    starts = functools.partial(LaunchOptions, ahead=(0.3, ahead), across=across, longest=longest)
    ends = functools.partial(ends_options, longest=longest)
    setattr(controller, "LaunchOptions", starts)  # noqa: B010
    setattr(arrival, "ArrivalOptions", ends)  # noqa: B010
    t0 = time.perf_counter()
    row, _ = trial_result(load_campaign(PAIRS), index, "gracenav")
    row["wall_s"] = time.perf_counter() - t0
    keep = {k: v for k, v in row.items() if v is None or isinstance(v, int | float | str | bool)}
    return {"reach": list(reach), **keep}


def _summary(rows: list[dict[str, Any]]) -> str:
    reached = [r for r in rows if r["reached_goal"]]
    if not reached:
        return f"0 of {len(rows)} reached"
    return (
        f"{len(reached)} of {len(rows)} reached, median "
        f"{statistics.median(r['time_s'] for r in reached):.2f} s, max / p95 jerk "
        f"{statistics.median(r['max_jerk_mps3'] for r in reached):.2f} / "
        f"{statistics.median(r['p95_jerk_mps3'] for r in reached):.2f} m/s³, largest lean "
        f"{max(r['max_lean_deg'] for r in reached):.3f}°, smallest clearance "
        f"{min(r['min_clearance_m'] for r in reached):.3f} m, recoveries "
        f"{sum(r['verified_recoveries'] for r in rows)}, fallbacks "
        f"{sum(r['fallbacks'] for r in rows)}, wall time per trial (median) "
        f"{statistics.median(r['wall_s'] for r in rows):.1f} s"
    )


def _against(rows: list[dict[str, Any]], ref: list[dict[str, Any]]) -> str:
    both = [
        (r["time_s"] - q["time_s"], r["trial"])
        for r, q in zip(rows, ref, strict=True)
        if r["reached_goal"] and q["reached_goal"]
    ]
    sooner = sum(d < -TICK for d, _ in both)
    later = [(d, t) for d, t in both if d > TICK]
    worst = max(later, default=(0.0, -1))
    return (
        f"against the first: {sooner} sooner, {len(later)} later of {len(both)}, "
        f"{sum(d for d, _ in both):+.2f} s in all"
        + (f", largest loss {worst[0]:.2f} s (trial {worst[1]})" if later else "")
    )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--trials", type=int, default=40, help="random pairs trials (default 40)")
    ap.add_argument(
        "--reach",
        type=_reach,
        default=_reach("3.5:1.2:4.5,3.5:1.2:6.5"),
        metavar="AHEAD:ACROSS[:LONGEST],...",
        help="reaches of starts (m) and of starts and ends (s), the first the reference "
        "(default 3.5:1.2:4.5,3.5:1.2:6.5)",
    )
    ap.add_argument("--processes", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--jsonl", type=Path, default=None, help="also write every row here")
    args = ap.parse_args()
    if not 1 <= args.trials <= 200:
        ap.error(f"--trials must be 1..200 (the campaign's trials), got {args.trials}")
    if args.processes < 1:
        ap.error(f"--processes must be at least 1, got {args.processes}")
    jobs = [(reach, i) for reach in args.reach for i in range(args.trials)]
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.processes) as pool:
        for k, row in enumerate(pool.map(_trial, *zip(*jobs, strict=True))):
            rows.append(row)
            print(
                f"launches: {k + 1}/{len(jobs)} ({time.perf_counter() - t0:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
    if args.jsonl is not None:
        args.jsonl.write_text("".join(json.dumps(r) + "\n" for r in rows))
    by_reach = [rows[k * args.trials : (k + 1) * args.trials] for k in range(len(args.reach))]
    print(f"random pairs: {PAIRS.relative_to(HERE.parent)}, first {args.trials} trials, gracenav")
    for k, (reach, group) in enumerate(zip(args.reach, by_reach, strict=True)):
        print(
            f"  reach {reach[0]:g} m ahead, {reach[1]:g} m across, at most {reach[2]:g} s: "
            f"{_summary(group)}"
        )
        if k:
            print(f"    {_against(group, by_reach[0])}")


if __name__ == "__main__":
    main()
