"""Peak memory and time of the library and graph on 100 m × 100 m maps: a baseline.

Two maps at 5 cm resolution, one pass at spacing d (``max_halvings=0``):

* ``office``: ``maps.office_map(100.0, 0.05, seed=0)``: corridors, rooms, furniture;
* ``hall``: an open 100 m × 100 m hall, walls only (the most policies per area).

Each map runs in its own subprocess so that its peak resident memory
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``) is its own. The child reports the peak
after each stage (map and clearance field, library, graph, one tree)
and the wall time of each; the parent prints a table. A child that runs out of the
address-space limit (``--max-gib``) or the time limit is reported, not fatal.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_scale.py [--only office] [--lazy]

``--lazy`` adds the hybrid controller's first plan through a lazy tree
(:class:`gracenav.planning.LazyPolicyTree`) and local replans after pushes along it.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import subprocess
import sys
import time
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

CASES = ("office", "hall")
SIZE = 100.0  # m
RESOLUTION = 0.05  # m


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def child(
    case: str, size: float, tree_stage: bool, lazy_stage: bool = False
) -> dict[str, float | int | str]:
    """Build map, library, graph and one tree (the first, as a controller plans it:
    :meth:`PreparesGraph.search_form`); peak RSS after each.

    The results so far are printed (one JSON line) after every stage, so a stage that
    fails still leaves the earlier ones to the parent."""
    import numpy as np
    from bench_library import get_palette

    from gracenav.errors import ConfigError, MapError
    from gracenav.library import build_library
    from gracenav.planning import plan_path, plan_tree
    from gracenav.planning.graph import build_graph
    from gracenav.world import WorldMap, load_map, office_map

    out: dict[str, float | int | str] = {"case": case, "rss_start_mib": _rss_mib()}
    palette, note = get_palette()
    out["palette"] = note
    t0 = time.perf_counter()
    if case == "office":
        wmap = office_map(size, RESOLUTION, seed=0)
    else:
        try:
            wmap = load_map(
                {"bounds": [[0.0, 0.0], [size, size]], "obstacles": [], "resolution": RESOLUTION}
            )
        except MapError:  # above the loader's cell limit: the same grid, built directly
            cells = round(size / RESOLUTION)
            wmap = WorldMap(
                origin=np.zeros(2), resolution=RESOLUTION, occupied=np.zeros((cells, cells), bool)
            )
    _ = wmap.clearance_grid
    out["map_s"] = time.perf_counter() - t0
    out["rss_map_mib"] = _rss_mib()
    print(json.dumps(out), flush=True)
    t0 = time.perf_counter()
    try:
        lib = build_library(palette, wmap, max_halvings=0)
    except ConfigError as exc:  # refused up front: over the memory limit
        out["refused"] = str(exc)
        out["refused_s"] = time.perf_counter() - t0
        out["rss_library_mib"] = _rss_mib()
        return out
    out["library_s"] = time.perf_counter() - t0
    out["rss_library_mib"] = _rss_mib()
    out["policies"] = len(lib)
    print(json.dumps(out), flush=True)
    t0 = time.perf_counter()
    graph = build_graph(lib)
    out["graph_s"] = time.perf_counter() - t0
    out["rss_graph_mib"] = _rss_mib()
    t0 = time.perf_counter()
    out["edges"] = graph.num_edges  # counted on first use (what search_form asks)
    out["count_s"] = time.perf_counter() - t0
    print(json.dumps(out), flush=True)
    trims = lib.trim_indices()
    goal = int(trims[np.argmin(np.linalg.norm(lib.start_xy[trims] - size / 2, axis=1))])
    # The first point-to-point plan: A* from the trim nearest a corner region (the
    # nearest whose plan reaches the goal) to the goal near the centre.
    near = trims[np.argsort(np.linalg.norm(lib.start_xy[trims] - 0.1 * size, axis=1))]
    t0 = time.perf_counter()
    for start in near[:20]:
        path = plan_path(graph, int(start), goal)
        if path.reachable:
            break
    out["plan_s"] = time.perf_counter() - t0
    out["plan_cost"] = path.cost
    out["plan_expanded"] = path.expanded
    out["plan_policies"] = int(path.policies.size)
    out["rss_plan_mib"] = _rss_mib()
    print(json.dumps(out), flush=True)
    if lazy_stage:
        _lazy_stage(out, graph, int(start), goal)
        print(json.dumps(out), flush=True)
    if not tree_stage:
        return out
    form = graph.search_form("time")
    out["search_form"] = "stored" if form is not graph else "lattice"
    t0 = time.perf_counter()
    tree = plan_tree(form, goal)
    out["tree_s"] = time.perf_counter() - t0
    out["tree_size"] = int(np.isfinite(tree.cost_to_go).sum())
    out["rss_tree_mib"] = _rss_mib()
    return out


def _lazy_stage(out: dict[str, float | int | str], graph: Any, start: int, goal: int) -> None:
    """The hybrid controller's first plan through a lazy tree (the best of the policies
    whose S contains the start trim's start state), then pushes along its path: the
    same tree settled on the policies that capture each pushed state, side by side
    with ``plan_path(..., via=)``."""
    import statistics

    import numpy as np
    from bench_lazy import captured, push_rows

    from gracenav.planning import LazyPolicyTree, plan_path

    lib = graph.library
    t0 = time.perf_counter()
    LazyPolicyTree(graph, goal).settle([goal])  # load the compiled kernel
    out["lazy_load_s"] = time.perf_counter() - t0
    first = captured(lib, lib.start_state[start])
    t0 = time.perf_counter()
    tree = LazyPolicyTree(graph, goal)
    tree.settle(first, best=True)
    out["lazy_first_s"] = time.perf_counter() - t0
    out["lazy_first_expanded"] = tree.expanded
    cost = tree.cost_to_go[first]
    row = int(first[int(np.argmin(cost))])
    out["lazy_first_cost"] = float(cost.min())
    out["rss_lazy_mib"] = _rss_mib()
    path = np.array(tree.path_from(row), dtype=np.int64)
    via = plan_path(graph, row, goal)
    lazy, peer = [], []
    for rows in push_rows(lib, path, 10, np.random.default_rng(0)):
        t0 = time.perf_counter()
        tree.settle(rows, best=True)
        lazy.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        replan = plan_path(graph, rows, goal, via=via)
        peer.append(time.perf_counter() - t0)
        assert np.isclose(replan.cost, tree.cost_to_go[rows].min(), rtol=1e-12)
    out["rss_pushes_mib"] = _rss_mib()
    # The hybrid controller end to end: an 8.9 m task from the centre with two pushes.
    from gracenav.execution import ExecutionOptions, HybridController

    # On a graph that has not counted its edges (the bench counted them above), as a
    # controller meets a new graph.
    from gracenav.planning.graph import build_graph
    from gracenav.sim import Push, state_from_position

    t0 = time.perf_counter()
    hc = HybridController(lib, build_graph(lib))
    out["hc_init_s"] = time.perf_counter() - t0
    centre = 0.5 * float(lib.world_map.bounds[1][0])
    x0 = state_from_position([centre, centre, 0.0, 0.0], hc.params.ball_radius)
    pushes = (Push(3.0, (0.0, -12.0)), Push(8.0, (10.0, 5.0)))
    t0 = time.perf_counter()
    ep = hc.run(
        x0,
        [[centre + 8.0, centre + 4.0, 0.0, 0.0]],
        disturbances=pushes,
        options=ExecutionOptions(max_time=60.0),
    )
    out["hc_run_s"] = time.perf_counter() - t0
    out["hc_sim_s"] = float(ep.time[-1])
    out["hc_status"] = ep.status.value
    out["hc_domain_exits"] = sum(e.reason.value == "domain_exit" for e in ep.events)
    out["rss_hc_mib"] = _rss_mib()
    out["push_lazy_ms_median"] = 1e3 * statistics.median(lazy)
    out["push_lazy_ms_max"] = 1e3 * max(lazy)
    out["push_via_ms_median"] = 1e3 * statistics.median(peer)
    out["push_via_ms_max"] = 1e3 * max(peer)
    out["pushes"] = len(lazy)


def run_child(
    case: str, size: float, max_gib: float, timeout: float, tree: bool, lazy: bool = False
) -> dict[str, object]:
    here = os.path.dirname(os.path.abspath(__file__))
    limit = int(max_gib * 2**30)

    def limit_memory() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [
                sys.executable,
                os.path.join(here, "bench_scale.py"),
                "--child",
                case,
                "--size",
                str(size),
                *([] if tree else ["--no-tree"]),
                *(["--lazy"] if lazy else []),
            ],
            capture_output=True,
            text=True,
            timeout=timeout,
            preexec_fn=limit_memory,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return {"case": case, "error": f"no result within {timeout:g} s"}
    wall = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    res: dict[str, object] = json.loads(lines[-1]) if lines else {"case": case}
    if proc.returncode != 0:
        err = (proc.stderr.strip().splitlines() or ["?"])[-1]
        res["error"] = f"exit {proc.returncode} after {wall:.0f} s: {err}"
    return res


def _cell(r: dict[str, object], key: str, width: int, fmt: str, scale: float = 1.0) -> str:
    """``r[key]`` (times ``scale``) formatted right-aligned, or "-" if the stage failed."""
    v = r.get(key)
    return f"{'-':>{width}}" if v is None else f"{float(v) * scale:>{width}{fmt}}"  # type: ignore[arg-type]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=CASES, help="run one map only")
    ap.add_argument("--max-gib", type=float, default=8.0, help="address-space limit per map")
    ap.add_argument("--timeout", type=float, default=900.0, help="time limit per map (s)")
    ap.add_argument("--size", type=float, default=SIZE, help="side of the square maps (m)")
    ap.add_argument("--no-tree", action="store_true", help="skip the whole single-goal tree")
    ap.add_argument(
        "--lazy", action="store_true", help="the first plan and pushes through a lazy tree"
    )
    ap.add_argument("--child", choices=CASES, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.size, not args.no_tree, args.lazy)))
        return
    results = [
        run_child(c, args.size, args.max_gib, args.timeout, not args.no_tree, args.lazy)
        for c in CASES
        if args.only in (None, c)
    ]
    notes = {str(r["palette"]) for r in results if "palette" in r}
    for n in notes:
        print(n)
    print(f"{args.size:g} m x {args.size:g} m maps, {RESOLUTION:g} m cells, one pass at spacing d")
    head = (
        f"{'map':<7} {'policies':>9} {'edges':>11} {'map s':>6} {'library s':>9} "
        f"{'graph s':>7} {'lib+graph s':>11} {'plan s':>6} {'expanded':>8} {'search':>7} "
        f"{'tree s':>6} {'tree size':>9} "
        f"{'peak RSS MiB: map':>17} {'library':>7} {'graph':>7} {'+plan':>6} {'+tree':>6}"
    )
    print(head)
    for r in results:
        cell = functools.partial(_cell, r)

        total = (
            float(r["library_s"]) + float(r["graph_s"])  # type: ignore[arg-type]
            if "graph_s" in r
            else None
        )
        print(
            f"{r['case']!s:<7} {cell('policies', 9, '.0f')} {cell('edges', 11, '.0f')} "
            f"{cell('map_s', 6, '.1f')} {cell('library_s', 9, '.1f')} {cell('graph_s', 7, '.1f')} "
            f"{'-' if total is None else f'{total:.1f}':>11} {cell('plan_s', 6, '.2f')} "
            f"{cell('plan_expanded', 8, '.0f')} {r.get('search_form', '-')!s:>7} "
            f"{cell('tree_s', 6, '.2f')} {cell('tree_size', 9, '.0f')} "
            f"{cell('rss_map_mib', 17, '.0f')} {cell('rss_library_mib', 7, '.0f')} "
            f"{cell('rss_graph_mib', 7, '.0f')} {cell('rss_plan_mib', 6, '.0f')} "
            f"{cell('rss_tree_mib', 6, '.0f')}"
        )
        if "lazy_first_s" in r:
            print(
                f"  {r['case']} lazy tree: first plan {float(r['lazy_first_s']):.2f} s "  # type: ignore[arg-type]
                f"({r['lazy_first_expanded']} closed, kernel load "
                f"{float(r['lazy_load_s']):.2f} s), peak RSS {float(r['rss_lazy_mib']):.0f} MiB; "  # type: ignore[arg-type]
                f"{r.get('pushes', '-')} pushes: lazy "
                f"{float(r.get('push_lazy_ms_median', 'nan')):.1f} ms median "  # type: ignore[arg-type]
                f"(max {float(r.get('push_lazy_ms_max', 'nan')):.1f}), plan_path(via=) "  # type: ignore[arg-type]
                f"{float(r.get('push_via_ms_median', 'nan')):.1f} ms "  # type: ignore[arg-type]
                f"(max {float(r.get('push_via_ms_max', 'nan')):.1f}), peak RSS "  # type: ignore[arg-type]
                f"{float(r.get('rss_pushes_mib', 'nan')):.0f} MiB"  # type: ignore[arg-type]
            )
        if "rss_hc_mib" in r:
            rss = float(r["rss_hc_mib"])  # type: ignore[arg-type]
            print(f"  {r['case']} peak RSS after the controller's run {rss:.0f} MiB")
        if "hc_run_s" in r:
            print(
                f"  {r['case']} hybrid controller: constructed in {float(r['hc_init_s']):.1f} s "  # type: ignore[arg-type]
                f"(+ {float(r['count_s']):.1f} s counting the edges before), "  # type: ignore[arg-type]
                "a point-to-point run with two pushes "
                f"({r['hc_domain_exits']} domain exits, {r['hc_status']}) took "
                f"{float(r['hc_run_s']):.2f} s for {float(r['hc_sim_s']):.1f} s simulated"  # type: ignore[arg-type]
            )
        if "error" in r:
            print(f"  {r['case']} failed: {r['error']}")
        if "refused" in r:
            print(f"  {r['case']} refused after {float(r['refused_s']):.1f} s: {r['refused']}")  # type: ignore[arg-type]
    print("peak RSS is ru_maxrss of the map's own process, cumulative over the stages")


if __name__ == "__main__":
    main()
