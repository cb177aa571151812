"""Falls: the documented recovery bounds of the balancing controller, and simulations that
stop where the lean passes the fall limit."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from gracenav._util.progress import Progress
from gracenav.control import design_gains
from gracenav.params import BallbotParams
from gracenav.sim import (
    DEFAULT_FALL_LEAN,
    Push,
    Reference,
    SimulationOptions,
    StopReason,
    simulate,
    simulate_batch,
    state_from_position,
)

P = BallbotParams()
NO_LIMIT = SimulationOptions(fall_lean=math.inf)


def recovers(lean_deg: float = 0.0, push: tuple[float, float] | None = None) -> bool:
    """Station keeping for 20 s without a fall limit: back upright and at rest?"""
    x0 = state_from_position(np.zeros(4), P.ball_radius, lean=np.deg2rad([lean_deg] * 2))
    res = simulate(
        x0,
        Reference.hold((0.0, 0.0), 20.0),
        disturbances=[Push(1.0, push)] if push else [],
        options=NO_LIMIT,
    )
    lean = np.abs(res.lean)
    speed = np.hypot(*res.position_state[-1, 2:])
    return bool(np.all(np.isfinite(lean)) and lean[-1].max() < np.deg2rad(0.1) and speed < 0.01)


def test_documented_lean_bound() -> None:
    # docs/design/conventions.md: recovery from initial leans up to 20.4° in both planes.
    assert recovers(lean_deg=20.3)
    assert not recovers(lean_deg=20.5)
    assert DEFAULT_FALL_LEAN == pytest.approx(np.deg2rad(20.0), rel=0, abs=1e-15)


@pytest.mark.parametrize(
    ("angle_deg", "bound"), [(0.0, 80.5), (90.0, 80.5), (45.0, 113.8)], ids=["x", "y", "diag"]
)
def test_documented_push_bounds(angle_deg: float, bound: float) -> None:
    a = np.deg2rad(angle_deg)
    assert recovers(push=(0.99 * bound * np.cos(a), 0.99 * bound * np.sin(a)))
    assert not recovers(push=(1.01 * bound * np.cos(a), 1.01 * bound * np.sin(a)))


def test_a_fall_stops_the_simulation_at_the_limit() -> None:
    x0 = state_from_position(np.zeros(4), P.ball_radius, lean=np.deg2rad([22.0, 22.0]))
    ref = Reference.hold((0.0, 0.0), 5.0)
    res = simulate(x0, ref)
    assert res.stop_reason is StopReason.FELL and res.time.size == 1  # at once
    res = simulate(
        state_from_position(np.zeros(4), P.ball_radius), ref, disturbances=[Push(1.0, (150.0, 0.0))]
    )
    assert res.stop_reason is StopReason.FELL
    lean = np.abs(res.lean).max(axis=1)
    assert lean[-1] > DEFAULT_FALL_LEAN and np.all(lean[:-1] <= DEFAULT_FALL_LEAN)
    batch = simulate_batch(np.stack([x0, state_from_position(np.zeros(4), P.ball_radius)]), ref)
    np.testing.assert_array_equal(batch.fall_tick, [0, -1])
    np.testing.assert_array_equal(batch.last_tick, [0, ref.num_ticks])


def test_a_non_finite_state_is_a_fall() -> None:
    x0 = state_from_position(np.zeros(4), P.ball_radius)
    res = simulate(
        x0,
        Reference.hold((0.0, 0.0), 2.0),
        design_gains(),
        params=BallbotParams(ball_radius=1e9),
        options=SimulationOptions(),
    )
    assert res.stop_reason is StopReason.FELL and res.time[-1] < 0.01


def test_progress_is_erased_and_silent_off_a_terminal() -> None:
    stream = io.StringIO()  # not a terminal
    with Progress(3, "work", stream=stream) as bar:
        bar.update(5)  # clipped to the total
    assert stream.getvalue() == "" and bar.count == 3
    stream = io.StringIO()
    with Progress(2, "work", stream=stream, force=True) as bar:
        bar.update()
        bar.write("a message")
        bar.update()
    text = stream.getvalue()
    assert "work" in text and "a message\n" in text
    assert text.endswith("\r")  # the bar's line is blanked when it closes
