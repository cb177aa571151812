"""Rest trims on the way are skipped when the next policy's start domain already holds
the state (:attr:`gracenav.execution.ExecutionOptions.skip_holds`): the same switching
rule as every switch, checked here from the episode's own states, and a run that
arrives sooner by whole rest trims."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from pairs import pairs_trial

from gracenav.execution import (
    CAPTURE,
    TERMINAL,
    Episode,
    EventReason,
    ExecutionOptions,
    HybridController,
    TaskStatus,
)
from gracenav.execution.capture import ShiftTerminal
from gracenav.policies import PrimitiveKind
from gracenav.scenarios import parse_scenario
from gracenav.scenarios.run import prepare_library
from gracenav.sim import position_state, state_from_position

#: The cluttered 6 m room of examples/campaigns/random_pairs.yaml
#: (examples/maps/room_6m_cluttered.yaml), one lattice halving, a start and a goal at
#: rest off the map's lattice (the campaign's first trial).
ROOM = {
    k: v
    for k, v in yaml.safe_load(
        (
            Path(__file__).resolve().parent.parent / "examples/maps/room_6m_cluttered.yaml"
        ).read_text()
    ).items()
    if k != "name"
}
START = (2.375, 1.125)
GOAL = (3.475, 3.975)


@pytest.fixture(scope="module")
def controller() -> HybridController:
    scenario = parse_scenario(
        {
            "name": "holds",
            "map": ROOM,
            "robot": {"footprint_radius": 0.2},
            # The map's lattice: the goal is off it, and a terminal ends the task.
            "planner": {"cost": "time", "max_halvings": 1, "lattice_anchor": "map"},
            "task": {
                "kind": "point_to_point",
                "goal": [*GOAL, 0.0, 0.0],
                "starts": [[*START, 0.0, 0.0]],
            },
            "simulation": {"max_time": 60},
        },
        source="holds",
    )
    prepared = prepare_library(scenario)
    return HybridController(prepared.library, prepared.graph, criterion="time")


def _run(hc: HybridController, skip: bool) -> Episode:
    x0 = state_from_position(np.array([*START, 0.0, 0.0]), hc.radius)
    # The holds after the start's capture and on the lattice's way to the terminal, not
    # a start or an end designed online (a launch from this start takes the capture's
    # place).
    options = ExecutionOptions(
        max_time=60.0, skip_holds=skip, online_starts=False, online_ends=False
    )
    return hc.run(x0, [np.array([*GOAL, 0.0, 0.0])], options=options)


def _ran_rest_trims(hc: HybridController, ep: Episode) -> list[int]:
    rows = [e.to_policy for e in ep.events if e.to_policy >= 0]
    return [r for r in rows if hc.library.policy(r).policy.primitive.kind is PrimitiveKind.REST]


@pytest.mark.slow
def test_skipped_holds_switch_into_domains_that_hold_the_state(
    controller: HybridController,
) -> None:
    hc = controller
    held = _run(hc, skip=False)
    skipped = _run(hc, skip=True)
    for ep in (held, skipped):
        assert ep.status is TaskStatus.GOAL_REACHED
        final = position_state(ep.states[-1], hc.radius)
        assert np.linalg.norm(final[:2] - np.array(GOAL)) <= 0.05
    # The paper's rule runs a rest trim after the capture and one before the terminal;
    # skipping runs neither here.
    assert len(_ran_rest_trims(hc, held)) >= 2
    assert _ran_rest_trims(hc, skipped) == []
    rest = min(
        hc.library.policy(r).duration for r in _ran_rest_trims(hc, held)
    )  # a rest trim's duration (s)
    saved = held.time[-1] - skipped.time[-1]
    assert saved >= 2 * rest - 1e-9
    # Every switch of the faster run went into a policy whose S holds the state there.
    term = hc.terminal_policies(np.array([*GOAL, 0.0, 0.0]))[0]
    for e in skipped.events[1:]:
        p = position_state(skipped.states[e.tick], hc.radius)
        if e.to_policy == TERMINAL and e.reason is EventReason.HOLD_GOAL:
            # The shifts' last rest tail left for the regulator at the goal.
            assert isinstance(term, ShiftTerminal) and term.hold.policy.capture
            assert term.hold.start_domain.contains(p)
        elif e.to_policy == TERMINAL:
            assert e.reason is EventReason.TERMINAL
            assert term.start_domain.contains(p)
        elif e.to_policy == CAPTURE:
            continue  # the capture's own stages: checked in test_capture.py
        else:
            assert e.reason is EventReason.GRACEFUL
            assert hc.library.policy(e.to_policy).start_domain.contains(p)


def test_holds_are_skipped_by_default() -> None:
    assert ExecutionOptions().skip_holds is True


@pytest.mark.slow
def test_a_settled_terminal_ends_the_task_without_changing_the_motion(
    controller: HybridController,
) -> None:
    """Ending at the first settled tick of the terminal regulator (within 1 cm, over
    0.125 s) only moves the end: the states are those of the run that holds the
    regulator to its end, which goes on from there."""
    hc = controller
    early = _run(hc, skip=True)
    x0 = state_from_position(np.array([*START, 0.0, 0.0]), hc.radius)
    late = hc.run(
        x0,
        [np.array([*GOAL, 0.0, 0.0])],
        options=ExecutionOptions(
            max_time=60.0, settle_tolerance=1e-6, online_starts=False, online_ends=False
        ),
    )
    assert early.events[-1].to_policy == TERMINAL and late.events[-1].to_policy == TERMINAL
    n = early.states.shape[0]
    assert late.states.shape[0] > n + 1024  # a second or more later
    np.testing.assert_array_equal(early.states, late.states[:n])
    p = position_state(early.states[-1], hc.radius)
    assert np.hypot(*(p[:2] - np.array(GOAL))) <= 0.01 + 1e-3  # window mean within 1 cm
    assert np.hypot(*p[2:]) <= 0.05
    q = position_state(late.states[-1], hc.radius)
    assert np.hypot(*(q[:2] - np.array(GOAL))) < np.hypot(*(p[:2] - np.array(GOAL)))


def test_a_lattice_through_the_goal_passes_through_it_at_every_spacing() -> None:
    from gracenav.library import lattice_origin
    from gracenav.world import WorldMap

    world = WorldMap.from_shapes(((0.0, 0.0), (6.0, 6.0)), [], resolution=0.05)
    for spacing in (0.5, 0.25, 0.125):
        for anchor in ((3.475, 3.975), (0.0, 0.0), (5.999999999999, 2.5), (0.3, 5.9)):
            o = lattice_origin(world, spacing, anchor)
            assert np.all(o >= 0.0) and np.all(o < spacing)
            k = (np.asarray(anchor) - o) / spacing
            np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    np.testing.assert_array_equal(lattice_origin(world, 0.5), [0.0, 0.0])


@pytest.mark.slow
def test_a_goal_off_the_map_lattice_ends_on_a_rest_trim_of_the_goal_lattice() -> None:
    """planner.lattice_anchor auto (the default for point-to-point tasks) puts the goal
    on the lattice: the run ends on a rest trim at the goal, with no terminal, and
    sooner than on the map's lattice, where it needs one (the lattice's own ends: with
    online ends, the map's lattice ends this task sooner, 11.30 s against 12.33 s)."""
    from gracenav.scenarios import run_scenario

    def doc(anchor: str) -> dict:
        return {
            "name": "anchor",
            "map": ROOM,
            "robot": {"footprint_radius": 0.2},
            "planner": {
                "cost": "time",
                "max_halvings": 1,
                "lattice_anchor": anchor,
                "online_ends": False,
            },
            "task": {
                "kind": "point_to_point",
                "goal": [*GOAL, 0.0, 0.0],
                "starts": [[*START, 0.0, 0.0]],
            },
            "simulation": {"max_time": 60},
        }

    on_goal = run_scenario(parse_scenario(doc("auto"), source="auto"))
    on_map = run_scenario(parse_scenario(doc("map"), source="map"))
    for result in (on_goal, on_map):
        run = result.runs[0]
        assert run.reached_goal and not run.contact
        assert run.final_error_m is not None and run.final_error_m <= 0.01 + 1e-3
    lib = on_goal.library
    np.testing.assert_allclose((np.array(GOAL) - lib.origin) / lib.spacing % 1.0, 0.0, atol=1e-9)
    last = on_goal.episodes[0].events[-1]
    assert last.to_policy >= 0 and last.to_policy != TERMINAL
    np.testing.assert_allclose(lib.end_state[last.to_policy], [*GOAL, 0.0, 0.0], atol=1e-9)
    assert on_map.episodes[0].events[-1].to_policy == TERMINAL
    assert on_goal.runs[0].time_s < on_map.runs[0].time_s


def _trial(i: int):  # type: ignore[no-untyped-def]
    return pairs_trial(i, online_starts=False)


def _hold_left(ep: Episode, lib):  # type: ignore[no-untyped-def]
    """(the switch that left the start's hold, the tick the hold began, when it would
    have ended): the hold is the start's capture regulator, or the last stage of its
    capture; the switch is the first into a library policy after it."""
    first = ep.events[0]
    k = next(i for i, e in enumerate(ep.events) if i > 0 and e.to_policy >= 0)
    began = ep.events[k - 1]
    if first.to_policy == CAPTURE:
        duration = ep.captures[0][1].policies[-1].duration
    else:
        assert lib.policy(first.to_policy).policy.capture
        duration = lib.policy(first.to_policy).duration
    return ep.events[k], began.tick, began.time + duration


@pytest.mark.slow
@pytest.mark.parametrize("trial", [1, 10, 15])
def test_a_hold_is_left_in_the_still_band_once_the_next_policy_holds_the_state(trial) -> None:
    """Trial 1 of random_pairs.yaml starts with a capture (one shift), trial 10 with a
    capture regulator, trial 15 with two shifts (the second left at its first tick): each
    hold is left before its own end, at its first tick at which the next policy's S holds
    the state and the lean and lean rate are within the still band, into a policy
    verified from that band; the task reaches its goal without leaving a domain or
    balancing."""
    row, res = _trial(trial)
    ep, lib = res.episodes[0], res.library
    assert row["reached_goal"] and row["balancing_s"] == 0.0
    assert all(e.reason is not EventReason.DOMAIN_EXIT for e in ep.events)
    e, began, planned_end = _hold_left(ep, lib)
    assert e.time < planned_end - 0.25
    assert e.reason is EventReason.GRACEFUL
    nxt = lib.policy(e.to_policy)
    assert nxt.policy.starts_from_still_band
    band = lib.palette.options.catch.still_lean
    x = ep.states[e.tick]
    assert np.hypot(*x[2:4]) <= band[0] and np.hypot(*x[6:8]) <= band[1]
    assert nxt.start_domain.contains(position_state(x, ep.radius))
    # Left at the first tick of the hold at which the rule held.
    for tick in range(began, e.tick):
        y = ep.states[tick]
        assert not (
            np.hypot(*y[2:4]) <= band[0]
            and np.hypot(*y[6:8]) <= band[1]
            and nxt.start_domain.contains(position_state(y, ep.radius))
        )


@pytest.mark.slow
def test_a_hold_is_kept_to_its_end_without_the_still_band_verification(monkeypatch) -> None:
    """The same start as trial 1 when the next policy was not verified from the still
    band: the capture runs to its end, and the task ends later."""
    from gracenav.policies import MotionPolicy

    row, _ = _trial(1)
    monkeypatch.setattr(MotionPolicy, "starts_from_still_band", property(lambda self: False))
    late_row, res = _trial(1)
    e, _, planned_end = _hold_left(res.episodes[0], res.library)
    assert e.time >= planned_end - 1e-9
    assert late_row["reached_goal"] and late_row["time_s"] > row["time_s"] + 0.25
