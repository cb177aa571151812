"""Physical limits: top speed, steady acceleration at a lean, and the time bound, each
against an independent computation (root finding, simulation of the planar model,
a numerically integrated minimum-time profile)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from gracenav.model import PlanarBallbot, physical_time_bound, steady_acceleration, top_speed
from gracenav.params import BallbotParams

P = BallbotParams()


def test_top_speed_is_where_the_model_friction_takes_the_torque_limit() -> None:
    """The planar model's friction (smooth Coulomb and viscous) equals τ_max at v_max."""
    model = PlanarBallbot(P)
    rate = brentq(lambda w: float(model.friction([w, 0.0])) - P.torque_limit, 1.0, 100.0)
    assert top_speed(P) == pytest.approx(P.ball_radius * rate, rel=1e-9)
    assert top_speed(P) == pytest.approx(1.615, abs=1e-3)  # the issue's 1.62 m/s


@pytest.mark.parametrize("plane", ["x", "y"])
@pytest.mark.parametrize("lean_deg", [2.0, 5.0, 8.0])
def test_steady_acceleration_by_simulating_the_planar_model(plane: str, lean_deg: float) -> None:
    """Simulate the planar model (RK4, 1 ms) with the torque that keeps φ̈ = 0 at every
    step, from rest at lean φ: φ stays, and the ball covers ½ a t² with the closed
    form's a (friction included: it only changes the torque)."""
    model = PlanarBallbot(P, plane=plane)  # type: ignore[arg-type]
    lean = math.radians(lean_deg)

    def torque(q: np.ndarray, qd: np.ndarray) -> float:
        # φ̈ is affine in τ: find the τ that zeroes it from two evaluations
        f0 = model.accelerations(q, qd, 0.0)[1]
        f1 = model.accelerations(q, qd, 1.0)[1]
        return float(-f0 / (f1 - f0))

    def rhs(s: np.ndarray) -> np.ndarray:
        q, qd = s[:2], s[2:]
        return np.concatenate([qd, model.accelerations(q, qd, torque(q, qd))])

    s = np.array([-lean, lean, 0.0, 0.0])  # ball at x = 0, body leaning by φ
    dt, duration = 1e-3, 2.0
    for _ in range(round(duration / dt)):
        k1 = rhs(s)
        k2 = rhs(s + 0.5 * dt * k1)
        k3 = rhs(s + 0.5 * dt * k2)
        k4 = rhs(s + dt * k3)
        s = s + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    a = steady_acceleration(P, lean)
    assert s[1] == pytest.approx(lean, abs=1e-9)
    assert float(model.ball_position(s[:2])) == pytest.approx(0.5 * a * duration**2, rel=1e-6)
    assert P.ball_radius * (s[2] + s[3]) == pytest.approx(a * duration, rel=1e-6)


def _integrated_min_time(length: float, v_max: float, a_max: float, dt: float) -> float:
    """Minimum time over ``length``, rest to rest, by stepping a speed profile: full
    acceleration while the braking distance allows, speed at most v_max, full braking."""
    x = v = t = 0.0
    while x < length:
        brake = v * v / (2.0 * a_max)
        if x + brake >= length and v > 0.0:
            # braking phase: the rest is v / a_max, exactly
            return t + v / a_max
        v_next = min(v + a_max * dt, v_max)
        x += 0.5 * (v + v_next) * dt
        v = v_next
        t += dt
    return t


@pytest.mark.parametrize("length", [0.5, 3.0, 23.8, 100.0])
def test_time_bound_against_an_integrated_profile(length: float) -> None:
    lean = math.radians(5.0)
    tb = physical_time_bound(P, length, lean_limit=lean)
    numeric = _integrated_min_time(length, tb.v_max, tb.a_max, 1e-5)
    assert tb.bound == pytest.approx(numeric, rel=1e-3)
    assert tb.reaches_top_speed == (length >= tb.v_max**2 / tb.a_max)


def test_the_issue_figures() -> None:
    """v_max ≈ 1.62 m/s, a_max ≈ 0.74 m/s² at 5°, T* ≈ 16.9 s over 23.8 m."""
    tb = physical_time_bound(P, 23.8, lean_limit=math.radians(5.0))
    assert tb.v_max == pytest.approx(1.62, abs=0.01)
    assert tb.a_max == pytest.approx(0.74, abs=0.01)
    assert tb.bound == pytest.approx(16.9, abs=0.05)


def test_limits_refuse_what_has_no_bound() -> None:
    with pytest.raises(ValueError, match="no top speed"):
        top_speed(P.without_friction())
    with pytest.raises(ValueError, match="does not exceed the Coulomb"):
        top_speed(BallbotParams(torque_limit=3.0))
    with pytest.raises(ValueError, match="lean must be in"):
        steady_acceleration(P, 0.0)
    with pytest.raises(ValueError, match="length must be positive"):
        physical_time_bound(P, -1.0, lean_limit=0.1)
