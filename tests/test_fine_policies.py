"""Fine copies of the lattice policies: every domain scaled down, verified again, placed
only near obstacles, and chained to the unscaled policies by exact containment."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from reverify import assert_holds_from_unchosen_points

from gracenav.library import InstantiatedPolicy, build_library
from gracenav.planning import plan_tree
from gracenav.planning.graph import build_graph, gracefully_prepares
from gracenav.policies import fine_label
from gracenav.world import load_map

ROOT = Path(__file__).resolve().parent.parent
LEVELS = (0.5, 0.25)

#: A straight passage 0.72 m wide (walls 0.1 m thick) between two 2 m rooms: the 0.2 m
#: footprint passes with 0.16 m to spare on each side, which no unscaled policy's swept
#: D' (0.26 m at its start) leaves room for.
PASSAGE = {
    "bounds": [[0.0, 0.0], [8.0, 2.0]],
    "resolution": 0.02,
    "obstacles": [
        {"rectangle": {"min": [2.0, 0.0], "max": [6.0, 0.64]}},
        {"rectangle": {"min": [2.0, 1.36], "max": [6.0, 2.0]}},
    ],
}


def _coarse(palette):
    """The palette without its fine copies (as built before they existed)."""
    keep = tuple(p for p in palette.policies if "[x" not in p.name)
    return dataclasses.replace(
        palette,
        policies=keep,
        options=dataclasses.replace(palette.options, fine_scales=()),
    )


def test_every_lattice_policy_has_verified_fine_copies(palette) -> None:
    assert palette.options.fine_scales == LEVELS
    bases = [p for p in palette.policies if not p.label and not p.capture]
    assert len(bases) >= 30
    for base in bases:
        for lam in LEVELS:
            fine = palette[fine_label(base.primitive.name, lam)]
            assert fine.primitive is base.primitive
            assert fine.report is not None and fine.report.passed
            assert fine.start_radii.position == pytest.approx(lam * base.start_radii.position)
            assert fine.goal_radii.velocity == pytest.approx(lam * base.goal_radii.velocity)
            t = np.linspace(0.0, base.duration, 7)
            np.testing.assert_allclose(
                fine.outer_extents(t), lam * np.asarray(base.outer_extents(t)), rtol=1e-12
            )


def test_a_fine_copy_holds_from_states_its_verification_did_not_choose(palette) -> None:
    """Re-verified from another boundary set, and run from random interior states of S,
    on the 3D model."""
    pol = palette[fine_label("cruise_x_to_cruise_y_1_1", 0.25)]
    assert_holds_from_unchosen_points(
        pol, palette.options, boundary_points=101, interior=24, seed=11
    )


def test_levels_chain_down_one_at_a_time_and_up_at_once(palette) -> None:
    """By the general definition (exact ellipsoid containment, continuous reference): a
    level prepares the next finer one and every coarser one, never two levels down."""
    p = {lam: palette[fine_label("cruise_x", lam)] for lam in LEVELS}
    p[1.0] = palette["cruise_x"]
    names = [pol.name for pol in palette.policies]

    def placed(lam: float, x: float) -> InstantiatedPolicy:
        return InstantiatedPolicy(
            index=0,
            policy=p[lam],
            palette_index=names.index(p[lam].name),
            orientation=0,
            start_xy=np.array([x, 0.0]),
        )

    step = float(p[1.0].primitive.position[-1, 0])
    for a, b, want in [
        (1.0, 0.5, True),
        (0.5, 0.25, True),
        (1.0, 0.25, False),
        (0.25, 0.5, True),
        (0.25, 1.0, True),
        (0.5, 1.0, True),
    ]:
        assert gracefully_prepares(placed(a, 0.0), placed(b, step)) is want, (a, b)


def test_fine_copies_are_placed_only_where_the_unscaled_policy_does_not_fit(
    box_room_library,
) -> None:
    lib = box_room_library
    fine = lib.is_fine(np.arange(len(lib)))
    assert 0 < np.count_nonzero(fine) < len(lib) // 2
    # One type per scale group (a primitive at one orientation) and point: a fine copy
    # starts only where none of the unscaled sizes of its primitive was placed.
    group = lib.types.scale_group[lib.type_index]
    key = group * (lib.lattice_shape[0] * lib.lattice_shape[1]) + lib.point_index
    assert np.unique(key).size == len(lib)
    # Far from the walls and the box every unscaled policy fits: no fine copy there.
    clear = lib.world_map.clearance(lib.start_xy)
    assert np.count_nonzero(fine & (clear > 1.0)) < np.count_nonzero(fine & (clear < 0.6))


def test_a_passage_only_the_fine_copies_fit_through(palette) -> None:
    world = load_map(PASSAGE)
    start, goal = np.array([1.0, 1.0, 0.0, 0.0]), np.array([7.0, 1.0, 0.0, 0.0])
    got = {}
    for name, pal in (("coarse", _coarse(palette)), ("fine", palette)):
        lib = build_library(pal, world, footprint_radius=0.2, max_halvings=1)
        graph = build_graph(lib)
        rest = lib.trim_indices()
        at = rest[np.argmin(np.linalg.norm(lib.end_state[rest] - goal, axis=1))]
        tree = plan_tree(graph, int(at))
        first = lib.start_domain_contains(start[None]).indices
        got[name] = bool(np.any(tree.cost_to_go[first] < np.inf))
    assert got == {"coarse": False, "fine": True}


@pytest.mark.slow
def test_the_robot_drives_through_the_passage_without_contact(palette) -> None:
    from gracenav.execution import HybridController
    from gracenav.sim import position_state, state_from_position

    world = load_map(PASSAGE)
    lib = build_library(palette, world, footprint_radius=0.2, max_halvings=1)
    hc = HybridController(lib, build_graph(lib))
    r = palette.params.ball_radius
    ep = hc.run(state_from_position(np.array([1.0, 1.0, 0.0, 0.0]), r), [[7.0, 1.0, 0.0, 0.0]])
    assert ep.status.value == "goal_reached"
    ps = position_state(ep.states, r)
    assert np.linalg.norm(ps[-1, :2] - [7.0, 1.0]) < 0.05
    assert float(np.min(world.clearance(ps[:, :2]))) - 0.2 > 0.0
    assert len(ep.captures) == 0


def test_captures_end_only_on_rest_trims_whose_start_domain_holds_their_goal() -> None:
    """Near walls the library has fine rest trims, whose S (0.04 m for x0.25) does not
    hold a shift's or a settled catch's G (0.08 m): every capture plan on the cluttered
    room chains by exact containment, catch to shifts to rest trim."""
    from gracenav.execution.capture import capture_for
    from gracenav.palette import load_palette

    world = load_map(ROOT / "examples" / "maps" / "room_6m_cluttered.yaml")
    lib = build_library(load_palette(), world, footprint_radius=0.2, max_halvings=1)
    capture = capture_for(lib)
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 6.0, size=(4000, 2))
    xy = xy[world.is_free(xy) & (world.clearance(xy) >= 0.3)][:400]
    v = rng.uniform(-0.4, 0.4, size=xy.shape)
    planned = ends_on_fine = 0
    for x in np.concatenate([xy, v], axis=1):
        plan = capture.plan(x, lean_deviation=(0.0, 0.0))
        if plan is None:
            continue
        planned += 1
        last = plan.catch.goal_domain
        for shift in plan.shifts:
            assert shift.start_domain.contains_domain(last)
            last = shift.goal_domain
        assert lib.policy(plan.rest_row).start_domain.contains_domain(last)
        ends_on_fine += bool(lib.is_fine([plan.rest_row])[0])
    assert planned >= 200
    assert ends_on_fine >= 1
