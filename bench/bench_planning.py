"""Speed of the single-goal tree against the search alone and another library.

For the paper's 3.5 m × 3.5 m free area (d = 0.5 m, one pass) and the 50 m × 50 m
synthetic office (5 cm cells, one pass), prints the median time of

* ``plan_tree(graph.csc())``: the tree on the reversed graph kept with the graph, by
  the compiled search with one FIFO queue per distinct edge cost;
* the previous ``plan_tree`` (:func:`previous_plan_tree`, kept here as a peer): scipy's
  Dijkstra with predecessors on the same reversed graph, its output converted;
* ``plan_tree(graph.csr())``: the tree with the adjacency converted to CSC on every
  call (how the tree was computed before the reversed graph was kept);
* scipy's Dijkstra alone on a pre-transposed CSR, with predecessors;
* rustworkx's Dijkstra path lengths (no predecessors) on the same reversed graph as a
  ``PyDiGraph`` with float edge weights, if rustworkx is installed (the ``bench``
  extra); otherwise the row says it was skipped.

Before timing, every goal's tree is checked against the previous one: identical
costs-to-go, and next policies that differ only between equally good successors.

Goals are trim policies: on the office, random ones (most lie in rooms, whose trees
are small) and, separately, ones in the largest strongly connected part of the graph
(the corridors: trees over about half of the library). Each measurement is the median
over goals and repeats, the methods interleaved per goal; the one-time cost of
building the reversed graph and its size in bytes per edge are printed too. Timings
on a shared machine are noisy: compare ratios within one run.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_planning.py [--skip-large]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from bench_library import get_palette
from scipy.sparse import csgraph

from gracenav.library import build_library
from gracenav.planning import CostCriterion, PolicyTree, plan_tree
from gracenav.planning.graph import PreparesGraph, build_graph
from gracenav.world import WorldMap, load_map, office_map

try:
    import rustworkx
except ImportError:  # the bench extra is optional
    rustworkx = None


def previous_plan_tree(adjacency: Any, goal: int) -> PolicyTree:
    """``plan_tree`` as it was before the compiled search: scipy's Dijkstra on the
    reversed graph (the CSC input reinterpreted as its transpose in CSR form)."""
    reverse = adjacency.T if adjacency.format == "csc" else adjacency.T.tocsr()
    dist, pred = csgraph.dijkstra(reverse, directed=True, indices=goal, return_predecessors=True)
    nxt = np.asarray(pred, dtype=np.int64)
    nxt[nxt < 0] = -1
    return PolicyTree(goal, nxt, np.asarray(dist, dtype=np.float64), CostCriterion.TIME)


def _check_same_tree(csc: Any, goal: int) -> None:
    """The new tree has the previous costs exactly; next policies may differ only
    between successors that attain the same cost-to-go."""
    new, old = plan_tree(csc, goal), previous_plan_tree(csc, goal)
    if not np.array_equal(new.cost_to_go, old.cost_to_go):
        raise AssertionError(f"goal {goal}: costs-to-go differ from the previous tree")
    fwd = csc.tocsr()
    for i in np.flatnonzero(new.next_policy != old.next_policy):
        for j in (new.next_policy[i], old.next_policy[i]):
            row = slice(fwd.indptr[i], fwd.indptr[i + 1])
            (k,) = np.flatnonzero(fwd.indices[row] == j)
            if fwd.data[row][k] + new.cost_to_go[j] != new.cost_to_go[i]:
                raise AssertionError(f"goal {goal}: next policy of {i} is not optimal")


def _ms(fn: Callable[..., Any], *args: Any) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return 1e3 * (time.perf_counter() - t0)


def _rx_graph(graph: PreparesGraph) -> Any:
    """The reversed graph as a rustworkx PyDiGraph with float weights (edge j → i)."""
    src, dst = graph.edges()
    g = rustworkx.PyDiGraph(multigraph=False)
    g.add_nodes_from(range(graph.num_nodes))
    g.extend_from_weighted_edge_list(
        list(zip(dst.tolist(), src.tolist(), graph.adjacency.data.tolist(), strict=True))
    )
    return g


def _rows(
    label: str, graph: PreparesGraph, rx: Any, goals: np.ndarray, repeats: int
) -> list[list[str]]:
    csr = graph.csr("time")
    csc = graph.csc("time")  # built already (see _graph)
    reverse = csc.T  # the reversed graph in CSR form, made once for the scipy row
    times: dict[str, list[float]] = {"new": [], "prev": [], "old": [], "scipy": [], "rx": []}
    reach = []
    methods: list[tuple[str, Callable[[int], Any]]] = [
        ("new", lambda g: plan_tree(csc, g)),
        ("prev", lambda g: previous_plan_tree(csc, g)),
        ("old", lambda g: plan_tree(csr, g)),
        ("scipy", lambda g: csgraph.dijkstra(reverse, indices=g, return_predecessors=True)),
    ]
    if rx is not None:
        methods.append(
            ("rx", lambda g: rustworkx.digraph_dijkstra_shortest_path_lengths(rx, g, float))
        )
    for k, goal in enumerate(int(g) for g in goals):
        _check_same_tree(csc, goal)
        reach.append(int(np.isfinite(plan_tree(csc, goal).cost_to_go).sum()))
        for r in range(repeats):
            j = (k + r) % len(methods)  # rotate the order: no method always runs first
            for name, fn in methods[j:] + methods[:j]:
                times[name].append(_ms(fn, goal))
    med = {k: statistics.median(v) for k, v in times.items() if v}
    head = f"{label}: {graph.num_nodes} policies, {graph.num_edges} edges"
    head += f", {goals.size} goals, tree sizes {min(reach)}..{max(reach)} (median "
    head += f"{int(statistics.median(reach))})"
    rows = [[head, "", ""]]
    rows.append(["  plan_tree(graph.csc()), reversed graph kept", f"{med['new']:.3f}", "1.00"])
    rows.append(
        [
            "  previous plan_tree(graph.csc()), scipy dijkstra",
            f"{med['prev']:.3f}",
            f"{med['prev'] / med['new']:.2f}",
        ]
    )
    rows.append(
        [
            "  plan_tree(graph.csr()), converted per call",
            f"{med['old']:.3f}",
            f"{med['old'] / med['new']:.2f}",
        ]
    )
    rows.append(
        [
            "  scipy dijkstra alone, pre-transposed CSR",
            f"{med['scipy']:.3f}",
            f"{med['scipy'] / med['new']:.2f}",
        ]
    )
    if "rx" in med:
        rows.append(
            [
                "  rustworkx dijkstra lengths, same reversed graph",
                f"{med['rx']:.3f}",
                f"{med['rx'] / med['new']:.2f}",
            ]
        )
    else:
        rows.append(["  rustworkx: not installed (pip install .[bench]), skipped", "-", "-"])
    return rows


def _graph(wmap: WorldMap) -> tuple[PreparesGraph, str]:
    palette, _ = get_palette()
    graph = build_graph(build_library(palette, wmap, max_halvings=0))
    t_csc = _ms(lambda: graph.csc("time"))
    t_dist = _ms(lambda: graph.csc("distance"))
    t, d = graph.csc("time"), graph.csc("distance")
    a = graph.adjacency
    e = max(graph.num_edges, 1)
    shared = (t.indices.nbytes + t.indptr.nbytes) / e
    forward = (a.data.nbytes + a.indices.nbytes + a.indptr.nbytes) / e
    forward += graph.distance_weights.nbytes / e
    note = (
        f": reversed graph built in {t_csc:.1f} ms (time) + {t_dist:.1f} ms (distance); "
        f"{shared + t.data.nbytes / e:.1f} B/edge for one cost, "
        f"{shared + (t.data.nbytes + d.data.nbytes) / e:.1f} B/edge for both "
        f"(forward graph with both costs: {forward:.1f} B/edge)"
    )
    return graph, note


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs per goal and method")
    ap.add_argument("--goals", type=int, default=20, help="goals per map")
    ap.add_argument("--skip-large", action="store_true", help="skip the 50 m office map")
    args = ap.parse_args()
    _, note = get_palette()
    print(note)
    rng = np.random.default_rng(0)
    here = os.path.dirname(os.path.abspath(__file__))
    free = load_map(os.path.join(here, "..", "examples", "maps", "free_area_3p5m.yaml"))
    rows = [["measure", "median (ms)", "x new"]]
    notes = []
    graph, n = _graph(free)
    notes.append("3.5 m free area" + n)
    rx = _rx_graph(graph) if rustworkx is not None else None
    goals = rng.choice(graph.library.trim_indices(), args.goals)
    rows += _rows("3.5 m free area, random trim goals", graph, rx, goals, args.repeats)
    if not args.skip_large:
        graph, n = _graph(office_map(50.0, 0.05, seed=0))
        notes.append("50 m office" + n)
        rx = _rx_graph(graph) if rustworkx is not None else None
        trims = graph.library.trim_indices()
        goals = rng.choice(trims, args.goals)
        rows += _rows("50 m office, random trim goals", graph, rx, goals, args.repeats)
        _, label = csgraph.connected_components(graph.adjacency, connection="strong")
        big = trims[label[trims] == np.argmax(np.bincount(label))]
        goals = rng.choice(big, args.goals)
        rows += _rows("50 m office, goals in the corridors", graph, rx, goals, args.repeats)
    widths = [max(len(r[i]) for r in rows if r[1]) for i in range(3)]
    for r in rows:
        if not r[1]:
            print(r[0])
            continue
        print(f"{r[0]:<{widths[0]}}  {r[1]:>{widths[1]}}  {r[2]:>{widths[2]}}")
    for n in notes:
        print(n)
    print("targets: plan_tree <= 0.5 ms on the 3.5 m area, <= 10 ms on the 50 m office")


if __name__ == "__main__":
    main()
