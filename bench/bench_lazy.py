"""The lazy single-goal tree: the first plan and the local replan after a push.

On the 50 m × 50 m synthetic office (5 cm cells, one pass at spacing d), trips between
random trim policies at least 20 m apart in the office's largest strongly connected
component. For each trip:

* ``first plan``: a :class:`gracenav.planning.LazyPolicyTree` toward the goal, then
  ``settle(rows, best=True)`` on the non-capture policies whose S contains the start
  trim's start state (what :meth:`HybridController.best_policy` does), side by side
  with ``plan_path`` from those rows (forward A*);
* ``push``: every few policies along the planned path, the state at a policy's start
  with its velocity perturbed by σ = 5 cm/s (each component); the policies whose S
  contains it are settled (``best``) on the tree that has answered the first query
  only (``fresh``; the first query is rerun, untimed, before each push) and on one tree
  that keeps everything from push to push along the trip (``kept``), side by side with
  ``plan_path(rows, via=path)`` (forward A* joining the old path);
* the whole tree on the stored reversed graph (``plan_tree(graph.csc())``), what the
  controller computes on this map, and on edges generated from the lattice.

Every answer is checked against the whole tree (cost exactly, the same best row). Times
are medians and maxima over the pushes; each method is timed on the same push, one
after the other.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_lazy.py [--trips 3] [--pushes 13]
        [--sigma 0.05]

The 100 m hall runs in ``bench/bench_scale.py --lazy`` (its own process, peak RSS).
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import time
from typing import Any

import numpy as np
from bench_library import get_palette

from gracenav.library import PolicyLibrary, build_library
from gracenav.planning import LazyPolicyTree, plan_path, plan_tree
from gracenav.planning.graph import PreparesGraph, build_graph

SIGMA = 0.05  # m/s, the push model of docs/design/memory.md


def captured(lib: PolicyLibrary, state: np.ndarray) -> np.ndarray:
    """Non-capture rows whose S contains ``state`` (all of them if only capture
    regulators do), as the hybrid controller's best policy considers them."""
    hits = lib.start_domain_contains(state[None, :])
    idx = hits.indices[hits.indptr[0] : hits.indptr[1]].astype(np.int64)
    nav = idx[~lib.types.is_capture[lib.type_index[idx]]]
    return nav if nav.size else idx


def push_rows(
    lib: PolicyLibrary,
    path: np.ndarray,
    count: int,
    rng: np.random.Generator,
    sigma: float = SIGMA,
) -> list[np.ndarray]:
    """Rows captured by ``count`` pushed states along ``path`` (start states of its
    policies, velocity perturbed by ``sigma``), skipping states nothing captures."""
    out = []
    picks = np.linspace(1, max(1, path.size - 3), count).round().astype(int)
    for k in picks:
        state = lib.start_state[path[k]].copy()
        state[2:] += rng.normal(0.0, sigma, 2)
        rows = captured(lib, state)
        if rows.size:
            out.append(rows)
    return out


def best_row(tree: Any, rows: np.ndarray) -> tuple[int, float]:
    cost = tree.cost_to_go[rows]
    k = int(np.argmin(cost))
    return int(rows[k]), float(cost[k])


def trip(
    graph: PreparesGraph,
    start: int,
    goal: int,
    pushes: int,
    rng: np.random.Generator,
    whole: Any = None,
    sigma: float = SIGMA,
) -> dict[str, Any]:
    """Times (s) of the first plan and of every push; checks against ``whole``."""
    lib = graph.library
    first = captured(lib, lib.start_state[start])
    out: dict[str, Any] = {"fresh": [], "kept": [], "via": [], "expanded_fresh": []}
    t0 = time.perf_counter()
    tree = LazyPolicyTree(graph, goal)
    tree.settle(first, best=True)
    out["first_lazy"] = time.perf_counter() - t0
    out["first_expanded"] = tree.expanded
    t0 = time.perf_counter()
    astar = plan_path(graph, first, goal)
    out["first_astar"] = time.perf_counter() - t0
    row, cost = best_row(tree, first)
    if whole is not None:
        assert (row, cost) == best_row(whole, first), "first plan differs from the whole tree"
    assert np.isclose(astar.cost, cost, rtol=1e-12), (astar.cost, cost)
    path = np.array(tree.path_from(row), dtype=np.int64)
    via = plan_path(graph, row, goal)
    kept = tree
    for rows in push_rows(lib, path, pushes, rng, sigma):
        fresh = LazyPolicyTree(graph, goal)
        fresh.settle(first, best=True)
        before = fresh.expanded
        t0 = time.perf_counter()
        fresh.settle(rows, best=True)
        out["fresh"].append(time.perf_counter() - t0)
        out["expanded_fresh"].append(fresh.expanded - before)
        t0 = time.perf_counter()
        kept.settle(rows, best=True)
        out["kept"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        replan = plan_path(graph, rows, goal, via=via)
        out["via"].append(time.perf_counter() - t0)
        got = best_row(fresh, rows)
        assert got == best_row(kept, rows)
        if whole is not None:
            assert got == best_row(whole, rows), "push answer differs from the whole tree"
        assert np.isclose(replan.cost, got[1], rtol=1e-12), (replan.cost, got[1])
    return out


def _ms(xs: list[float]) -> str:
    return f"{1e3 * statistics.median(xs):7.1f} (max {1e3 * max(xs):6.1f})"


def main() -> None:
    from scipy.sparse import csgraph

    from gracenav.world import load_map, office_map

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trips", type=int, default=3)
    ap.add_argument("--pushes", type=int, default=13, help="pushes per trip")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sigma", type=float, default=SIGMA, help="push: velocity std (m/s)")
    args = ap.parse_args()
    palette, note = get_palette()
    print(note)
    rng = np.random.default_rng(args.seed)
    here = os.path.dirname(os.path.abspath(__file__))
    # The 3.5 m area: the hybrid controller keeps its stored reversed graph.
    free = load_map(os.path.join(here, "..", "examples", "maps", "free_area_3p5m.yaml"))
    g_free = build_graph(build_library(palette, free, max_halvings=0))
    form = g_free.search_form("time")
    print(f"3.5 m area: search form {'stored' if form is not g_free else 'lattice'}")
    lib = build_library(palette, office_map(50.0, 0.05, seed=0), max_halvings=0)
    graph = build_graph(lib)  # never stores a matrix: the lazy tree and A* generate edges
    stored = build_graph(lib)
    print(f"50 m office: {len(lib)} policies, {graph.num_edges} edges")
    t0 = time.perf_counter()
    csc = stored.csc("time")
    print(f"reversed graph (csc) built in {time.perf_counter() - t0:.2f} s")
    # Compile outside the timings.
    goal0 = int(lib.trim_indices()[0])
    LazyPolicyTree(graph, goal0).settle([0], best=True, budget=100)
    plan_path(graph, 0, goal0)
    plan_tree(csc, goal0)
    plan_tree(graph, goal0)
    _, label = csgraph.connected_components(stored.adjacency, connection="strong")
    trims = lib.trim_indices()
    big = trims[label[trims] == np.argmax(np.bincount(label))]
    res: dict[str, list[float]] = {}
    stored_s: list[float] = []
    implicit_s: list[float] = []
    for _ in range(args.trips):
        while True:
            start, goal = (int(v) for v in rng.choice(big, 2, replace=False))
            if np.linalg.norm(lib.start_xy[start] - lib.start_xy[goal]) >= 20.0:
                break
        t0 = time.perf_counter()
        whole = plan_tree(csc, goal)
        stored_s.append(time.perf_counter() - t0)
        if not implicit_s:  # seconds: once
            t0 = time.perf_counter()
            plan_tree(graph, goal)
            implicit_s.append(time.perf_counter() - t0)
        out = trip(graph, start, goal, args.pushes, rng, whole, args.sigma)
        for k, v in out.items():
            res.setdefault(k, []).extend(v if isinstance(v, list) else [v])
    n = len(res["fresh"])
    print(f"{args.trips} trips, {n} pushes (σ = {args.sigma * 100:g} cm/s), ms median (max):")
    print(f"  first plan, lazy tree        {_ms(res['first_lazy'])}")
    print(f"  first plan, plan_path (A*)   {_ms(res['first_astar'])}")
    print(f"  push, lazy tree (fresh)      {_ms(res['fresh'])}")
    print(f"  push, lazy tree (kept)       {_ms(res['kept'])}")
    print(f"  push, plan_path(via=)        {_ms(res['via'])}")
    print(f"  whole tree, stored reversed  {_ms(stored_s)}")
    print(f"  whole tree, lattice edges    {_ms(implicit_s)}")
    print(
        f"  expanded: first plan median {statistics.median(res['first_expanded']):.0f}, "
        f"push (fresh) median {statistics.median(res['expanded_fresh']):.0f} "
        f"(max {max(res['expanded_fresh']):.0f})"
    )
    ratio = statistics.median(res["via"]) / statistics.median(res["fresh"])
    print(f"  plan_path(via=) / lazy (fresh), medians: {ratio:.1f}x; target <= 20 ms")


if __name__ == "__main__":
    main()
