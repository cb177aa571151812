"""Goals at rest off the lattice: how tasks end there.

Seeded goals drawn uniformly on ``examples/maps/room_6m_cluttered.yaml`` (the random
pairs' room), each from the first of four starts at rest near the corners and the west
wall that is at least 2 m away (in turn), with the library instantiated on the map's
lattice (``planner.lattice_anchor: map``), so that the goal is off it and the task ends
with a terminal: a capture regulator at the goal, shifts and a regulator at the goal,
or shifts and a hold next to it (:mod:`gracenav.execution.goals`). Goals the library
refuses (in an obstacle, outside coverage, unreachable from that start) are counted and
skipped.

Per goal it prints the time to goal, the final error, the largest step of the
reference (a regulator's step to the goal; 0 without one), the ball's largest and 95th
percentile jerk from the true state (:mod:`gracenav.execution.smoothness`) and the
largest lean; then the medians. Run it at two commits to compare two ways of ending a
task. ``--noise`` puts position noise of that standard deviation (m) on the measured
state (``simulation.position_noise_std``). Progress goes to stderr, the table to stdout.

    OPENBLAS_NUM_THREADS=1 python bench/bench_goals.py [--goals 24] [--seed 0] [--noise 0.005]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import copy
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from gracenav.errors import PlanningError
from gracenav.scenarios import parse_scenario, run_scenario

HERE = Path(__file__).resolve().parent
PAIRS = HERE.parent / "examples" / "campaigns" / "random_pairs.yaml"
STARTS = ((0.5, 0.5), (5.5, 0.5), (0.6, 3.0), (5.5, 5.5))
MIN_DISTANCE = 2.0  # m between start and goal


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--goals", type=int, default=24, help="goals drawn (default 24)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")
    ap.add_argument(
        "--noise", type=float, default=0.0, help="position noise std (m; default 0: none)"
    )
    args = ap.parse_args()
    base = yaml.safe_load(PAIRS.read_text())["scenario"]
    rng = np.random.default_rng(args.seed)
    (x0, y0), (x1, y1) = base["map"]["bounds"]
    rows: list[dict[str, Any]] = []
    refused = 0
    t0 = time.perf_counter()
    print(
        f"{'goal':>16s} {'start':>12s} {'time (s)':>9s} {'error (mm)':>10s} {'ref step (m)':>12s} "
        f"{'max jerk':>9s} {'p95 jerk':>9s} {'lean (°)':>9s}"
    )
    for k in range(args.goals):
        goal = rng.uniform((x0, y0), (x1, y1))
        start = STARTS[k % len(STARTS)]
        if np.hypot(*(goal - start)) < MIN_DISTANCE:
            start = max(STARTS, key=lambda s: float(np.hypot(*(goal - s))))
        doc = copy.deepcopy(base)
        doc["planner"]["lattice_anchor"] = "map"
        doc["task"]["goal"] = [float(goal[0]), float(goal[1]), 0.0, 0.0]
        doc["task"]["starts"] = [[start[0], start[1], 0.0, 0.0]]
        if args.noise > 0.0:
            doc["simulation"] = {**doc.get("simulation", {}), "position_noise_std": args.noise}
        try:
            result = run_scenario(parse_scenario(doc, source=f"goal {k}"))
        except PlanningError:
            refused += 1
            continue
        run, ep = result.runs[0], result.episodes[0]
        step = float(np.max(np.hypot(*np.diff(ep.reference[:, :2], axis=0).T)))
        row = {
            "reached": run.reached_goal,
            "time": run.time_s,
            "error": (run.final_error_m or 0.0) * 1000.0,
            "step": step,
            "jerk": run.max_jerk_mps3,
            "p95": run.p95_jerk_mps3,
            "lean": run.max_lean_deg,
        }
        rows.append(row)
        print(
            f"({goal[0]:6.3f}, {goal[1]:6.3f}) ({start[0]:4.1f}, {start[1]:4.1f}) "
            f"{row['time']:9.2f} {row['error']:10.2f} {row['step']:12.3f} {row['jerk']:9.2f} "
            f"{row['p95']:9.2f} {row['lean']:9.2f}" + ("" if row["reached"] else "  not reached")
        )
        print(
            f"goal {k + 1}/{args.goals} ({time.perf_counter() - t0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )
    reached = [r for r in rows if r["reached"]]
    print(
        f"goals: {args.goals} drawn (seed {args.seed}, noise {args.noise:g} m), {refused} refused, "
        f"{len(reached)} of {len(rows)} run reached"
    )
    if reached:
        print(
            "medians: "
            + ", ".join(
                f"{name} {statistics.median(r[key] for r in reached):.3f}"
                for name, key in (
                    ("time (s)", "time"),
                    ("error (mm)", "error"),
                    ("reference step (m)", "step"),
                    ("max jerk (m/s³)", "jerk"),
                    ("p95 jerk (m/s³)", "p95"),
                )
            )
            + f"; largest max jerk {max(r['jerk'] for r in reached):.2f} m/s³, largest lean "
            f"{max(r['lean'] for r in reached):.2f}°"
        )


if __name__ == "__main__":
    main()
