"""Capture planning time: how long `Capture.plan` takes for one state.

States of the cluttered 6 m room (``examples/maps/room_6m_cluttered.yaml``,
footprint 0.2 m, one lattice halving) at up to 0.5 m/s with the plan lean, in two
sets: near obstacles (0.3-0.5 m from the nearest; most catches there are refused
for clearance and many placements are tried) and open space (more than 0.8 m).
Each state is planned without a tree (any rest trim will do: what coverage counts)
and with the cost-to-go of a policy tree toward (5, 5) (what the hybrid controller
does). The first plan of every state on a fresh `Capture` pays for the grid points'
ways onto rest trims; the table gives that cold time and a second, warm pass.

The peer run places every catch pointing straight at its end point (the heading
search's span set to 0, ``gracenav.execution.capture._HEADING_SPAN``): the ratio is the
search's cost, the coverage column its gain on the same states.

    OPENBLAS_NUM_THREADS=1 python bench/bench_capture.py [--states 300] [--seed 0]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

import gracenav.execution.capture as capture_module
from gracenav.execution import HybridController
from gracenav.execution.capture import Capture
from gracenav.library import PolicyLibrary, build_library
from gracenav.palette import load_palette
from gracenav.planning import PolicyTree
from gracenav.planning.graph import build_graph
from gracenav.world import load_map

ROOT = Path(__file__).resolve().parent.parent
MAP = ROOT / "examples" / "maps" / "room_6m_cluttered.yaml"
FOOTPRINT = 0.2
SPEED = 0.5
GOAL = (5.0, 5.0, 0.0, 0.0)


def draw(lib: PolicyLibrary, n: int, lo: float, hi: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` states whose clearance is in [lo, hi) m, velocity uniform on the disc."""
    world = lib.world_map
    (x0, y0), (x1, y1) = world.bounds
    xy = rng.uniform((x0, y0), (x1, y1), size=(200 * n, 2))
    c = world.clearance(xy)
    xy = xy[world.is_free(xy) & (c >= lo) & (c < hi)][:n]
    radius = SPEED * np.sqrt(rng.uniform(size=xy.shape[0]))
    angle = rng.uniform(0.0, 2.0 * np.pi, size=xy.shape[0])
    return np.column_stack([xy, radius * np.cos(angle), radius * np.sin(angle)])


def timed(
    lib: PolicyLibrary, states: np.ndarray, cost_to_go: np.ndarray | None
) -> tuple[list[float], list[float], int]:
    """Cold and warm plan times (s) per state on a fresh Capture, and plans found."""
    capture = Capture(lib)
    out = []
    found = 0
    for _ in range(2):
        times = []
        found = 0
        for st in states:
            t0 = time.perf_counter()
            plan = capture.plan(st, lean_deviation=(0.0, 0.0), cost_to_go=cost_to_go)
            times.append(time.perf_counter() - t0)
            found += plan is not None
        out.append(times)
    return out[0], out[1], found


def _ms(times: list[float]) -> str:
    return f"{1e3 * statistics.median(times):.2f} / {1e3 * statistics.mean(times):.2f} ms"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--states", type=int, default=300, help="states per set (default 300)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    pal = load_palette()
    lib = build_library(pal, load_map(MAP), footprint_radius=FOOTPRINT, max_halvings=1)
    robot = HybridController(lib, build_graph(lib))
    tree = robot.tree(robot.goal_policy(np.asarray(GOAL)))
    assert isinstance(tree, PolicyTree)  # a whole tree on a map this size
    rng = np.random.default_rng(args.seed)
    sets = {
        "0.3-0.5 m from obstacles": draw(lib, args.states, 0.3, 0.5, rng),
        "open space (> 0.8 m)": draw(lib, args.states, 0.8, np.inf, rng),
    }
    span = capture_module._HEADING_SPAN
    print(f"{len(lib)} policies; {args.states} states per set, |v| <= {SPEED} m/s")
    header = ("states", "tree", "placement", "cold median / mean", "warm median / mean", "planned")
    rows = [header]
    ratios = []
    for name, states in sets.items():
        for tree_name, togo in (("none", None), ("to (5, 5)", tree.cost_to_go)):
            means = {}
            for label, s in (("heading search", span), ("straight (peer)", 0.0)):
                capture_module._HEADING_SPAN = s
                try:
                    cold, warm, found = timed(lib, states, togo)
                finally:
                    capture_module._HEADING_SPAN = span
                means[label] = statistics.mean(warm)
                rows.append(
                    (
                        name,
                        tree_name,
                        label,
                        _ms(cold),
                        _ms(warm),
                        f"{found} of {states.shape[0]}",
                    )
                )
            ratios.append((name, tree_name, means["heading search"] / means["straight (peer)"]))
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)))
    for name, tree_name, ratio in ratios:
        print(f"warm mean, heading search / straight: {ratio:.2f} ({name}, tree {tree_name})")


if __name__ == "__main__":
    main()
