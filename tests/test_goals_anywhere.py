"""Goals at rest anywhere the robot fits, starts at rest near walls, and goals next to a
parked obstacle: shift terminals, two-shift captures onto a rest trim that reaches the
goal, other ends of the way while a cart blocks the goal's own, and ``blocked`` when
no way ever opens."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gracenav.errors import PlanningError
from gracenav.execution import CAPTURE, TERMINAL, EventReason, HybridController, TaskStatus
from gracenav.execution.capture import ShiftTerminal, TerminalPolicy, capture_for
from gracenav.scenarios import parse_scenario, run_scenario
from gracenav.scenarios.run import prepare_library
from gracenav.world import forest_map, save_ros_map

FOOT = 0.2
ROOT = Path(__file__).resolve().parent.parent
#: The 5 m room with a central 1 m box (examples/maps/room_5m_box.yaml).
BOX_ROOM = {
    "bounds": [[0.0, 0.0], [5.0, 5.0]],
    "resolution": 0.05,
    "obstacles": [{"rectangle": {"min": [2.0, 2.0], "max": [3.0, 3.0]}}],
}
#: A grid point of the shift terminals is within half a diagonal of a grid cell (d/16)
#: of the goal; the tracking error adds a few millimetres.
_GRID_HALF_DIAGONAL = 0.5 * np.hypot(0.5 / 16, 0.5 / 16)


def _task(world: object, goal: tuple[float, float], start: tuple[float, float], **extra) -> dict:
    data = {
        "name": "goals anywhere",
        "map": world,
        "robot": {"footprint_radius": FOOT},
        "planner": {"cost": "time"},
        "task": {
            "kind": "point_to_point",
            "goal": [*goal, 0.0, 0.0],
            "starts": [[*start, 0.0, 0.0]],
        },
        "simulation": {"max_time": 60},
    }
    data.update(extra)
    return data


@pytest.fixture(scope="module")
def forest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sparse forest of posts (seed 1, density 0.012) as a ROS map file."""
    path = tmp_path_factory.mktemp("forest") / "forest.yaml"
    save_ros_map(forest_map(seed=1, density=0.012), path, image_format="png")
    return path


def test_a_goal_between_posts_is_reached_through_shifts_without_contact(forest: Path) -> None:
    """0.25 m beyond the footprint from a post, no rest trim's G holds the goal and no
    capture regulator fits (the smallest fits, but the nearest rest trim is 0.15 m off,
    outside its S): a shift from that rest trim's end to the grid point next to the
    goal, then a rest hold there, brings the robot onto it."""
    goal = (13.0, 2.25)
    scenario = parse_scenario(
        _task(
            {"ros_map": str(forest)},
            goal,
            (15.0, 2.25),
            # The goal off the lattice; its terminal, not an end designed online.
            planner={"cost": "time", "lattice_anchor": "map", "online_ends": False},
        ),
        source="forest.yaml",
    )
    prepared = prepare_library(scenario)
    lib = prepared.library
    hc = HybridController(lib, prepared.graph)
    g = np.array([*goal, 0.0, 0.0])
    terms = hc.terminal_policies(g)
    assert terms and all(isinstance(t, ShiftTerminal) for t in terms)
    term = terms[0]
    assert isinstance(term, ShiftTerminal)
    assert hc.goal_policy(g) == term.approach
    # The chain's containments, exactly: rest trim G ⊂ S of the first shift, each G ⊂
    # the next S, the last G ⊂ the hold's S; the goal in the hold's G.
    before = lib.policy(term.approach).goal_domain
    for stage in term.stages:
        assert stage.start_domain.contains_domain(before)
        before = stage.goal_domain
    assert term.goal_domain.contains(g)
    assert np.hypot(*(term.goal_xy - g[:2])) <= _GRID_HALF_DIAGONAL + 1e-12
    # The swept D' grown by the footprint is clear of the posts.
    room = lib.world_map.clearance(term.sweep_points) - FOOT - term.sweep_reach
    assert room.min() >= 0.0

    result = run_scenario(scenario, prepared=prepared)
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal and run.stop_reason == "goal_reached"
    assert not run.contact and run.min_clearance_m >= 0.0
    assert run.final_error_m is not None and run.final_error_m <= _GRID_HALF_DIAGONAL + 0.005
    assert run.final_speed_mps <= 0.01
    assert any(e.reason is EventReason.TERMINAL for e in ep.events)
    assert ep.policy[-2] == TERMINAL and run.balancing_s == 0.0


def test_where_no_terminal_fits_the_refusal_says_why(box_room_library, box_room_graph) -> None:
    """0.07 m beyond the footprint from the wall: neither a regulator (0.22 m) nor a
    shift's D' (0.11 m) fits; the message names both and what to do."""
    hc = HybridController(box_room_library, box_room_graph)
    with pytest.raises(PlanningError, match="no capture regulator fits there") as err:
        hc.goal_policy([0.27, 2.63, 0.0, 0.0])
    msg = str(err.value)
    assert "needs 0.22 m" in msg
    assert "no shift ends there" in msg and "the goal has 0.070 m" in msg
    assert "move the goal to at least 0.11" in msg
    # A goal with room for a shift but none for a regulator is accepted.
    g = np.array([0.34, 2.63, 0.0, 0.0])
    terms = hc.terminal_policies(g)
    assert terms and isinstance(terms[0], ShiftTerminal)
    assert hc.goal_policy(g) == terms[0].approach


def test_regulator_ends_become_shifts_from_the_same_approach(
    box_room_library, box_room_graph
) -> None:
    """Where capture regulators fit, the task approaches the goal through the same rest
    trims as before, in the same order; from each one that shifts reach the goal from,
    it ends with the shifts and a regulator at the goal instead of the regulator's step
    of the reference."""
    hc = HybridController(box_room_library, box_room_graph)
    g = np.array([1.13, 1.37, 0.0, 0.0])
    terms = hc.terminal_policies(g)
    regulators = hc.goals._regulators(g, every_size=False)
    assert regulators and all(isinstance(t, TerminalPolicy) for t in regulators)
    assert [t.approach for t in terms] == [t.approach for t in regulators]
    shifts = [t for t in terms if isinstance(t, ShiftTerminal)]
    assert isinstance(terms[0], ShiftTerminal) and len(shifts) >= len(terms) // 2
    for term in shifts:
        assert term.hold.policy.capture
        np.testing.assert_allclose(term.goal_xy, g[:2], atol=1e-12)
        before = box_room_library.policy(term.approach).goal_domain
        for stage in term.stages:
            assert stage.start_domain.contains_domain(before)
            before = stage.goal_domain
        assert term.goal_domain.contains(g)


@pytest.mark.parametrize("online_ends", [False, True])
@pytest.mark.parametrize("noise", [0.0, 0.005])
def test_a_goal_off_the_lattice_ends_without_a_step(noise: float, online_ends: bool) -> None:
    """A goal off the map's lattice, 1 cm off the shifts' grid: the shifts and a hold at
    the goal end the task within the settle tolerance of it, the reference never steps
    by more than the grid's half diagonal (the regulator's step to the goal is up to
    0.2 m), and the ball's jerk stays within the shifts' bound (the regulator's step
    jerks it at 30-40 m/s³); with 5 mm of position noise on the measured state too.
    With online ends, one maneuver straight to rest at the goal takes the place of the
    shifts, and the hold at the goal takes over from it: the same holds."""
    goal = (1.13 + 0.01, 1.37)
    scenario = parse_scenario(
        _task(
            BOX_ROOM,
            goal,
            (4.0, 4.25),
            planner={"cost": "time", "lattice_anchor": "map", "online_ends": online_ends},
            simulation={"max_time": 60, "position_noise_std": noise, "seed": 3},
        ),
        source="box.yaml",
    )
    result = run_scenario(scenario)
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal and run.stop_reason == "goal_reached"
    if online_ends:
        assert ep.arrival is not None and ep.arrival.plan.rest_row == TERMINAL
        assert not any(e.reason is EventReason.TERMINAL for e in ep.events)
        assert ep.events[-1].reason is EventReason.HOLD_GOAL
    else:
        assert ep.arrival is None
        assert any(e.reason is EventReason.TERMINAL for e in ep.events)
    assert run.final_error_m is not None and run.final_error_m <= 0.011
    steps = np.hypot(*np.diff(ep.reference[:, :2], axis=0).T)
    assert steps.max() <= _GRID_HALF_DIAGONAL + 1e-3
    assert run.max_jerk_mps3 <= 12.0


CLUTTERED = ROOT / "examples" / "maps" / "room_6m_cluttered.yaml"


def test_a_start_near_walls_is_caught_onto_a_rest_trim_that_reaches_the_goal() -> None:
    """At rest 0.3 m beyond the footprint from two walls, with the default stopping
    allowance: the start is served by shifts onto a rest trim with a way out (a shift
    whose S, placed at the grid point next to the start, holds it; before, a still
    catch first, and two shifts before the palette had fine copies). Online starts off:
    the capture is what this looks at; with them, the next test."""
    scenario = parse_scenario(
        _task(
            _inline(CLUTTERED),
            (3.0, 2.25),
            (5.5, 0.5),
            planner={"cost": "time", "online_starts": False},
        ),
        source="cluttered.yaml",
    )
    assert scenario.speed_clearance == pytest.approx(0.1)
    result = run_scenario(scenario)
    run, ep = result.runs[0], result.episodes[0]
    assert ep.events[0].to_policy == CAPTURE
    plan = ep.captures[0][1]
    assert 1 <= len(plan.policies) <= 3
    assert all(p.policy.name.startswith("shift") for p in plan.policies)
    start = np.array([5.5, 0.5, 0.0, 0.0])
    assert plan.policies[0].start_domain.contains(start)
    for before, after in zip(plan.policies, plan.policies[1:], strict=False):
        assert after.start_domain.contains_domain(before.goal_domain)
    rest = result.library.policy(plan.rest_row)
    assert rest.start_domain.contains_domain(plan.policies[-1].goal_domain)
    assert run.reached_goal and not run.contact and run.min_clearance_m >= 0.0
    assert run.final_error_m is not None and run.final_error_m <= 0.01
    assert run.balancing_s == 0.0


def test_a_start_near_walls_launched_online_clears_them() -> None:
    """The same start near two walls with online starts (the default): one maneuver
    designed at the start, whose S holds the start and whose G the next policy's S
    holds, with its swept D' clear of the walls; the task reaches the goal without
    contact, no later than through the shifts."""
    doc = _task(_inline(CLUTTERED), (3.0, 2.25), (5.5, 0.5))
    result = run_scenario(parse_scenario(doc, source="cluttered.yaml"))
    doc["planner"] = {"cost": "time", "online_starts": False}
    shifted = run_scenario(parse_scenario(doc, source="cluttered.yaml"))
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal and not run.contact and run.min_clearance_m >= 0.0
    assert run.final_error_m is not None and run.final_error_m <= 0.01
    assert run.balancing_s == 0.0 and run.verified_recoveries == 0
    assert run.time_s <= shifted.runs[0].time_s + 1e-9
    (t0, plan), *_ = ep.captures
    assert t0 == 0.0 and plan.catch.policy.name == "launch"
    assert plan.catch.start_domain.contains(np.array([5.5, 0.5, 0.0, 0.0]))
    after = result.library.policy(plan.rest_row)
    assert after.start_domain.contains_domain(plan.catch.goal_domain)
    capture = capture_for(result.library)
    path, reach = capture.swept(plan.catch.policy)
    assert np.all(capture.clear(plan.catch.start_xy + path, reach))


def test_a_start_on_another_sub_lattice_ends_through_another_rest_trim() -> None:
    """In the 1 m passage between the table and the south wall the rest trims cannot
    reach the goal's own rest trim (another sub-lattice; no capture regulator fits
    there to join them): the task ends on a rest trim they reach and a terminal. With
    online ends, one maneuver from the policy before that rest trim runs straight to
    the terminal's hold at the goal instead, sooner."""
    runs = {}
    for ends in (False, True):
        doc = _task(_inline(CLUTTERED), (3.0, 2.25), (1.5, 0.5))
        doc["planner"]["online_ends"] = ends
        result = run_scenario(parse_scenario(doc, source="cluttered.yaml"))
        run, ep = result.runs[0], result.episodes[0]
        assert run.reached_goal and not run.contact and run.min_clearance_m >= 0.0
        assert run.final_error_m is not None
        assert run.final_error_m <= _GRID_HALF_DIAGONAL + 0.005
        runs[ends] = (run, ep)
    run, ep = runs[False]
    assert ep.arrival is None
    assert any(e.reason is EventReason.TERMINAL for e in ep.events)
    run_ends, ep_ends = runs[True]
    assert ep_ends.arrival is not None and ep_ends.arrival.plan.rest_row == TERMINAL
    assert ep_ends.events[-1].reason is EventReason.HOLD_GOAL
    assert ep_ends.events[-1].to_policy == TERMINAL
    assert run_ends.time_s <= run.time_s - 1.0


def test_a_start_where_the_library_has_no_way_out_is_refused_with_the_reason() -> None:
    """In the pocket between the bench and the north wall the rest trims reach only each
    other (its way out passes the bin with 0.21 m beyond the footprint, less than any
    moving policy's D' needs) and the nearest rest trim outside is 1.75 m away, beyond
    two shifts: the start is refused, saying so."""
    scenario = parse_scenario(
        _task(_inline(CLUTTERED), (3.0, 2.25), (0.75, 5.5)), source="cluttered.yaml"
    )
    with pytest.raises(PlanningError, match="at most two shifts"):
        run_scenario(scenario)


def _inline(path: Path) -> dict:
    import yaml

    doc = yaml.safe_load(path.read_text())
    doc.pop("name", None)
    return doc


def _cart(x: float, y: float, **keys: float) -> dict:
    return {"moving_obstacles": [{"name": "cart", "radius": 0.5, "path": [[x, y]], **keys}]}


@pytest.mark.parametrize(
    ("goal", "cart"),
    [
        # Off the lattice: the terminal regulator (D' 0.61 m) is blocked, the rest trim
        # it starts from is not; the robot used to go back and forth between them.
        ((3.9, 4.1), (2.82, 4.1)),
        # On the lattice: the goal's own rest trim (S = 3 G, D' 0.38 m) is blocked.
        ((4.0, 4.0), (4.0, 2.92)),
    ],
)
def test_a_cart_parked_next_to_the_goal_is_passed_by_another_end_of_the_way(
    goal: tuple[float, float], cart: tuple[float, float]
) -> None:
    """A cart (radius 0.5 m) parked from the start 0.38 m beyond the footprint from the
    goal: the task ends through a shift terminal clear of it."""
    assert np.hypot(goal[0] - cart[0], goal[1] - cart[1]) == pytest.approx(0.5 + FOOT + 0.38)
    scenario = parse_scenario(
        _task(BOX_ROOM, goal, (1.0, 1.0), **_cart(*cart, appear=0.0)), source="depot.yaml"
    )
    result = run_scenario(scenario)
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal and run.stop_reason == "goal_reached"
    assert not run.contact and run.min_clearance_m >= 0.0  # against the cart too
    assert run.final_error_m is not None and run.final_error_m <= _GRID_HALF_DIAGONAL + 0.005
    assert run.time_s <= 40.0
    assert any(e.reason is EventReason.TERMINAL for e in ep.events)
    assert len(ep.events) <= 15  # no back and forth


def _without_shifts(palette):
    return dataclasses.replace(palette, shifts=())


def test_a_way_that_never_opens_ends_blocked(palette) -> None:
    """With a palette without shifts the terminal regulator is the goal's only end and
    the parked cart blocks it: the robot waits on the rest trim before it, and the run
    ends ``blocked`` (it went back and forth and ended ``timeout`` before)."""
    scenario = parse_scenario(
        _task(BOX_ROOM, (3.9, 4.1), (1.0, 1.0), **_cart(2.82, 4.1, appear=0.0))
        | {"simulation": {"max_time": 30}},
        source="depot.yaml",
    )
    result = run_scenario(scenario, palette=_without_shifts(palette))
    run, ep = result.runs[0], result.episodes[0]
    assert ep.status is TaskStatus.BLOCKED and run.outcome == "blocked"
    assert not run.reached_goal and not run.contact and run.min_clearance_m >= 0.0
    assert run.blocked_s >= 15.0
    assert ep.events[-1].reason is EventReason.BLOCKED and ep.events[-1].to_policy >= 0
    assert sum(e.reason is EventReason.TERMINAL for e in ep.events) == 0
    assert run.final_error_m is not None and 0.1 <= run.final_error_m <= 0.2  # at the trim


def test_a_way_that_opens_later_is_taken(palette) -> None:
    """The same cart leaves at 20 s: the robot resumes and ends with the regulator."""
    scenario = parse_scenario(
        _task(BOX_ROOM, (3.9, 4.1), (1.0, 1.0), **_cart(2.82, 4.1, appear=0.0, leave=20.0)),
        source="depot.yaml",
    )
    result = run_scenario(scenario, palette=_without_shifts(palette))
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal and not run.contact
    assert run.final_error_m is not None and run.final_error_m <= 0.01  # settle_tolerance
    reasons = [e.reason for e in ep.events]
    assert EventReason.BLOCKED in reasons and EventReason.RESUMED in reasons
    assert ep.events[-1].reason is EventReason.TERMINAL and ep.time[-1] > 20.0


def test_the_other_end_holds_when_looks_land_later(box_room_library, box_room_graph) -> None:
    """With looks computed in the background (``planning="modelled"``), a look that
    lands after the task's end moved is applied to the tree of the new end: the lattice
    goal next to the parked cart is reached as with instant looks."""
    from gracenav.execution import ExecutionOptions
    from gracenav.sim import state_from_position
    from gracenav.world import MovingObstacle
    from gracenav.world.moving import moving_clearance

    hc = HybridController(box_room_library, box_room_graph)
    cart = MovingObstacle(radius=0.5, path=((4.0, 2.92),), appear=0.0)
    goal = np.array([4.0, 4.0, 0.0, 0.0])
    options = ExecutionOptions(planning="modelled", planning_latency=0.02, max_time=60.0)
    ep = hc.run(
        state_from_position([1.0, 1.0, 0.0, 0.0], hc.radius),
        [goal],
        options=options,
        moving_obstacles=[cart],
    )
    assert ep.status is TaskStatus.GOAL_REACHED
    p = ep.position_state
    assert np.hypot(*(p[-1, :2] - goal[:2])) <= 0.01
    assert np.min(moving_clearance([cart], p[:, :2], ep.time)) - FOOT >= 0.0
    assert np.min(box_room_library.world_map.clearance(p[:, :2])) - FOOT >= 0.0
