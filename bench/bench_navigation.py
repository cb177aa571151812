"""Planning and execution speed.

Targets: the single-goal tree in <= 1 ms on the paper-size library (3.5 m x 3.5 m
free area, d = 0.5 m; the paper: 50 ms); a point-to-point episode simulated
>= 50x faster than real time; the decoupled baseline's plan (grid path, shortcut,
smoothing and timing) across the 5 m room with a central box well under 1 s (tens of
ms on one core, once compiled).

    OPENBLAS_NUM_THREADS=1 python bench/bench_navigation.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import time
from importlib import resources
from pathlib import Path

import numpy as np

from gracenav.baseline import MotionLimits, plan_decoupled
from gracenav.execution import HybridController
from gracenav.library import build_library
from gracenav.palette import load_palette
from gracenav.planning import plan_tree
from gracenav.planning.graph import build_graph
from gracenav.scenarios import load_scenario
from gracenav.sim import state_from_position
from gracenav.world import load_map


def main() -> None:
    pal = load_palette()
    free = load_map({"bounds": [[0.0, 0.0], [3.5, 3.5]], "obstacles": []})
    lib = build_library(pal, free, max_halvings=0)
    graph = build_graph(lib)
    adj = graph.csc("time")  # the reversed graph, kept with the graph
    goals = lib.trim_indices()
    rng = np.random.default_rng(0)
    times = []
    for g in rng.choice(goals, 50):
        t0 = time.perf_counter()
        plan_tree(adj, int(g))
        times.append(time.perf_counter() - t0)
    rows = [
        (
            f"tree on the 3.5 m library ({len(lib)} nodes, {graph.num_edges} edges), median of 50",
            f"{1000 * statistics.median(times):.3f} ms",
        )
    ]
    path = Path(
        str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml")
    )
    sc = load_scenario(path)
    wm = load_map(sc.map_source)
    assert sc.max_halvings is not None, "the Fig. 5 scenario states its halvings"
    lib5 = build_library(pal, wm, max_halvings=sc.max_halvings)
    hc = HybridController(lib5, build_graph(lib5))
    r = pal.params.ball_radius
    hc.run(state_from_position(np.asarray(sc.starts[0]), r), sc.goals)  # compile
    speed = []
    for start in sc.starts:
        x0 = state_from_position(np.asarray(start), r)
        for _ in range(3):
            t0 = time.perf_counter()
            ep = hc.run(x0, sc.goals)
            wall = time.perf_counter() - t0
            speed.append(ep.time[-1] / wall)
    rows.append(
        (
            "Fig. 5 point-to-point episodes, simulated s per wall s (median of 12)",
            f"{statistics.median(speed):.0f}x real time",
        )
    )
    room = load_map(
        {
            "bounds": [[0.0, 0.0], [5.0, 5.0]],
            "resolution": 0.05,
            "obstacles": [{"rectangle": {"min": [2.0, 2.0], "max": [3.0, 3.0]}}],
        }
    )
    limits = MotionLimits(max_speed=0.5, max_acceleration=0.6, max_jerk=1.7)

    def plan() -> float:
        return plan_decoupled(room, (1, 1), (4, 4), footprint_radius=0.2, limits=limits).seconds

    plan()  # compile
    plans = [plan() for _ in range(11)]
    rows.append(
        (
            "decoupled plan across the 5 m box room, (1, 1) -> (4, 4), median of 11",
            f"{1000 * statistics.median(plans):.1f} ms",
        )
    )
    width = max(len(a) for a, _ in rows)
    print(f"{'measure':<{width}}  value")
    for a, b in rows:
        print(f"{a:<{width}}  {b}")


if __name__ == "__main__":
    main()
