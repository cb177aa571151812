"""Maps a user brings: gracenav and the decoupled baseline side by side on seeded
forests, warehouses and offices.

Each map class draws seeded tasks, each checked possible for the footprint first
(:func:`gracenav.world.footprint_connected`):

* ``forest``: a 4.5 m x 16 m field of 0.15 m posts on a 0.15 m grid (``forest_map``,
  density 0.012), start (3, 2.25) 3 m in, goal (13, 2.25) 10 m ahead, at rest; a field
  is kept when its widest route leaves the footprint 0.175 m on each side (a disc of
  radius 0.375 m crosses it, :func:`gracenav.world.footprint_connected`), else drawn
  again;
* ``forest_tight``: the same fields kept when the widest route leaves 0.1 m on each
  side;
* ``warehouse``: a 30 m x 50 m warehouse at 3 cm (``warehouse_map``), start and goal
  at rest with clearance >= footprint + 0.3 m, >= 5 m apart;
* ``office``: a 20 m office at 5 cm with 0.8 m doors (``office_map``), tasks drawn as
  in the warehouse.

Each task runs through :func:`gracenav.scenarios.run_scenario` with default settings
(footprint 0.2 m, the scenario defaults otherwise, 120 s), the map passed as a ROS map_server
file, for gracenav and for the decoupled baseline. The table gives per map class and
planner: tasks, goal reached, refused (with the reasons, shortened), contacts, the
median time to goal and the median wall time per task.

    OPENBLAS_NUM_THREADS=1 python bench/bench_maps.py [--tasks 8] [--seed 0]
        [--classes forest forest_tight warehouse office] [--max-halvings N]
        [--design-push 8] [--no-online-starts] [--no-online-ends] [--per-task]

``--per-task`` also prints every task's time to goal and wall time for both planners
(to compare two versions task by task). ``--no-online-starts`` sets
``planner.online_starts: false`` of every task (no start at rest through one maneuver
designed at the start; the decoupled baseline ignores it), and
``--no-online-ends`` ``planner.online_ends: false`` (no end through one maneuver
designed when the task starts).
``--design-push J`` sets ``planner.design_push`` (N s; default the scenario default,
gracenav.library.DEFAULT_DESIGN_PUSH; 0: none) of every task, both planners (the
decoupled baseline ignores it); ``GRACENAV_PALETTE=FILE`` runs another palette.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import collections
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.errors import GracenavError
from gracenav.library import DEFAULT_DESIGN_PUSH
from gracenav.scenarios import parse_scenario, run_scenario
from gracenav.world import (
    WorldMap,
    footprint_connected,
    forest_map,
    office_map,
    save_ros_map,
    warehouse_map,
)

FOOT = 0.2
#: Room a forest's widest route leaves beside the footprint on each side (m).
FOREST_SPARE = {"forest": 0.175, "forest_tight": 0.1}
CLASSES = ("forest", "forest_tight", "warehouse", "office")


def _draw_pair(world: WorldMap, rng: np.random.Generator) -> tuple[Any, Any] | None:
    """Start and goal at rest, clearance >= footprint + 0.3 m, >= 5 m apart, connected."""
    (x0, y0), (x1, y1) = world.bounds
    for _ in range(2000):
        p = rng.uniform((x0, y0), (x1, y1), size=(2, 2))
        if np.linalg.norm(p[0] - p[1]) < 5.0:
            continue
        if np.any(world.clearance(p) < FOOT + 0.3):
            continue
        if footprint_connected(world, p[0], p[1], FOOT):
            return tuple(p[0]), tuple(p[1])
    return None


def tasks(kind: str, n: int, seed: int) -> list[tuple[WorldMap, Any, Any]]:
    """``n`` seeded tasks (map, start xy, goal xy) of a map class."""
    rng = np.random.default_rng(seed)
    out: list[tuple[WorldMap, Any, Any]] = []
    k = 0
    while len(out) < n and k < 50 * n:
        k += 1
        if kind in FOREST_SPARE:
            world = forest_map(density=0.012, seed=seed * 1000 + k)
            start, goal = (3.0, 2.25), (13.0, 2.25)
            if footprint_connected(world, start, goal, FOOT + FOREST_SPARE[kind]):
                out.append((world, start, goal))
            continue
        if kind == "warehouse":
            world = warehouse_map(30.0, 50.0, resolution=0.03, seed=seed * 1000 + k)
        else:
            world = office_map(20.0, resolution=0.05, seed=seed * 1000 + k, door=0.8)
        pair = _draw_pair(world, rng)
        if pair is not None:
            out.append((world, *pair))
    return out


def run_one(
    path: Path,
    start: Any,
    goal: Any,
    planner: str,
    max_halvings: int | None = None,
    design_push: float = DEFAULT_DESIGN_PUSH,
    online_starts: bool = True,
    online_ends: bool = True,
) -> dict[str, Any]:
    """One task through run_scenario: outcome, time to goal, contact, wall time."""
    data: dict[str, Any] = {
        "name": f"{path.stem} {planner}",
        "map": {"ros_map": str(path)},
        "robot": {"footprint_radius": FOOT},
        "planner": {"cost": "time"},
        "task": {
            "kind": "point_to_point",
            "goal": [*goal, 0.0, 0.0],
            "starts": [[*start, 0.0, 0.0]],
        },
        "simulation": {"max_time": 120},
    }
    if max_halvings is not None:
        data["planner"]["max_halvings"] = max_halvings
    data["planner"]["design_push"] = design_push
    if not online_starts:
        data["planner"]["online_starts"] = False
    if not online_ends:
        data["planner"]["online_ends"] = False
    if planner == "decoupled":
        data["planner"]["kind"] = "decoupled"
    t0 = time.perf_counter()
    try:
        result = run_scenario(parse_scenario(data, source=str(path)))
    except GracenavError as exc:
        msg = str(exc).split(": ", 1)[-1]
        return {"refused": msg[:90], "wall": time.perf_counter() - t0}
    run = result.runs[0]
    ep = result.episodes[0]
    return {
        "reached": bool(run.reached_goal),
        "contact": bool(run.min_clearance_m < 0.0),
        "time": float(ep.time[-1]),
        "wall": time.perf_counter() - t0,
    }


def _cell(row: dict[str, Any]) -> str:
    """A task's outcome for ``--per-task``: time to goal (or why not) and wall time."""
    if "refused" in row:
        what = f"refused ({row['refused']})"
    elif row.get("reached"):
        what = f"{row['time']:.3f} s" + (" (contact)" if row.get("contact") else "")
    else:
        what = "not reached"
    return f"{what}, wall {row['wall']:.1f} s"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--classes",
        nargs="+",
        default=list(CLASSES),
        choices=CLASSES,
    )
    ap.add_argument(
        "--max-halvings",
        type=int,
        default=None,
        help="planner.max_halvings of every task (default: the scenario default)",
    )
    ap.add_argument(
        "--design-push",
        type=float,
        default=DEFAULT_DESIGN_PUSH,
        help=f"planner.design_push (N s) of every task (default {DEFAULT_DESIGN_PUSH:g}; 0: none)",
    )
    ap.add_argument(
        "--no-online-starts",
        action="store_true",
        help="planner.online_starts: false in every task (no start at rest through one "
        "maneuver designed and verified at the start)",
    )
    ap.add_argument(
        "--no-online-ends",
        action="store_true",
        help="planner.online_ends: false in every task (no end through one maneuver "
        "designed and verified when the task starts)",
    )
    ap.add_argument(
        "--per-task",
        action="store_true",
        help="also print every task's time to goal and wall time, both planners",
    )
    args = ap.parse_args()
    print("class      planner     tasks  reached  refused  contacts  median_time_s  median_wall_s")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.classes:
            drawn = tasks(kind, args.tasks, args.seed)
            paths = []
            for i, (world, _, _) in enumerate(drawn):
                path = Path(tmp) / f"{kind}_{i}.yaml"
                save_ros_map(world, path, image_format="png")
                paths.append(path)
            by_planner: dict[str, list[dict[str, Any]]] = {}
            for planner in ("gracenav", "decoupled"):
                rows = by_planner[planner] = [
                    run_one(
                        p,
                        s,
                        g,
                        planner,
                        args.max_halvings,
                        args.design_push,
                        not args.no_online_starts,
                        not args.no_online_ends,
                    )
                    for p, (_, s, g) in zip(paths, drawn, strict=True)
                ]
                reached = sum(1 for r in rows if r.get("reached"))
                refused = collections.Counter(r["refused"] for r in rows if "refused" in r)
                contacts = sum(1 for r in rows if r.get("contact"))
                times = [r["time"] for r in rows if r.get("reached")]
                med = f"{statistics.median(times):.2f}" if times else "-"
                wall = statistics.median(r["wall"] for r in rows) if rows else float("nan")
                print(
                    f"{kind:10s} {planner:10s} {len(rows):6d} {reached:8d} "
                    f"{sum(refused.values()):8d} {contacts:9d} {med:>14s} {wall:14.1f}"
                )
            g_rows, d_rows = by_planner["gracenav"], by_planner["decoupled"]
            if args.per_task:
                for i, (g, d) in enumerate(zip(g_rows, d_rows, strict=True)):
                    print(f"{kind:10s} task {i}: gracenav {_cell(g)}, decoupled {_cell(d)}")
            g_t = [r["time"] for r in g_rows if r.get("reached")]
            d_t = [r["time"] for r in d_rows if r.get("reached")]
            both = [
                g["time"] / d["time"]
                for g, d in zip(g_rows, d_rows, strict=True)
                if g.get("reached") and d.get("reached")
            ]
            if g_t and d_t:
                print(
                    f"{kind:10s} time ratio gracenav / decoupled: medians "
                    f"{statistics.median(g_t) / statistics.median(d_t):.3f}, median of the "
                    f"{len(both)} tasks both reached {statistics.median(both):.3f}"
                )
                for why, count in refused.most_common():
                    print(f"    refused {count}x: {why}")


if __name__ == "__main__":
    main()
