"""Rest trims on the way are skipped when the next policy's start domain already holds
the state (:attr:`gracenav.execution.ExecutionOptions.skip_holds`): the same switching
rule as every switch, checked here from the episode's own states, and a run that
arrives sooner by whole rest trims."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gracenav.execution import (
    CAPTURE,
    TERMINAL,
    Episode,
    EventReason,
    ExecutionOptions,
    HybridController,
    TaskStatus,
)
from gracenav.policies import PrimitiveKind
from gracenav.scenarios import parse_scenario
from gracenav.scenarios.run import prepare_library
from gracenav.sim import position_state, state_from_position

#: The cluttered 6 m room of examples/campaigns/random_pairs.yaml, one lattice halving,
#: a start and a goal at rest off the lattice (the campaign's first trial).
ROOM = {
    "bounds": [[0.0, 0.0], [6.0, 6.0]],
    "resolution": 0.05,
    "obstacles": [
        {"rectangle": {"min": [1.0, 1.0], "max": [2.0, 1.6]}},
        {"rectangle": {"min": [3.5, 0.0], "max": [4.1, 1.2]}},
        {"rectangle": {"min": [4.2, 3.0], "max": [5.0, 4.0]}},
        {"rectangle": {"min": [0.0, 4.3], "max": [1.4, 4.8]}},
        {"circle": {"center": [2.9, 3.1], "radius": 0.35}},
        {"circle": {"center": [1.9, 4.9], "radius": 0.25}},
        {"circle": {"center": [5.3, 1.9], "radius": 0.25}},
        {"polygon": {"points": [[2.6, 5.2], [3.6, 5.2], [3.1, 6.0]]}},
    ],
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
            "planner": {"cost": "time", "max_halvings": 1},
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
    options = dataclasses.replace(ExecutionOptions(max_time=60.0), skip_holds=skip)
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
        if e.to_policy == TERMINAL:
            assert e.reason is EventReason.TERMINAL
            assert term.start_domain.contains(p)
        elif e.to_policy == CAPTURE:
            continue  # the capture's own stages: checked in test_capture.py
        else:
            assert e.reason is EventReason.GRACEFUL
            assert hc.library.policy(e.to_policy).start_domain.contains(p)


def test_holds_are_skipped_by_default() -> None:
    assert ExecutionOptions().skip_holds is True
    assert dataclasses.replace(ExecutionOptions(), skip_holds=False).skip_holds is False


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
        options=ExecutionOptions(max_time=60.0, settle_tolerance=1e-6),
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
