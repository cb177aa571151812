"""Capture regulators: verified policies that catch a moving robot and bring it to rest."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pairs import pairs_trial

from gracenav import BallbotParams, ConfigError
from gracenav.errors import PlanningError
from gracenav.execution import EventReason, ExecutionOptions, HybridController, TaskStatus
from gracenav.execution.capture import ShiftTerminal
from gracenav.library import build_library
from gracenav.palette import REGULATOR_NAME
from gracenav.planning.graph import build_graph, gracefully_prepares
from gracenav.policies import (
    BrakingOptions,
    RegulatorOptions,
    domain_shape,
    push_lean_table,
    regulator_label,
)
from gracenav.policies.braking import braking_policies, braking_primitive
from gracenav.sim import (
    Push,
    Reference,
    position_state,
    simulate,
    simulate_batch,
    state_from_position,
)
from gracenav.world import load_map

PARAMS = BallbotParams()


@pytest.fixture(scope="module")
def regulators(palette):
    return [p for p in palette if p.capture]


@pytest.fixture(scope="module")
def room():
    """A free 5 m × 5 m room (walls at the map edge)."""
    return load_map({"bounds": [[0.0, 0.0], [5.0, 5.0]], "resolution": 0.05})


def test_palette_has_every_regulator_size_verified(palette, regulators) -> None:
    reg = palette.options.regulator
    assert reg is not None
    assert [p.start_radii.position for p in regulators] == list(reg.position_extents)
    for pol in regulators:
        rep = pol.report
        # 2 placements × boundary points × (the plan lean + one per push time).
        assert rep.runs == 2 * reg.boundary_points * (1 + len(reg.push_times))
        assert rep.passed and rep.saturated_runs == 0
        assert rep.max_outer_value <= 1.0 and rep.max_goal_value <= 1.0
        assert rep.max_lean <= palette.options.lean_limit
        assert pol.name == regulator_label(REGULATOR_NAME, pol.start_radii.position)
        assert pol.primitive.duration == pytest.approx(reg.duration, abs=1e-12)
        # G is the palette's: a captured robot continues on the rest trim.
        assert pol.goal_radii == palette["rest"].goal_radii
        assert pol.correlation == palette["rest"].correlation
        assert pol.start_shape_correlation == reg.correlation
    largest = regulators[-1]
    # Catches a robot moving at 0.7 m/s in any direction.
    assert largest.start_radii.velocity >= 0.7


def test_outer_domain_does_not_shrink_and_contains_the_start_domain(regulators) -> None:
    pol = regulators[-1]
    centres, shapes = pol.outer_monitor()
    np.testing.assert_array_equal(shapes, np.broadcast_to(shapes[0], shapes.shape))
    np.testing.assert_array_equal(centres, np.zeros_like(centres))
    assert pol.outer_domain(0.0).contains_domain(pol.start_domain)
    assert pol.outer_domain(pol.duration).contains_domain(pol.goal_domain)
    # Uncorrelated: the XY radius is the factor times e_p of S.
    q = pol.outer_domain(1.0).xy_projection()
    np.testing.assert_allclose(
        q, np.eye(2) / (pol.outer_factors[0] * pol.start_radii.position) ** 2, rtol=1e-12
    )


@pytest.mark.parametrize("which", [0, -1])
def test_regulator_holds_from_states_the_verifier_never_used(palette, regulators, which) -> None:
    """Random interior and near-boundary states of S, with a push lean at a random time
    after the push (not one of the verified times), on the 3D model: inside D' at every
    tick, in G at t_f, no saturation, lean within the limit."""
    pol = regulators[which]
    reg = palette.options.regulator
    table = push_lean_table(pol.gains, reg.push_impulses, np.linspace(0.0, 0.3, 13))
    rng = np.random.default_rng(2026)
    n = 400
    u = rng.normal(size=(n, 4))
    u *= rng.uniform(0.5, 1.0, size=(n, 1)) ** 0.25 / np.linalg.norm(u, axis=1, keepdims=True)
    ell = np.linalg.cholesky(np.linalg.inv(pol.start_domain.shape_matrix))
    p0 = u @ ell.T
    speed = np.hypot(p0[:, 2], p0[:, 3])
    unit = p0[:, 2:] / np.maximum(speed, 1e-12)[:, None]
    k = rng.integers(0, table.times.size, size=n)
    lean = np.zeros((n, 2))
    rate = np.zeros((n, 2))
    for kk in np.unique(k):
        m = k == kk
        dl, dr = table.lean_at(int(kk), speed[m])
        lean[m], rate[m] = unit[m] * dl[:, None], unit[m] * dr[:, None]
    r = PARAMS.ball_radius
    x0 = state_from_position(p0, r, lean=lean, lean_rate=rate)
    res = simulate_batch(x0, pol.primitive.reference(), pol.gains, monitor=pol.outer_monitor())
    assert np.max(res.max_domain_value) <= 1.0
    assert np.max(pol.goal_domain.value(position_state(res.final_states, r))) <= 1.0
    assert np.count_nonzero(res.saturated_ticks) == 0
    assert np.max(res.max_lean) <= palette.options.lean_limit


def test_push_lean_table_is_linear_for_small_pushes_and_conserves_momentum(palette) -> None:
    """Right after an impulse I on the body centre of mass, the angular momentum about
    the floor contact is I (r + ℓ) (the floor's impulsive reaction acts through the
    contact; the drive torque is internal); the response is linear in I while nothing
    saturates."""
    gains = palette.gains
    table = push_lean_table(gains, (2.0, 4.0), (0.0, 0.1))
    np.testing.assert_allclose(table.speed[1], 2.0 * table.speed[0], rtol=0.02)
    np.testing.assert_allclose(table.lean_rate[1], 2.0 * table.lean_rate[0], rtol=0.02)
    assert table.lean[0, 0] == 0.0  # position and lean are continuous at the impulse
    assert table.lean_rate[0, 0] > 0.0  # the body starts leaning along the push
    impulse = 4.0
    ref = Reference.hold((0.0, 0.0), 0.01, params=PARAMS)
    res = simulate(np.zeros(8), ref, gains, disturbances=[Push(0.0, (impulse, 0.0))])
    x = res.states[0]
    r, ell = PARAMS.ball_radius, PARAMS.body_com_height
    v = r * (x[4] + x[6])  # ball centre velocity ẋ
    phi_dot = x[6]
    momentum = (
        (PARAMS.ball_inertia / r + PARAMS.ball_mass * r) * v
        + PARAMS.body_mass * (r + ell) * (v + ell * phi_dot)
        + PARAMS.body_inertia_y * phi_dot
    )
    assert momentum == pytest.approx(impulse * (r + ell), rel=1e-9)
    assert v == pytest.approx(table.speed[1, 0], rel=1e-12)


def test_regulator_options_are_checked() -> None:
    with pytest.raises(ConfigError, match="ascend"):
        RegulatorOptions(position_extents=(0.5, 0.2))
    with pytest.raises(ConfigError, match="correlation"):
        RegulatorOptions(correlation=-1.0)
    assert RegulatorOptions.from_dict(dataclasses.asdict(RegulatorOptions())) == RegulatorOptions()


def test_no_policy_prepares_a_regulator_and_regulators_hand_over_to_rest(palette, room) -> None:
    lib = build_library(palette, room, footprint_radius=0.2, max_halvings=0)
    graph = build_graph(lib)
    capture = lib.types.is_capture[lib.type_index]
    assert np.any(capture)
    _, dst = graph.edges()
    assert not np.any(capture[dst])
    # Every regulator prepares the rest trim at its own point (G ⊂ S of rest).
    rest = lib.trim_indices()
    for i in np.flatnonzero(capture)[:40]:
        succ = graph.successors(int(i))
        assert succ.size > 0
        same = [j for j in succ if np.all(lib.start_xy[j] == lib.start_xy[i])]
        assert any(j in rest for j in same)
        assert gracefully_prepares(lib.policy(int(i)), lib.policy(int(same[0])))
        assert not gracefully_prepares(lib.policy(int(same[0])), lib.policy(int(i)))
    # Not goals: trims exclude them.
    assert not np.any(capture[rest])


def test_open_space_states_up_to_half_a_metre_per_second_are_covered(palette) -> None:
    """At spacing d, the regulators alone cover every position state with |v| <= 0.5 m/s
    whose regulator fits (brute force on random states): the largest S catches a robot
    at 0.5 m/s up to ≈0.9 m behind its rest point and its D' (radius 1.1 e_p) grown by
    the footprint needs 1.19 m of clearance there, so states with clearance >= 2.1 m."""
    room = load_map({"bounds": [[0.0, 0.0], [7.0, 7.0]], "resolution": 0.05})
    lib = build_library(palette, room, footprint_radius=0.2, max_halvings=0)
    rng = np.random.default_rng(3)
    xy = rng.uniform(2.1, 4.9, size=(4000, 2))
    ang = rng.uniform(0, 2 * np.pi, 4000)
    sp = 0.5 * np.sqrt(rng.uniform(size=4000))
    pts = np.column_stack([xy, sp * np.cos(ang), sp * np.sin(ang)])
    hits = lib.start_domain_contains(pts)
    capture = lib.types.is_capture[lib.type_index]
    by_capture = np.asarray(hits[:, np.flatnonzero(capture)].sum(axis=1)).ravel() > 0
    assert np.all(by_capture)


def test_a_pushed_robot_is_caught_by_a_regulator_and_reaches_the_goal(palette, room) -> None:
    """A state moving at 0.55 m/s in the open, outside every navigation policy's S, is
    caught by a capture regulator, not by balancing mode, and the goal is reached."""
    lib = build_library(palette, room, footprint_radius=0.2, max_halvings=0)
    graph = build_graph(lib)
    hc = HybridController(lib, graph)
    # The first of a grid of states near the centre, moving at 0.55 m/s, that only
    # regulators contain.
    ang = np.deg2rad(np.arange(0, 360, 15))
    xy = np.array([[2.3, 2.4], [2.6, 2.2], [2.45, 2.55]])
    cand = np.array([[x, y, 0.55 * np.cos(a), 0.55 * np.sin(a)] for x, y in xy for a in ang])
    capture_row = lib.types.is_capture[lib.type_index]
    hits = lib.start_domain_contains(cand)
    need = [
        k for k in range(len(cand)) if hits[k].indices.size and np.all(capture_row[hits[k].indices])
    ]
    assert need, "some state near the centre must need a regulator"
    p0 = cand[need[0]]
    idx = hits[need[0]].indices
    x0 = state_from_position(p0, PARAMS.ball_radius)
    ep = hc.run(x0, [np.array([1.0, 1.0, 0.0, 0.0])])
    assert ep.status is TaskStatus.GOAL_REACHED
    assert ep.events[0].to_policy in idx
    assert lib.policy(ep.events[0].to_policy).policy.capture
    assert not any(e.reason is EventReason.BALANCING for e in ep.events)


def test_what_is_kept_per_library_is_shared_and_goes_with_the_library(palette, room) -> None:
    """The capture planner, the terminal regulators of a goal and the swept D' of the
    moving-obstacle tracker are built once per library and shared by everything on it,
    and none of them keeps the library alive."""
    import gc
    import weakref

    from gracenav.execution.capture import capture_for
    from gracenav.execution.obstacles import ObstacleTracker
    from gracenav.planning.repair import ObstacleSensing

    lib = build_library(palette, room, footprint_radius=0.2, max_halvings=0)
    graph = build_graph(lib)
    goal = np.array([2.13, 2.37, 0.0, 0.0])
    terms = HybridController(lib, graph).terminal_policies(goal)
    assert terms
    assert HybridController(lib, graph).terminal_policies(goal) is terms
    capture = capture_for(lib)
    assert capture_for(lib) is capture and capture.library is lib
    tracker = ObstacleTracker(lib, graph, (), ObstacleSensing())
    assert ObstacleTracker(lib, graph, (), ObstacleSensing()).swept is tracker.swept
    alive = weakref.ref(lib)
    del lib, graph, terms, capture, tracker
    gc.collect()
    assert alive() is None


@pytest.fixture(scope="module")
def box_room_controller(box_room_library, box_room_graph):
    return HybridController(box_room_library, box_room_graph)


@pytest.mark.parametrize("goal", [(1.13, 1.37), (4.02, 3.61), (0.9, 4.1)])
def test_goals_off_the_lattice_are_reached_within_a_millimetre(box_room_controller, goal) -> None:
    hc = box_room_controller
    g = np.array([*goal, 0.0, 0.0])
    terms = hc.terminal_policies(g)
    assert terms, "a terminal regulator fits there"
    term = terms[0]
    # Its S contains the G of the rest trim the task approaches (G ⊂ S, exactly), and
    # the regulator's D' at the goal (after shifts from that trim, where they reach the
    # goal) grown by the footprint is clear of obstacles.
    approach = hc.library.policy(term.approach)
    assert term.start_domain.contains_domain(approach.goal_domain)
    regulator = term.hold if isinstance(term, ShiftTerminal) else term
    assert regulator.policy.capture
    np.testing.assert_allclose(regulator.start_xy, g[:2], atol=1e-12)
    reach = regulator.policy.outer_factors[0] * regulator.policy.start_radii.position
    assert hc.library.world_map.clearance(g[None, :2])[0] >= hc.library.footprint_radius + reach
    start = [4.0, 4.0, 0.0, 0.0] if goal[0] < 2.5 else [1.0, 1.0, 0.0, 0.0]
    x0 = state_from_position(start, PARAMS.ball_radius)
    # By default the task ends once the ball is settled within 1 cm (averaged over
    # SETTLE_WINDOW ticks); asked for 1 mm and 1 mm/s, the same regulator gets there.
    ep = hc.run(x0, [g])
    p = ep.position_state[-1]
    assert ep.status is TaskStatus.GOAL_REACHED
    assert np.hypot(*(p[:2] - g[:2])) <= 0.01 and np.hypot(*p[2:]) <= 0.05
    ep = hc.run(x0, [g], options=ExecutionOptions(settle_tolerance=1e-3, goal_tolerance=1e-3))
    assert ep.status is TaskStatus.GOAL_REACHED
    assert ep.events[-1].reason is (
        EventReason.HOLD_GOAL if isinstance(term, ShiftTerminal) else EventReason.TERMINAL
    )
    p = ep.position_state[-1]
    assert np.hypot(*(p[:2] - g[:2])) <= 1e-3
    assert np.hypot(*p[2:]) <= 1e-3
    # The terminal regulator stayed in its outer domain (its run ended in its G).
    assert term.goal_domain.contains(p)


@pytest.mark.parametrize("goal", [(4.25, 3.75), (3.75, 0.75), (0.75, 4.25)])
def test_goals_on_the_other_sub_lattice_are_reached(box_room_controller, goal) -> None:
    """Maneuvers move by whole multiples of d, so the halved lattice splits into
    sub-lattices that maneuvers alone do not connect; a goal trim on another
    sub-lattice than the start is still reached (through a capture regulator's S or a
    terminal regulator at the goal)."""
    hc = box_room_controller
    start = np.array([1.0, 1.0, 0.0, 0.0])
    g = np.array([*goal, 0.0, 0.0])
    row = hc.goal_policy(g)
    assert np.allclose(hc.library.end_state[row], g)  # the goal is a lattice trim
    ep = hc.run(state_from_position(start, PARAMS.ball_radius), [g])
    assert ep.status is TaskStatus.GOAL_REACHED
    assert np.hypot(*(ep.position_state[-1, :2] - g[:2])) <= 0.05


def test_a_goal_too_close_to_a_wall_for_any_regulator_says_why(box_room_controller) -> None:
    hc = box_room_controller
    with pytest.raises(PlanningError, match="no capture regulator fits there"):
        hc.goal_policy([0.27, 2.63, 0.0, 0.0])


def test_balancing_mode_never_drives_toward_an_obstacle(box_room_controller) -> None:
    """The point balancing mode holds is reached along a segment that keeps the
    footprint + 5 cm clear (or the robot's own clearance if smaller), and it is the
    nearest such rest-trim start: checked against a brute force over every candidate
    with segments sampled every 5 mm (the controller samples every 5 cm map cell, so
    in between the clearance may dip by half a cell: clearance is 1-Lipschitz)."""
    hc = box_room_controller
    lib = hc.library
    wm = lib.world_map
    tree = hc.tree(hc.goal_policy([4.0, 4.0, 0.0, 0.0]))
    rest = lib.trim_indices()
    rest = rest[np.isfinite(tree.cost_to_go[rest]) | (rest == tree.goal)]
    cands = lib.start_xy[rest]
    half_cell = 0.5 * float(wm.resolution)
    rng = np.random.default_rng(11)
    xy = rng.uniform(0.0, 5.0, size=(600, 2))
    xy = xy[wm.clearance(xy) >= 0.2][:80]
    for here in xy:
        q = hc.recovery_point(np.array([*here, 0.0, 0.0]), tree)
        need = min(0.25, float(wm.clearance(here[None, :])[0]))

        def min_clearance(c: np.ndarray, here: np.ndarray = here) -> float:
            n = int(np.ceil(np.linalg.norm(c - here) / 0.005)) + 1
            seg = here + np.linspace(0.0, 1.0, n)[1:, None] * (c - here)
            return float(np.min(wm.clearance(seg))) if len(seg) else np.inf

        assert min_clearance(q) >= need - half_cell
        d = np.linalg.norm(cands - here, axis=1)
        nearest = cands[np.argsort(d, kind="stable")[:64]]  # the controller's search
        surely = [c for c in nearest if min_clearance(c) >= need + half_cell]
        if surely:
            assert np.linalg.norm(q - here) <= np.linalg.norm(surely[0] - here) + 1e-9


@pytest.fixture(scope="module")
def braking_member(palette):
    """The braking maneuver from 0.5 m/s along +x, verified with a small boundary set."""
    opts = dataclasses.replace(
        palette.options, braking=BrakingOptions(scales=(2.0,), boundary_points=16)
    )
    prim = braking_primitive(0.5, (1, 0), palette.d / 2, opts.braking, palette.gains)
    assert prim is not None
    shape = domain_shape(palette.gains, horizon=opts.shape_horizon)
    (pol,) = braking_policies(prim, palette.gains, opts, shape)
    return pol


def test_braking_maneuver_stops_on_the_lattice_and_verifies(palette, braking_member) -> None:
    pol = braking_member
    prim = pol.primitive
    assert pol.capture and pol.report.passed, pol.report
    assert pol.report.runs == 2 * 16 * 5  # placements × points × lean variants
    np.testing.assert_allclose(prim.start_velocity, [0.5, 0.0], atol=2e-3)
    np.testing.assert_allclose(prim.position[0, :4], [0, 0, *prim.start_velocity], atol=1e-9)
    # Ends at rest on a multiple of d/2 along its direction, upright.
    end = prim.position[-1]
    steps = end[0] / (palette.d / 2)
    assert abs(steps - round(steps)) < 1e-9 and round(steps) >= 1 and abs(end[1]) < 1e-12
    assert np.all(np.abs(end[2:]) < 1e-12) and np.all(np.abs(prim.states[-1, 2:]) < 1e-12)
    # Planned lean within the maneuvers' limit; the flat output decelerates
    # monotonically but the ball overshoots its rest point (to brake, the ball first
    # runs ahead of the body to lean it back; 3.1 cm here).
    assert np.max(np.abs(prim.states[:, 2:4])) <= np.deg2rad(4.5) + 1e-9
    assert 0.0 < np.max(prim.position[:, 0]) - end[0] < 0.05
    # D' floors: 0.32 m and 1.2 m/s, constant along the maneuver.
    rp, rv = pol.outer_extents(np.array([0.0, pol.duration]))
    np.testing.assert_allclose(rp, 0.32, rtol=1e-12)
    np.testing.assert_allclose(rv, 1.2, rtol=1e-12)
    # The closed loop from the reference's own start tracks it (an independent check of
    # the plan's feasibility on the 3D model) and ends at rest at the end point.
    res = simulate(prim.states[0], prim.reference(), pol.gains)
    err = np.max(np.hypot(*(res.position_state[:, :2] - prim.position[:, :2]).T))
    assert err < 0.01
    assert np.hypot(*(res.position_state[-1, :2] - end[:2])) < 1e-3


def test_braking_maneuver_in_the_library_hands_over_to_rest(palette, braking_member) -> None:
    pal = dataclasses.replace(palette, policies=(*palette.policies, braking_member))
    wm = load_map({"bounds": [[0.0, 0.0], [5.0, 5.0]], "resolution": 0.05})
    lib = build_library(pal, wm, footprint_radius=0.2, max_halvings=1)
    graph = build_graph(lib)
    brake = np.flatnonzero(lib.palette_index == len(pal.policies) - 1)
    assert brake.size > 0
    assert set(lib.orientation[brake]) == {0, 1, 2, 3}  # not rotation invariant
    _, dst = graph.edges()
    assert not np.isin(brake, dst).any()
    rest = set(lib.trim_indices().tolist())
    for i in brake[:20]:
        succ = graph.successors(int(i))
        assert any(int(j) in rest for j in succ)


def test_summary_reports_verified_recoveries_and_balancing_time() -> None:
    """A push in the Fig. 5 scenario: the summary counts the recoveries into verified
    start domains and the time spent in balancing mode, from the episode's events
    and policy indices."""
    import yaml

    from gracenav.scenarios import parse_scenario, run_scenario

    path = Path(__file__).resolve().parent.parent / "src/gracenav/data/scenarios"
    data = yaml.safe_load((path / "fig5_point_to_point.yaml").read_text())
    data["task"]["starts"] = [[0.0, 2.0, 0.0, 0.0]]
    data["disturbances"] = [{"kind": "push", "time": 2.0, "impulse": [0.0, -15.0]}]
    # Without catches at the state (planner.capture: false), this push leaves the
    # robot in no start domain and balancing mode takes over.
    data["planner"] = {**data.get("planner", {}), "capture": False}
    res = run_scenario(parse_scenario(data))
    run, ep = res.runs[0], res.episodes[0]
    forced = [
        e for e in ep.events if e.reason in (EventReason.DOMAIN_EXIT, EventReason.NOT_IN_GOAL)
    ]
    assert run.verified_recoveries == sum(1 for e in forced if e.to_policy >= 0)
    assert run.captures == 0
    assert run.balancing_s >= 1.0
    dt = np.diff(ep.time)
    assert run.balancing_s == pytest.approx(float(np.sum(dt[ep.policy[:-1] == -1])), abs=1e-12)
    d = run.to_dict()
    assert d["verified_recoveries"] == run.verified_recoveries and "balancing_s" in d
    # With catches (the default), a push of the same size away from the box below is
    # caught at the state: a verified recovery, no balancing mode. (Toward the box, as
    # above, no catch stops clear of it.)
    data["planner"]["capture"] = True
    data["disturbances"] = [{"kind": "push", "time": 2.0, "impulse": [0.0, 15.0]}]
    res = run_scenario(parse_scenario(data))
    run, ep = res.runs[0], res.episodes[0]
    assert run.captures >= 1 and run.captures == run.to_dict()["captures"]
    assert run.verified_recoveries >= run.captures
    assert run.balancing_s == 0.0 and run.reached_goal


@pytest.mark.slow
def test_palette_verify_rechecks_regulators_as_built(palette, tmp_path, capsys) -> None:
    """`gracenav palette verify` re-verifies a capture regulator with the push leans and
    boundary points it was built with, and a maneuver from rest from the still band
    too, optionally on another plant (--params)."""
    from gracenav.cli import main

    small = dataclasses.replace(
        palette,
        policies=(palette["rest"], palette["regulate[ep=0.2m]"], palette["rest_to_cruise_x_1_0"]),
        catches=tuple(palette.catches[2:4]),  # the 0.1 m/s catches, both lean classes
        shifts=tuple(palette.shifts[:1]),
    )
    path = small.save(tmp_path / "small.npz")
    assert main(["palette", "verify", "--file", str(path)]) == 0
    out = capsys.readouterr().out
    assert "all 3 policies verified at 0° and 90° (1 from the still band too)" in out
    assert "2 catches and 1 shifts as built" in out
    heavier = tmp_path / "p.yaml"
    heavier.write_text("body_mass: 56.0\n")
    assert main(["palette", "verify", "--file", str(path), "--params", str(heavier)]) == 0


@pytest.mark.parametrize("start", [(1.13, 1.37), (3.61, 4.02), (0.83, 2.71)])
def test_a_start_at_rest_is_served_by_shifts_without_a_catch(box_room_controller, start) -> None:
    """At rest with the plan's lean, off every start domain of the goal's sub-lattice: a
    shift placed at a grid point next to the start already holds it in its S, so the
    capture needs no catch and costs less than the cheapest one with a catch (the still
    catch is a 1 s rest hold); each containment of the chain holds exactly."""
    from gracenav.execution.capture import capture_for

    hc = box_room_controller
    lib = hc.library
    cap = capture_for(lib)
    goal = hc.goal_policy(np.array([4.0, 4.0, 0.0, 0.0]))
    togo = hc.tree(goal).cost_to_go
    st = np.array([*start, 0.0, 0.0])
    plan = cap.plan(st, lean_deviation=(0.0, 0.0), cost_to_go=togo)
    assert plan is not None
    assert all(p.policy.name.startswith("shift") for p in plan.policies)
    assert plan.policies[0].start_domain.contains(st)
    for before, after in zip(plan.policies, plan.policies[1:], strict=False):
        assert after.start_domain.contains_domain(before.goal_domain)
    assert lib.policy(plan.rest_row).start_domain.contains_domain(plan.policies[-1].goal_domain)
    shifts = sum(p.duration for p in plan.policies)
    assert plan.cost == pytest.approx(shifts + togo[plan.rest_row], abs=1e-9)
    # Outside the still lean band only catches serve the state, at a higher cost.
    opts = cap.options
    assert opts is not None
    settled = cap.plan(st, lean_deviation=(2 * opts.still_lean[0], 0.0), cost_to_go=togo)
    assert settled is not None and not settled.catch.policy.name.startswith("shift")
    assert plan.cost < settled.cost


@pytest.mark.parametrize("trial", [7, 15])
def test_a_start_at_rest_reaches_two_shift_ways_without_a_catch(trial) -> None:
    """Trials 7 and 15 of random_pairs.yaml start at rest where no one-shift way from the
    grid points next to the start leads to the goal (a rest trim near an obstacle): every
    two-shift way from those points is read, as at a catch's end, so the start is served
    by two shifts whose first holds it, without the still catch's 1 s hold and cheaper
    than the way with a catch; each containment of the chain holds exactly and the
    task reaches its goal without balancing mode."""
    from gracenav.execution.capture import capture_for

    row, res = pairs_trial(trial, online_starts=False)
    assert row["reached_goal"] and row["balancing_s"] == 0.0
    t0, plan = res.episodes[0].captures[0]
    assert t0 == 0.0
    names = [p.policy.name for p in plan.policies]
    assert len(names) == 2 and all(n.startswith("shift") for n in names), names
    lib = res.library
    start = np.array([row["start_x"], row["start_y"], 0.0, 0.0])
    assert plan.policies[0].start_domain.contains(start)
    assert plan.policies[1].start_domain.contains_domain(plan.policies[0].goal_domain)
    assert lib.policy(plan.rest_row).start_domain.contains_domain(plan.policies[1].goal_domain)
    hc = HybridController(lib, build_graph(lib))
    togo = hc.tree(hc.goal_policy(np.array([row["goal_x"], row["goal_y"], 0.0, 0.0]))).cost_to_go
    shifts = sum(p.duration for p in plan.policies)
    assert plan.cost == pytest.approx(shifts + togo[plan.rest_row], abs=1e-9)
    cap = capture_for(lib)
    opts = cap.options
    assert opts is not None
    caught = cap.plan(start, lean_deviation=(2 * opts.still_lean[0], 0.0), cost_to_go=togo)
    assert caught is not None and not caught.catch.policy.name.startswith("shift")
    assert plan.cost < caught.cost
