"""Coverage of the policy library, by the library's estimate and by brute force.

Coverage is measured on position states (x, y, ẋ, ẏ) with x, y uniform over the
free positions whose clearance (distance to the nearest obstacle or wall) is at
least ``footprint + margin`` and (ẋ, ẏ) uniform over the disc |v| <= 0.5 m/s. A
state is covered when it lies in at least one instantiated start domain S, or when
a capture (a catch placed at the state, up to two shifts, a rest trim:
gracenav.execution.capture) is planned for it with the plan lean. Two counts:

* ``library``: the library's estimate, ``start_domain_covers`` or
  ``capture_for(lib).plan``;
* ``brute force``: every sample tested against every start domain with the
  ellipsoid inequality (no spatial index), or a capture plan that passes an
  independent dense check: the catch's S (in the world frame) contains the state,
  64 points on the boundary of every tick's D' (its XY projection) of the catch and
  the shifts have clearance >= footprint, each shift's S contains the G before it
  and the rest trim's S the last G (exact ellipsoid containment).

The last column is a bound no controller can beat: the share of the states whose
capture point (gracenav.policies.capture_point; the ball's path reaches at least as
far as it in every direction) keeps the footprint clear of every obstacle.

Targets: >= 99 % at margin 0.3 m and >= 90 % at margin 0.1 m on the 5 m room, the
paper's Fig. 5 map and the cluttered 6 m room; library + graph on the paper-size
3.5 m area <= 100 ms.

``--design-push J`` builds every library with ``design_push`` J (N s; default
gracenav.library.DEFAULT_DESIGN_PUSH, 0: none; see gracenav.library.build_library).

    OPENBLAS_NUM_THREADS=1 python bench/bench_coverage.py [--halvings 1] [--samples 20000]
        [--brute 2000] [--design-push 8]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
import yaml

from gracenav.execution.capture import PlacedPolicy, capture_for
from gracenav.library import DEFAULT_DESIGN_PUSH, PolicyLibrary, build_library
from gracenav.palette import load_palette
from gracenav.params import BallbotParams
from gracenav.planning.graph import build_graph
from gracenav.policies import capture_point
from gracenav.world import WorldMap, load_map

ROOT = Path(__file__).resolve().parent.parent
MAPS = {
    "room 5 m, central box": ROOT / "examples" / "maps" / "room_5m_box.yaml",
    "paper Fig. 5 (scenario map)": ROOT
    / "src"
    / "gracenav"
    / "data"
    / "scenarios"
    / "fig5_point_to_point.yaml",
    "room 6 m, cluttered": ROOT / "examples" / "maps" / "room_6m_cluttered.yaml",
}
FOOTPRINT = 0.2
SPEED = 0.5


def sample_states(
    world: WorldMap, n: int, clearance: float, rng: np.random.Generator
) -> np.ndarray:
    """``n`` position states: free positions with clearance >= ``clearance`` (m), velocity
    uniform on the disc of radius SPEED."""
    (x0, y0), (x1, y1) = world.bounds
    got: list[np.ndarray] = []
    have = 0
    for _ in range(1000):
        xy = rng.uniform((x0, y0), (x1, y1), size=(4 * n, 2))
        xy = xy[world.is_free(xy) & (world.clearance(xy) >= clearance)]
        got.append(xy)
        have += xy.shape[0]
        if have >= n:
            break
    xy = np.concatenate(got)[:n]
    radius = SPEED * np.sqrt(rng.uniform(size=xy.shape[0]))
    angle = rng.uniform(0.0, 2.0 * np.pi, size=xy.shape[0])
    v = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    return np.concatenate([xy, v], axis=1)


def capture_point_clear(world: WorldMap, states: np.ndarray, params: BallbotParams) -> np.ndarray:
    """Whether the capture point of each state (at the plan lean: the flat output is
    the ball) keeps the footprint clear: otherwise no controller stops it in time."""
    xi = capture_point(states, params)
    return np.asarray(world.is_free(xi) & (world.clearance(xi) >= FOOTPRINT), dtype=bool)


def brute_force_covered(lib: PolicyLibrary, states: np.ndarray) -> np.ndarray:
    """Whether each state lies in some start domain, testing every domain (no index)."""
    covered = np.zeros(states.shape[0], dtype=bool)
    for i in range(len(lib)):
        dom = lib.policy(i).start_domain
        todo = ~covered
        if not np.any(todo):
            break
        covered[todo] |= dom.value(states[todo]) <= 1.0
    return covered


def outer_domains_clear(lib: PolicyLibrary, placed: PlacedPolicy) -> bool:
    """Whether the footprint keeps clear of obstacles from 64 points of the boundary of
    D'(t)'s XY projection at every control tick: an independent test of a placed
    policy's swept D' (the planner covers each D' by discs along the path)."""
    centres, shapes = placed.outer_monitor()
    ang = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    p_xy = shapes[:, :2, :2] - shapes[:, :2, 2:] @ np.linalg.solve(
        shapes[:, 2:, 2:], shapes[:, 2:, :2]
    )
    ell = np.linalg.cholesky(np.linalg.inv(p_xy))  # (T, 2, 2)
    xy = (centres[:, None, :2] + np.einsum("tij,kj->tki", ell, ring)).reshape(-1, 2)
    world = lib.world_map
    return bool(np.all(world.is_free(xy) & (world.clearance(xy) >= lib.footprint_radius)))


def capture_checked(lib: PolicyLibrary, state: np.ndarray) -> bool:
    """A capture plan for ``state`` that passes the independent dense check."""
    plan = capture_for(lib).plan(state, lean_deviation=(0.0, 0.0))
    if plan is None or not plan.catch.start_domain.contains(state):
        return False
    for placed in plan.policies:
        if not outer_domains_clear(lib, placed):
            return False
    last = plan.catch.goal_domain
    for shift in plan.shifts:
        if not shift.start_domain.contains_domain(last):
            return False
        last = shift.goal_domain
    return bool(lib.policy(plan.rest_row).start_domain.contains_domain(last))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--halvings", type=int, default=1, help="lattice halvings (default 1)")
    ap.add_argument("--samples", type=int, default=20_000, help="states per class")
    ap.add_argument("--brute", type=int, default=2_000, help="states checked by brute force")
    ap.add_argument(
        "--design-push",
        type=float,
        default=DEFAULT_DESIGN_PUSH,
        help=f"libraries' design push (N s, default {DEFAULT_DESIGN_PUSH:g}; 0: none)",
    )
    args = ap.parse_args()
    pal = load_palette()
    rng = np.random.default_rng(0)
    print(
        f"palette: {len(pal)} policies; lattice halvings {args.halvings}; |v| <= {SPEED} m/s; "
        f"design push {args.design_push:g} N s"
    )
    header = (
        "map",
        "policies",
        "margin",
        "library S",
        "library S or capture",
        "brute force S / S or capture",
        "agree",
        "capture-point bound",
    )
    rows = [header]
    for name, path in MAPS.items():
        doc = yaml.safe_load(path.read_text())
        world = load_map(doc["map"] if "task" in doc else path)
        lib = build_library(
            pal,
            world,
            footprint_radius=FOOTPRINT,
            max_halvings=args.halvings,
            coverage_target=1.0,
            design_push=args.design_push,
        )
        capture = capture_for(lib)
        for label, margin in (("+0.3 m", 0.3), ("+0.1 m", 0.1), ("all free", 0.0)):
            states = sample_states(world, args.samples, FOOTPRINT + margin, rng)
            in_s = lib.start_domain_covers(states)
            est_s = float(np.mean(in_s))
            caught = in_s.copy()
            caught[~in_s] = capture.covers(states[~in_s])
            sub = states[: args.brute]
            brute_s = brute_force_covered(lib, sub)
            brute = brute_s | np.array([capture_checked(lib, x) for x in sub], dtype=bool)
            agree = bool(np.array_equal(brute_s, in_s[: args.brute])) and bool(
                np.array_equal(brute, caught[: args.brute])
            )
            rows.append(
                (
                    name,
                    str(len(lib)),
                    label,
                    f"{100 * est_s:.1f} %",
                    f"{100 * np.mean(caught):.1f} %",
                    f"{100 * np.mean(brute_s):.1f} / {100 * np.mean(brute):.1f} % "
                    f"of {sub.shape[0]}",
                    str(agree),
                    f"{100 * np.mean(capture_point_clear(world, states, pal.params)):.1f} %",
                )
            )
    free = load_map({"bounds": [[0.0, 0.0], [3.5, 3.5]], "obstacles": []})
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        build_graph(build_library(pal, free, max_halvings=0, design_push=args.design_push))
        times.append(time.perf_counter() - t0)
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)))
    print(
        f"library + graph, 3.5 m free area, median of 5: {1000 * statistics.median(times):.1f} ms"
    )


if __name__ == "__main__":
    main()
