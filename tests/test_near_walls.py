"""Regression scenarios near walls: corner starts and goals, and a patrol 0.5 m from the
walls, each run with the default settings (stopping allowance included) to the end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gracenav.scenarios import load_scenario, run_scenario

HERE = Path(__file__).parent / "data" / "scenarios"


@pytest.mark.parametrize("name", ["corner_starts_5m", "corner_starts_6m"])
def test_corner_starts_reach_a_corner_goal(name: str) -> None:
    result = run_scenario(load_scenario(HERE / f"{name}.yaml"))
    sc = result.scenario
    assert len(result.runs) == 3
    for run, ep in zip(result.runs, result.episodes, strict=True):
        assert run.reached_goal and not run.contact, run
        assert run.final_error_m < 0.01
        assert run.captures == 0 and run.balancing_s == 0.0
        # The footprint kept its distance from every wall and obstacle at every tick.
        clear = sc_clearance(result, ep)
        assert clear > 0.0, clear
    assert sc.speed_clearance > 0.0  # the default stopping allowance


def test_patrol_half_a_metre_from_the_walls() -> None:
    result = run_scenario(load_scenario(HERE / "wall_patrol.yaml"))
    run, ep = result.runs[0], result.episodes[0]
    assert run.outcome == "loops_completed"
    assert run.goals_reached == 8 and not run.contact
    assert run.non_graceful_switches == 0
    assert sc_clearance(result, ep) > 0.0
    # Each moving goal was met at its state: 0.5 m/s along a wall 0.5 m from it.
    goals = np.asarray(result.scenario.goals)
    for t, k in ep.goals_reached:
        i = int(np.searchsorted(ep.time, t))
        err = ep.position_state[i] - goals[k % len(goals)]
        assert np.hypot(*err[:2]) < 0.05 and np.hypot(*err[2:]) < 0.05, (t, k, err)


def sc_clearance(result, ep) -> float:
    """Least distance (m) from the footprint to a wall or obstacle over the episode."""
    sc = result.scenario
    xy = ep.position_state[:, :2]
    return float(np.min(result.library.world_map.clearance(xy))) - sc.footprint_radius
