"""The decoupled baseline: grid path, smoothing, timing, tracking, replanning, falls."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from gracenav.baseline import (
    BASELINE_POLICY,
    DecoupledOptions,
    MotionLimits,
    grid_path,
    motion_limits,
    plan_decoupled,
    shortcut_path,
    smooth_path,
    time_parameterize,
)
from gracenav.errors import ConfigError, PlanningError
from gracenav.execution import TaskStatus
from gracenav.palette import Palette
from gracenav.scenarios import parse_scenario
from gracenav.scenarios.decoupled import run_decoupled
from gracenav.world import WorldMap, load_map

FOOTPRINT = 0.2
ROOM = {
    "bounds": [[0.0, 0.0], [5.0, 5.0]],
    "resolution": 0.05,
    "obstacles": [{"rectangle": {"min": [2.0, 2.0], "max": [3.0, 3.0]}}],
}
LIMITS = MotionLimits(max_speed=0.5, max_acceleration=0.6, max_jerk=1.7)


def _length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def _scenario(**extra: object) -> dict[str, object]:
    data: dict[str, object] = {
        "name": "room",
        "map": ROOM,
        "robot": {"footprint_radius": FOOTPRINT},
        "task": {"kind": "point_to_point", "goal": [4, 4, 0, 0], "starts": [[1, 1, 0, 0]]},
        "simulation": {"max_time": 25},
    }
    data.update(extra)
    return data


@pytest.fixture(scope="module")
def room() -> WorldMap:
    return load_map(ROOM)


@pytest.fixture(scope="module")
def empty() -> WorldMap:
    return load_map({"bounds": [[0.0, 0.0], [3.0, 3.0]], "resolution": 0.05})


@pytest.mark.parametrize(
    ("goal", "cells"),
    [((2.475, 0.525), (39, 0)), ((2.475, 2.475), (39, 39)), ((1.125, 2.475), (12, 39))],
)
def test_grid_path_is_the_octile_distance_on_an_empty_map(
    empty: WorldMap, goal: tuple[float, float], cells: tuple[int, int]
) -> None:
    # Start and goal on cell centres: the optimal 8-connected length is the octile
    # distance min(i, j) √2 + |i − j| cells.
    path = grid_path(empty, (0.525, 0.525), goal, 0.3)
    i, j = cells
    octile = 0.05 * (min(i, j) * math.sqrt(2.0) + abs(i - j))
    assert _length(path) == pytest.approx(octile, rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(path[-1], goal, rtol=0, atol=1e-12)


def test_grid_path_keeps_the_footprint_and_margin(room: WorldMap) -> None:
    margin = 0.1
    path = grid_path(room, (1, 1), (4, 4), FOOTPRINT + margin)
    clear = room.clearance(path)
    assert np.min(clear[1:-1]) >= FOOTPRINT + margin - 1e-12
    frac = np.linspace(0, 1, 20)[:, None]
    dense = np.concatenate([a + frac * (b - a) for a, b in itertools.pairwise(path)])
    assert np.min(room.clearance(dense)) >= FOOTPRINT
    # around the box: longer than the straight line, no longer than a detour along it
    assert math.hypot(3, 3) < _length(path) < 3 + 3 + 0.5


def test_unreachable_goal_raises_planning_error() -> None:
    wall = load_map(
        {
            "bounds": [[0.0, 0.0], [5.0, 5.0]],
            "resolution": 0.05,
            "obstacles": [{"rectangle": {"min": [2.4, 0.0], "max": [2.6, 5.0]}}],
        }
    )
    with pytest.raises(PlanningError, match=r"cannot be reached from \(1, 1\)"):
        grid_path(wall, (1, 1), (4, 4), FOOTPRINT)
    data = _scenario(
        map={
            "bounds": [[0.0, 0.0], [5.0, 5.0]],
            "resolution": 0.05,
            "obstacles": [{"rectangle": {"min": [2.4, 0.0], "max": [2.6, 5.0]}}],
        }
    )
    with pytest.raises(PlanningError, match=r"task\.starts\[0\].*cannot be reached"):
        run_decoupled(parse_scenario(data, source="walled.yaml"))


def test_shortcut_and_smoothing_keep_clearance(room: WorldMap) -> None:
    opts = DecoupledOptions()
    plan = plan_decoupled(room, (1, 1), (4, 4), footprint_radius=FOOTPRINT, limits=LIMITS)
    assert plan.margin == opts.safety_margin
    assert _length(plan.shortcut) <= _length(plan.grid) + 1e-12
    assert len(plan.shortcut) < len(plan.grid)
    clear = room.clearance(plan.curve)
    assert np.min(clear) >= FOOTPRINT + opts.smooth_margin - 1e-9
    np.testing.assert_allclose(plan.curve[[0, -1]], [[1, 1], [4, 4]], rtol=0, atol=1e-9)
    # the timed path follows the curve from start to goal
    np.testing.assert_allclose(plan.timed.position[[0, -1]], [[1, 1], [4, 4]], rtol=0, atol=1e-9)
    # Its time (tens of ms once compiled) is measured by bench/bench_navigation.py.
    xy, spacing = smooth_path(room, plan.shortcut, FOOTPRINT + 0.2)
    assert 0 < spacing <= 0.5
    assert np.min(room.clearance(xy)) >= FOOTPRINT + 0.2 - 1e-9


def test_shortcut_of_a_straight_grid_path_is_its_ends(empty: WorldMap) -> None:
    path = grid_path(empty, (0.525, 0.525), (2.475, 2.475), 0.3)
    cut = shortcut_path(empty, path, 0.3)
    np.testing.assert_allclose(cut, [[0.525, 0.525], [2.475, 2.475]], rtol=0, atol=1e-12)


def test_time_parameterization_respects_the_limits(room: WorldMap) -> None:
    plan = plan_decoupled(room, (1, 1), (4, 4), footprint_radius=FOOTPRINT, limits=LIMITS)
    tp = plan.timed
    speed = np.linalg.norm(tp.velocity, axis=1)
    acc = np.linalg.norm(tp.acceleration, axis=1)
    jerk = np.linalg.norm(tp.jerk, axis=1)
    assert np.max(speed) <= LIMITS.max_speed * (1 + 1e-6)
    assert np.max(acc) <= LIMITS.max_acceleration * (1 + 2e-3)
    assert np.max(jerk) <= LIMITS.max_jerk * (1 + 2e-2)
    # rest at both ends, trims (zero acceleration, jerk, snap)
    assert speed[0] == 0.0 and speed[-1] == 0.0
    for a in (tp.acceleration, tp.jerk, tp.snap):
        assert np.all(a[[0, -1]] == 0.0)
    # velocity is the derivative of position (central differences), and continuous
    fd = np.gradient(tp.position, tp.dt, axis=0)
    np.testing.assert_allclose(fd[1:-1], tp.velocity[1:-1], rtol=0, atol=2e-4)
    assert np.max(np.abs(np.diff(tp.velocity, axis=0))) <= LIMITS.max_acceleration * tp.dt * 1.01
    np.testing.assert_allclose(tp.position[-1], [4, 4], rtol=0, atol=1e-9)


def test_straight_line_timing_is_the_smoothed_trapezoid() -> None:
    # 2 m straight: trapezoid time L/v + v/a, and the three box filters of width T
    # lengthen the support by 3 T (minus the sample each filter shares); the ends where
    # the speed is below 1e-9 v_max are cut (the speed rises as t⁴: ≈ 7 ms at each end).
    dt = 1.0 / 1024.0
    tp = time_parameterize([[0.0, 0.0], [2.0, 0.0]], LIMITS, dt=dt)
    v, a = LIMITS.max_speed, LIMITS.max_acceleration
    m = max(1, round(LIMITS.filter_time / dt)) | 1
    expected = 2.0 / v + v / a + 3 * (m - 1) * dt
    assert expected - 0.02 <= tp.duration <= expected
    np.testing.assert_allclose(tp.position[:, 1], 0.0, rtol=0, atol=1e-12)
    assert np.max(tp.speed) == pytest.approx(v, rel=1e-6)


def test_timing_from_a_moving_start_starts_at_that_speed() -> None:
    tp = time_parameterize([[0.0, 0.0], [3.0, 0.0]], LIMITS, start_speed=0.3)
    assert tp.speed[0] == pytest.approx(0.3, rel=1e-6)
    np.testing.assert_allclose(tp.velocity[0], [0.3, 0.0], rtol=0, atol=1e-6)
    assert np.all(tp.acceleration[0] == 0.0)
    assert tp.speed[-1] == 0.0


def test_motion_limits_come_from_the_palette(palette: Palette) -> None:
    lim = motion_limits(palette, DecoupledOptions(speed_scale=1.0, accel_scale=1.0))
    from gracenav.library import max_trim_speed
    from gracenav.primitives.shape_planner import flat_output_gain

    assert lim.max_speed == pytest.approx(max_trim_speed(palette), rel=1e-12)
    assert lim.max_acceleration == pytest.approx(
        flat_output_gain(palette.params) * palette.primitive_options.max_lean, rel=1e-12
    )
    assert 0.5 < lim.max_jerk < 5.0
    # the jerk scale moves the jerk limit alone; without it the jerk follows accel_scale
    scaled = motion_limits(palette, DecoupledOptions(accel_scale=0.5, jerk_scale=2.0))
    assert scaled.max_jerk == pytest.approx(2.0 * lim.max_jerk, rel=1e-12)
    assert scaled.max_acceleration == pytest.approx(0.5 * lim.max_acceleration, rel=1e-12)
    halved = motion_limits(palette, DecoupledOptions(accel_scale=0.5))
    assert halved.max_jerk == pytest.approx(0.5 * lim.max_jerk, rel=1e-12)


def test_options_are_checked() -> None:
    with pytest.raises(ConfigError, match="smooth_margin <= safety_margin"):
        DecoupledOptions(safety_margin=0.05, smooth_margin=0.1)
    with pytest.raises(ConfigError, match="speed_scale"):
        DecoupledOptions(speed_scale=1.5)
    for bad in (0.0, -1.0, 10.5, float("nan")):
        with pytest.raises(ConfigError, match="jerk_scale"):
            DecoupledOptions(jerk_scale=bad)


def test_no_push_run_reaches_the_goal_without_contact() -> None:
    result = run_decoupled(parse_scenario(_scenario(), source="room.yaml"))
    run = result.runs[0]
    ep = result.episodes[0]
    assert run.reached_goal and run.outcome == "goal_reached"
    assert ep.status is TaskStatus.GOAL_REACHED
    assert not run.contact and run.min_clearance_m >= 0.1
    assert run.final_error_m is not None and run.final_error_m < 0.005
    assert 9.0 < run.time_s < 16.0
    assert run.max_lean_deg < 4.5
    assert np.all(ep.policy == BASELINE_POLICY) and ep.events == ()
    assert run.balancing_s == 0.0
    assert result.library is None and result.library_size == 0
    assert math.isnan(result.coverage)


def test_push_beyond_the_threshold_replans_and_still_arrives() -> None:
    data = _scenario(disturbances=[{"kind": "push", "time": 3.0, "impulse": [0.0, -20.0]}])
    result = run_decoupled(parse_scenario(data, source="pushed.yaml"))
    run = result.runs[0]
    assert len(result.episodes[0].tree_seconds) >= 2  # at least one replan
    assert run.reached_goal and not run.contact


def test_huge_push_is_a_fall() -> None:
    data = _scenario(disturbances=[{"kind": "push", "time": 2.0, "impulse": [80.0, 0.0]}])
    result = run_decoupled(parse_scenario(data, source="shoved.yaml"))
    assert result.episodes[0].status is TaskStatus.FELL
    assert result.runs[0].stop_reason == "fell" and not result.runs[0].reached_goal
    assert result.runs[0].max_lean_deg > 20.0


def test_surveillance_is_refused() -> None:
    data = _scenario(
        task={"kind": "surveillance", "start": [1, 1, 0, 0], "goals": [[4, 4, 0, 0]], "loops": 1}
    )
    with pytest.raises(ConfigError, match="point-to-point only"):
        run_decoupled(parse_scenario(data, source="patrol.yaml"))


def test_start_at_the_goal_holds_it_without_planning() -> None:
    data = _scenario(
        task={"kind": "point_to_point", "goal": [4, 4, 0, 0], "starts": [[4, 4, 0, 0]]}
    )
    result = run_decoupled(parse_scenario(data, source="there.yaml"))
    assert result.runs[0].reached_goal
    assert result.runs[0].time_s <= 0.125 + 1e-9
    assert result.episodes[0].tree_seconds == ()


def test_drag_waits_then_replans_once() -> None:
    drag = {"kind": "drag", "start_time": 3.0, "end_time": 5.0, "velocity": [0.0, -0.3]}
    result = run_decoupled(parse_scenario(_scenario(disturbances=[drag]), source="drag.yaml"))
    assert result.runs[0].reached_goal
    assert len(result.episodes[0].tree_seconds) == 2  # the first plan and one after the drag


def test_a_harder_jerk_limit_trades_jerk_for_time() -> None:
    """``DecoupledOptions.jerk_scale`` reaches the campaign's runs: on a random pair,
    twice the jerk limit (box filters half as wide) reaches the goal sooner and jerks
    the ball harder (measured on trial 0: 8.57 against 9.60 s, 5.24 against 1.58 m/s³)."""
    from pairs import pairs_campaign

    from gracenav.campaign.runner import trial_result

    campaign = pairs_campaign(online_starts=True)
    rows = [
        trial_result(campaign, 0, "decoupled", decoupled_options=DecoupledOptions(jerk_scale=s))[0]
        for s in (0.9, 1.8)
    ]
    assert all(r["reached_goal"] for r in rows)
    slow, fast = rows
    assert fast["time_s"] < slow["time_s"] - 0.25
    assert fast["max_jerk_mps3"] > 2.0 * slow["max_jerk_mps3"]
