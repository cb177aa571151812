"""Replanning for moving obstacles: incremental repair against a full search.

For the paper's 3.5 m × 3.5 m free area and the 50 m × 50 m synthetic office (5 cm
cells, one pass at spacing d), a person (disc of 0.25 m, 1 m/s) walks a straight line
past a random goal's tree; every 0.1 s of its walk the robot's view changes. Each step
is timed two ways, interleaved:

* ``repair``: :func:`gracenav.planning.repair.timed_repair`, what the hybrid controller
  runs: the compiled blocking test, then the repair of the previous step's tree;
* ``full search``: the same blocking test, then ``plan_tree`` from scratch on the
  graph without the blocked policies (the CSR masked and transposed, then the
  compiled search): the peer a controller without repair would run;
* ``search alone``: ``plan_tree`` on the unmasked graph's kept reverse, a lower
  bound of any full search (one that skipped blocked policies inside the search
  would cost at least this), and the blocking test alone.

Both trees are checked equal (costs exactly) at every step. Prints medians and the
ratio; the first step (the person is first seen) is included.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_replan.py [--skip-large]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import time

import numpy as np
import scipy.sparse as sp
from bench_library import get_palette

from gracenav.execution.obstacles import ObstacleTracker
from gracenav.library import build_library
from gracenav.planning import plan_tree
from gracenav.planning.graph import build_graph
from gracenav.planning.repair import KnownObstacle, blocked_policies, timed_repair
from gracenav.world import load_map, office_map


def _full(graph, goal: int, blocked: np.ndarray):
    a = graph.csr("time")
    keep = ~blocked
    m = sp.diags(keep.astype(float)) @ a @ sp.diags(keep.astype(float))
    m = sp.csr_matrix(m)
    m.eliminate_zeros()
    # Zero-cost entries do not exist (durations > 0), so elimination drops only masks.
    tree = plan_tree(m.tocsc(), goal)
    if blocked[goal]:
        tree.cost_to_go[:] = np.inf
    return tree


def run(name: str, world, walks: int, seed: int) -> None:
    palette, note = get_palette()
    lib = build_library(palette, world, footprint_radius=0.2, max_halvings=0)
    graph = build_graph(lib)
    tracker = ObstacleTracker(lib, graph, (), _sensing())  # compiles the kernels
    rng = np.random.default_rng(seed)
    trims = lib.trim_indices()
    rep, full, alone, block = [], [], [], []
    for _ in range(walks):
        goal = int(rng.choice(trims))
        base = plan_tree(graph.csc("time"), goal)
        reach = np.flatnonzero(np.isfinite(base.cost_to_go))
        mid = lib.start_xy[int(rng.choice(reach))]
        ang = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(ang), np.sin(ang)])
        tree, was = base, np.zeros(len(lib), dtype=bool)
        for k in range(30):  # 3 s of walking through the tree's middle
            c = mid + u * (k * 0.1 - 1.5)
            ob = KnownObstacle(0, (float(c[0]), float(c[1])), (float(u[0]), float(u[1])), 0.25)
            t0 = time.perf_counter()
            tree, blocked, _, _ = timed_repair(
                tree, graph, lib, tracker.swept, [ob], was, footprint=0.2, sensing=_sensing()
            )
            rep.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            ref = _full(graph, goal, blocked)
            full.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            plan_tree(graph.csc("time"), goal)
            alone.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            blocked_policies(lib, tracker.swept, [ob], footprint=0.2, sensing=_sensing())
            block.append(time.perf_counter() - t0)
            fin = np.isfinite(ref.cost_to_go)
            assert np.array_equal(fin, np.isfinite(tree.cost_to_go))
            assert np.array_equal(ref.cost_to_go[fin], tree.cost_to_go[fin])
            was = blocked
    mr, mf = statistics.median(rep), statistics.median(full)
    print(
        f"{name}: {len(lib):,} policies, {graph.num_edges:,} edges ({note}); "
        f"{len(rep)} steps: repair median {1e3 * mr:.2f} ms (max {1e3 * max(rep):.2f}), "
        f"full search median {1e3 * mf:.2f} ms: {mf / mr:.1f}× faster; "
        f"search alone {1e3 * statistics.median(alone):.2f} ms, blocking test alone "
        f"{1e3 * statistics.median(block):.2f} ms"
    )


def _sensing():
    from gracenav.planning.repair import ObstacleSensing

    return ObstacleSensing()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--skip-large", action="store_true", help="only the 3.5 m area")
    ap.add_argument("--walks", type=int, default=10)
    args = ap.parse_args()
    free = load_map({"bounds": [[0.0, 0.0], [3.5, 3.5]], "obstacles": [], "resolution": 0.05})
    run("free 3.5 m", free, args.walks, 0)
    if not args.skip_large:
        run("office 50 m", office_map(50.0, 0.05, seed=0), args.walks, 1)


if __name__ == "__main__":
    main()
