"""The shipped smooth, calm and default palettes on a task with turns: the ball's jerk
(from the true state, as the run summaries measure it) stays near each palette's bound
(2, 1.15 and 3 m/s³), where the nonic palette (the default before) jerks it several
times harder, for a little more time."""

from __future__ import annotations

import functools
import math

import numpy as np

from gracenav.palette import load_palette
from gracenav.scenarios import parse_scenario, run_scenario

START, GOAL = (1.0, 1.0), (5.5, 4.0)


def _room() -> dict[str, object]:
    """A 7 m x 5 m room with a 1.2 m x 1.2 m block between the start and the goal, so
    that the way turns."""
    return {
        "name": "room with a block",
        "map": {
            "bounds": [[0.0, 0.0], [7.0, 5.0]],
            "resolution": 0.05,
            "obstacles": [{"rectangle": {"min": [2.6, 1.6], "max": [3.8, 2.8]}}],
        },
        "robot": {"footprint_radius": 0.2},
        "planner": {"cost": "time"},
        "task": {
            "kind": "point_to_point",
            "goal": [*GOAL, 0.0, 0.0],
            "starts": [[*START, 0.0, 0.0]],
        },
        "simulation": {"max_time": 60, "seed": 0},
    }


@functools.cache
def _run(name: str) -> tuple[float, float, float, float]:
    """Time (s), max and p95 jerk (m/s³) and largest lean (rad) of the room's task with
    the shipped palette ``name``, which must reach the goal."""
    result = run_scenario(parse_scenario(_room(), source="room"), palette=load_palette(name))
    run, ep = result.runs[0], result.episodes[0]
    assert run.reached_goal, (name, run.outcome)
    lean = float(np.max(np.hypot(ep.lean[:, 0], ep.lean[:, 1])))
    return run.time_s, run.max_jerk_mps3, run.p95_jerk_mps3, lean


def test_the_smooth_palette_keeps_the_balls_jerk_near_its_bound() -> None:
    """Measured: max / p95 jerk 2.13 / 1.98 m/s³ in 13.62 s with the smooth palette,
    6.91 / 5.70 m/s³ in 12.50 s with the nonic palette; largest lean 4.34° and 4.42°."""
    runs = {name: _run(name) for name in ("smooth", "nonic")}
    t_smooth, jerk_smooth, p95_smooth, lean_smooth = runs["smooth"]
    t_fast, jerk_fast, p95_fast, _ = runs["nonic"]
    assert jerk_smooth <= 2.0 * 1.25
    assert jerk_fast >= 2 * jerk_smooth and p95_fast >= 2 * p95_smooth
    assert t_smooth <= 1.3 * t_fast
    assert lean_smooth <= math.radians(4.5)


def test_the_default_palette_halves_the_nonics_jerk_for_about_the_same_time() -> None:
    """Measured: max / p95 jerk 3.04 / 2.97 m/s³ in 12.75 s with the default palette
    (limited references within 3 m/s³, as long in all as the nonics), 6.91 / 5.70 m/s³
    in 12.50 s with the nonic palette; largest lean 4.20° and 4.42°."""
    runs = {name: _run(name) for name in ("default", "nonic")}
    t_gentle, jerk_gentle, p95_gentle, lean_gentle = runs["default"]
    t_fast, jerk_fast, p95_fast, _ = runs["nonic"]
    assert jerk_gentle <= 3.0 * 1.1
    assert jerk_fast >= 2 * jerk_gentle and p95_fast >= 1.5 * p95_gentle
    assert t_gentle <= 1.05 * t_fast
    assert lean_gentle <= math.radians(4.5)


def test_the_calm_palette_jerks_the_ball_at_its_bound() -> None:
    """Measured: max / p95 jerk 1.16 / 1.13 m/s³ in 14.87 s with the calm palette
    (0.4 m/s, limited references within 1.15 m/s³, the friction fed forward at the
    mid-period rate), 2.13 / 1.98 m/s³ in 13.62 s with the smooth one; largest lean
    3.79° and 4.34°. Noise-free, the run keeps the references' bound to 1 % (asserted to
    3 %)."""
    t_calm, jerk_calm, p95_calm, lean_calm = _run("calm")
    t_smooth, jerk_smooth, _, lean_smooth = _run("smooth")
    assert jerk_calm <= 1.15 * 1.03 and p95_calm <= 1.15
    assert jerk_calm <= 0.6 * jerk_smooth
    assert t_calm <= 1.2 * t_smooth
    assert lean_calm <= lean_smooth <= math.radians(4.5)
