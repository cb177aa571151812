"""Controller design: LQR analytic truth and the Fig. 2 cascade factorisation."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav import BallbotParams, ConfigError
from gracenav.control import LQRWeights, design_gains, lqr, planar_to_position_coordinates
from gracenav.model import PlanarBallbot


def test_lqr_double_integrator_closed_form() -> None:
    """u = −K x on ẍ = u with Q = I, R = 1 has K = [1, √3]."""
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = np.array([[0.0], [1.0]])
    k, p = lqr(a, b, np.eye(2), np.eye(1))
    np.testing.assert_allclose(k, [[1.0, np.sqrt(3.0)]], rtol=1e-10)
    np.testing.assert_allclose(p, [[np.sqrt(3.0), 1.0], [1.0, np.sqrt(3.0)]], rtol=1e-10)


@pytest.mark.parametrize("plane", [0, 1])
def test_closed_loop_poles(plane: int) -> None:
    params = BallbotParams()
    gains = design_gains(params)
    a, b = PlanarBallbot(params, plane="xy"[plane]).linearize()  # type: ignore[arg-type]
    t = planar_to_position_coordinates(params.ball_radius)
    acl = t @ a @ np.linalg.inv(t) - (t @ b) @ gains.lqr[plane][None, :]
    poles = np.linalg.eigvals(acl)
    assert np.all(poles.real < -1.0)
    slow = poles[np.argsort(poles.real)][-2:]
    # The position poles sit near −1.6 rad/s (DESIGN.md 3).
    assert np.all(np.abs(slow.real + 1.6) < 0.2)


def test_cascade_equals_lqr() -> None:
    """The Fig. 2 cascade with the factored gains reproduces u = −K e exactly (no saturation)."""
    gains = design_gains()
    rng = np.random.default_rng(0)
    k = gains.lqr[0]
    for e in rng.normal(size=(20, 4)) * [0.01, 0.01, 0.01, 0.01]:
        lean_comp = gains.tracking_position[0] * (-e[0]) + gains.tracking_velocity[0] * (-e[2])
        u = -gains.lean[0] * (e[1] - lean_comp) - gains.lean_rate[0] * e[3]
        assert u == pytest.approx(-k @ e, rel=1e-12, abs=1e-12)


def test_tracking_controller_leans_toward_the_target() -> None:
    gains = design_gains()
    # Behind the target (p_ref > p): lean forward (positive compensation).
    assert np.all(gains.tracking_position > 0) and np.all(gains.tracking_velocity > 0)


def test_bad_weights() -> None:
    with pytest.raises(ConfigError, match="torque"):
        LQRWeights(torque=0.0)
    with pytest.raises(ConfigError, match="position"):
        LQRWeights(position=-1.0)
