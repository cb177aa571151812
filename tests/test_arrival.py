"""Ends at rest through one maneuver designed and verified when the task starts
(``ExecutionOptions.online_ends``, :mod:`gracenav.execution.arrival`)."""

from __future__ import annotations

import numpy as np
import pytest
from pairs import launch_without_fine_copies, pairs_trial
from reverify import assert_holds_from_unchosen_points

from gracenav.execution import CAPTURE, TERMINAL, EventReason, ExecutionOptions
from gracenav.execution.capture import capture_for
from gracenav.policies import PrimitiveKind

TICK = 1.0 / 1024


def test_online_ends_are_on_by_default() -> None:
    assert ExecutionOptions().online_ends is True


def _arrived_sooner(trial: int, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """Trial ``trial`` of the random pairs with online ends, without them, and with the
    same start but the end maneuver not taken (the tree's way to the goal): all reach
    the goal, with them without contact or balancing, sooner than without them, and
    sooner than the same start's tree way by the plan's saving (to a few ticks of
    settling), through the end maneuver, entered by a graceful switch when the policy
    it follows ends. Returns the row and the run with them (the row also with
    ``time_without_s``, the tree way's time), and its arrival plan."""
    from gracenav.execution.supervisor import Supervisor

    off, _ = pairs_trial(trial, online_starts=True, online_ends=False)
    row, result = pairs_trial(trial, online_starts=True)
    init = Supervisor.__init__

    def not_taken(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        init(self, *args, **kwargs)
        self.arrival = None

    with monkeypatch.context() as m:
        m.setattr(Supervisor, "__init__", not_taken)
        row0, res0 = pairs_trial(trial, online_starts=True)
    assert off["reached_goal"] and row0["reached_goal"] and row["reached_goal"]
    assert res0.episodes[0].arrival is None
    assert row["min_clearance_m"] >= 0.0 and row["balancing_s"] == 0.0
    assert row["time_s"] <= off["time_s"]
    ep = result.episodes[0]
    arrival = ep.arrival
    assert arrival is not None and arrival.saving >= 1.0
    # The same start: the run's first events are the same.
    assert res0.episodes[0].events[:2] == ep.events[:2]
    # At least the saving priced (off the lattice the regulator's shorter settling too).
    assert row["time_s"] <= row0["time_s"] - arrival.saving + 0.25
    row["time_without_s"] = row0["time_s"]
    into = [k for k, e in enumerate(ep.events) if k > 0 and e.to_policy == CAPTURE]
    assert len(into) == 1
    k = into[0]
    assert ep.events[k].reason is EventReason.GRACEFUL
    assert ep.events[k - 1].to_policy == arrival.after
    # It runs to its end, then what follows at the goal takes over.
    maneuver = arrival.plan.catch
    assert ep.events[k + 1].time == pytest.approx(
        ep.events[k].time + maneuver.duration, abs=2 * TICK
    )
    assert ep.events[k + 1].to_policy == arrival.plan.rest_row
    return row, result, arrival


def _check_domains(result, arrival) -> None:  # type: ignore[no-untyped-def]
    """The prepares relation both ways, exactly, and the sweep clear of the map."""
    lib = result.library
    maneuver = arrival.plan.catch
    assert maneuver.start_domain.contains_domain(lib.policy(arrival.after).goal_domain)
    path, reach = capture_for(lib).swept(maneuver.policy)
    assert np.all(capture_for(lib).clear(maneuver.start_xy + path, reach))
    # From the policy's end state, straight to rest.
    prim = maneuver.primitive
    end = lib.end_state[arrival.after]
    assert np.allclose(maneuver.start_xy, end[:2])
    assert np.allclose(prim.start_velocity, end[2:], atol=1e-9)
    assert np.allclose(prim.end_velocity, 0.0, atol=1e-9)


@pytest.mark.slow
def test_an_end_on_the_lattice_takes_one_verified_maneuver_to_the_goal(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Trial 19 of the random pairs ends with a stop and a 4 s rest-to-rest step onto
    the goal; with online ends one maneuver from the cruise before them runs straight to
    rest at the goal's rest trim, whose S holds its G; it holds again from points its
    verification did not choose, and the task ends 2.25 s sooner."""
    launch_without_fine_copies(monkeypatch)
    row, result, arrival = _arrived_sooner(19, monkeypatch)
    assert row["time_s"] == pytest.approx(row["time_without_s"] - arrival.saving, abs=0.25)
    lib = result.library
    _check_domains(result, arrival)
    goal = lib.policy(arrival.plan.rest_row)
    assert goal.policy.primitive.kind is PrimitiveKind.REST
    maneuver = arrival.plan.catch
    assert goal.start_domain.contains_domain(maneuver.goal_domain)
    assert np.allclose(maneuver.start_xy + maneuver.primitive.displacement, goal.start_xy)
    assert_holds_from_unchosen_points(
        arrival.plan.catch.policy,
        lib.palette.options,
        boundary_points=24,
        interior=6,
        seed=19,
        placements=(0,),
    )


@pytest.mark.slow
def test_an_end_off_the_lattice_hands_over_to_the_regulator_at_the_goal(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Trial 16's goal is off the lattice: the lattice stops, steps, and shifts onto the
    grid point next to the goal before the regulator there holds it (11.6 s). With online
    ends one maneuver from the cruise runs to rest at the goal itself and the
    regulator, whose S holds its G, settles it there: the task ends in 6.5 s."""
    row, result, arrival = _arrived_sooner(16, monkeypatch)
    _check_domains(result, arrival)
    assert arrival.plan.rest_row == TERMINAL
    ep = result.episodes[0]
    (k,) = [k for k, e in enumerate(ep.events) if k > 0 and e.to_policy == CAPTURE]
    assert ep.events[k + 1].reason is EventReason.HOLD_GOAL
    maneuver = arrival.plan.catch
    goal = maneuver.start_xy + maneuver.primitive.displacement
    assert np.hypot(*(goal - np.array([row["goal_x"], row["goal_y"]]))) <= 1e-9
    assert_holds_from_unchosen_points(
        arrival.plan.catch.policy,
        result.library.palette.options,
        boundary_points=24,
        interior=6,
        seed=16,
        placements=(0,),
    )


@pytest.mark.slow
def test_an_end_on_a_lazy_tree(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the graph keeps no reversed graph (building-scale maps) the trees are lazy,
    read only as far as asked: trial 19 forced onto a lazy tree (by lowering
    :data:`gracenav.planning.graph.STORED_EDGES`) takes an end maneuver too, and
    arrives as the whole tree's run does."""
    import gracenav.execution.controller as controller_module
    import gracenav.planning.graph as graph_module
    from gracenav.planning import LazyPolicyTree

    launch_without_fine_copies(monkeypatch)
    whole, res = pairs_trial(19, online_starts=True)
    made: list[LazyPolicyTree] = []

    class Recorded(LazyPolicyTree):
        def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(graph_module, "STORED_EDGES", 0)
    monkeypatch.setattr(controller_module, "LazyPolicyTree", Recorded)
    lazy, res_lazy = pairs_trial(19, online_starts=True)
    assert made and all(t.expanded < len(res_lazy.library) for t in made)
    a, b = res.episodes[0].arrival, res_lazy.episodes[0].arrival
    assert a is not None and b is not None
    assert (b.after, b.saving) == (a.after, a.saving)
    assert lazy["reached_goal"] and lazy["balancing_s"] == 0.0
    assert lazy["time_s"] == pytest.approx(whole["time_s"], abs=1e-9)


def _room_task(goal: tuple[float, float], start: tuple[float, float], ends: bool):  # type: ignore[no-untyped-def]
    """The random pairs' room on the map's lattice (``bench/bench_goals.py``): a goal
    off the lattice, at rest from a start at rest."""
    import copy
    from pathlib import Path

    import yaml

    from gracenav.scenarios import parse_scenario, run_scenario

    pairs = Path(__file__).resolve().parent.parent / "examples" / "campaigns"
    doc = copy.deepcopy(yaml.safe_load((pairs / "random_pairs.yaml").read_text())["scenario"])
    doc["planner"]["lattice_anchor"] = "map"
    doc["planner"]["online_ends"] = ends
    doc["task"]["goal"] = [goal[0], goal[1], 0.0, 0.0]
    doc["task"]["starts"] = [[start[0], start[1], 0.0, 0.0]]
    return run_scenario(parse_scenario(doc, source="room"))


@pytest.mark.slow
def test_an_end_saves_a_shift_terminals_shifts() -> None:
    """A goal off the lattice reached through a shift terminal: from the approach trim,
    shifts to the grid point next to the goal, then the regulator at the goal. The end
    maneuver runs straight to rest at the goal instead of the stop and the shifts, so
    its saving counts the shifts too (priced without them, no maneuver paid here); the
    regulator at the goal takes over from it, and the run is sooner by about the
    saving."""
    goal, start = (3.874, 4.319), (5.5, 5.5)
    off = _room_task(goal, start, ends=False)
    on = _room_task(goal, start, ends=True)
    ep_off, ep = off.episodes[0], on.episodes[0]
    assert off.runs[0].reached_goal and on.runs[0].reached_goal
    assert ep_off.arrival is None
    arrival = ep.arrival
    assert arrival is not None and arrival.plan.rest_row == TERMINAL
    # Without online ends: a rest-to-rest step onto the approach trim, the terminal's
    # shift (3.25 s and 2 s), then its hold at the goal; the maneuver (3.6 s) pays only
    # with the shift counted.
    reasons = [e.reason for e in ep_off.events if e.to_policy == TERMINAL]
    assert reasons == [EventReason.TERMINAL, EventReason.HOLD_GOAL]
    shift_started = next(e.time for e in ep_off.events if e.to_policy == TERMINAL)
    held = next(e.time for e in ep_off.events if e.reason is EventReason.HOLD_GOAL)
    step = ep_off.events[1]
    way_after = off.library.policy(step.to_policy).duration
    assert arrival.after == ep_off.events[0].to_policy  # from the first step's end
    assert arrival.saving > way_after - arrival.plan.catch.duration + 1.0
    assert held - shift_started >= 1.0
    saved = off.runs[0].time_s - on.runs[0].time_s
    assert saved >= 1.0
    assert saved == pytest.approx(arrival.saving, abs=0.25)
    (k,) = [k for k, e in enumerate(ep.events) if k > 0 and e.to_policy == CAPTURE]
    assert ep.events[k].reason is EventReason.GRACEFUL
    assert ep.events[k + 1].to_policy == TERMINAL
    maneuver = arrival.plan.catch
    assert np.hypot(*(maneuver.start_xy + maneuver.primitive.displacement - goal)) <= 1e-9


@pytest.mark.slow
def test_an_end_longer_than_the_palettes_maneuvers(monkeypatch: pytest.MonkeyPatch) -> None:
    """Trial 25's way passes a cruise policy whose end lies farther from the goal than
    a nonic from cruise to rest covers within the palette's 4.5 s. Kept to the palette's
    longest maneuver, its end saves less; with the default
    (:data:`gracenav.execution.online.LONGEST`, 6.5 s) one maneuver of more than 4.5 s
    runs from there to rest at the goal, entered by a graceful switch, its S holding the
    G of the policy it follows and its sweep clear; it holds again from points its
    verification did not choose, and the task ends sooner by the difference of the
    savings."""
    import functools

    import gracenav.execution.arrival as arrival_module
    from gracenav.execution.arrival import ArrivalOptions

    with monkeypatch.context() as m:
        m.setattr(arrival_module, "ArrivalOptions", functools.partial(ArrivalOptions, longest=None))
        short_row, short = pairs_trial(25, online_starts=True)
    row, result = pairs_trial(25, online_starts=True)
    assert row["reached_goal"] and short_row["reached_goal"]
    assert row["min_clearance_m"] >= 0.0 and row["balancing_s"] == 0.0
    arrival, before = result.episodes[0].arrival, short.episodes[0].arrival
    assert arrival is not None
    kept = before.saving if before is not None else 0.0
    assert arrival.saving >= kept + 0.25
    assert arrival.plan.catch.duration > short.library.palette.primitive_options.max_duration
    assert row["time_s"] == pytest.approx(short_row["time_s"] - (arrival.saving - kept), abs=0.05)
    _check_domains(result, arrival)
    ep = result.episodes[0]
    (k,) = [k for k, e in enumerate(ep.events) if k > 0 and e.to_policy == CAPTURE]
    assert ep.events[k].reason is EventReason.GRACEFUL
    assert ep.events[k - 1].to_policy == arrival.after
    assert_holds_from_unchosen_points(
        arrival.plan.catch.policy,
        result.library.palette.options,
        boundary_points=24,
        interior=6,
        seed=25,
        placements=(0,),
    )
