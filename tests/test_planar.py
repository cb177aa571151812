"""Planar model: an independent implementation of IJRR 2014 eqs. 1-5, closed forms, energy."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav import BallbotParams
from gracenav.model import PlanarBallbot


def reference_accelerations(p: BallbotParams, ib: float, q, qd, tau):
    """Scalar re-implementation straight from the paper's equations (sgn smoothed by tanh)."""
    _th, ph = q
    thd, phd = qd
    r, g = p.ball_radius, p.gravity
    a = p.ball_inertia + (p.ball_mass + p.body_mass) * r**2
    b = p.body_mass * r * p.body_com_height
    c = ib + p.body_mass * p.body_com_height**2
    m = np.array([[a, a + b * np.cos(ph)], [a + b * np.cos(ph), a + c + 2 * b * np.cos(ph)]])
    cc = np.array([-b * np.sin(ph) * phd**2, -b * np.sin(ph) * phd**2])
    gg = np.array([0.0, -b * g * np.sin(ph) / r])
    dd = np.array(
        [p.coulomb_friction * np.tanh(thd / p.friction_smoothing) + p.viscous_friction * thd, 0.0]
    )
    return np.linalg.solve(m, np.array([tau, 0.0]) - cc - gg - dd)


@pytest.mark.parametrize("plane", ["x", "y"])
def test_matches_independent_implementation(plane: str) -> None:
    rng = np.random.default_rng(1)
    p = BallbotParams()
    model = PlanarBallbot(p, plane=plane)  # type: ignore[arg-type]
    ib = p.body_inertia_y if plane == "x" else p.body_inertia_x
    q = rng.uniform(-0.5, 0.5, (50, 2))
    qd = rng.uniform(-2, 2, (50, 2))
    tau = rng.uniform(-40, 40, 50)
    got = model.accelerations(q, qd, tau)
    want = np.array(
        [reference_accelerations(p, ib, *args) for args in zip(q, qd, tau, strict=True)]
    )
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_open_loop_eigenvalues_and_input_matrix() -> None:
    a, b = PlanarBallbot(BallbotParams(), plane="y").linearize()
    eig = np.sort(np.linalg.eigvals(a).real)
    np.testing.assert_allclose(eig, [-4.935, 0.0, 0.0, 4.935], atol=5e-4)
    np.testing.assert_allclose(b.ravel(), [0, 0, 5.071, -0.4914], atol=5e-4)


@pytest.mark.parametrize("plane", ["x", "y"])
def test_unstable_pole_closed_form(plane: str) -> None:
    """λ² = β g/r · α / det M(0) for the linearised model (derived by hand from eqs. 1-5)."""
    model = PlanarBallbot(BallbotParams(), plane=plane)  # type: ignore[arg-type]
    a_, b_, c_ = model.alpha, model.beta, model.gamma
    det = a_ * (a_ + c_ + 2 * b_) - (a_ + b_) ** 2
    lam = np.sqrt(b_ * model.params.gravity / model.params.ball_radius * a_ / det)
    a, _ = model.linearize()
    assert np.max(np.linalg.eigvals(a).real) == pytest.approx(lam, rel=1e-12)


def test_linearisation_matches_finite_differences() -> None:
    model = PlanarBallbot(BallbotParams().without_friction())
    a, b = model.linearize()
    eps = 1e-6
    x0 = np.zeros(4)

    def f(x, u):
        return np.r_[x[2:], model.accelerations(x[:2], x[2:], u)]

    fd_a = np.column_stack(
        [(f(x0 + eps * e, 0.0) - f(x0 - eps * e, 0.0)) / (2 * eps) for e in np.eye(4)]
    )
    fd_b = (f(x0, eps) - f(x0, -eps)) / (2 * eps)
    np.testing.assert_allclose(a, fd_a, atol=1e-7)
    np.testing.assert_allclose(b.ravel(), fd_b, atol=1e-7)
    a_v, _ = PlanarBallbot(BallbotParams()).linearize(viscous=True)
    assert a_v[2, 2] < 0.0  # viscous friction damps the ball rate


def test_steady_lean_for_constant_acceleration() -> None:
    """φ_ss(a) = atan(a/g) + asin(α a / (β √(g² + a²))) (DESIGN.md 2.2; ≈3.40° at 0.5 m/s²)."""
    p = BallbotParams().without_friction()
    model = PlanarBallbot(p, plane="y")
    acc, g = 0.5, p.gravity
    phi = np.arctan(acc / g) + np.arcsin(model.alpha * acc / (model.beta * np.hypot(g, acc)))
    assert np.rad2deg(phi) == pytest.approx(3.40, abs=0.01)
    # With φ constant and φ̈ = 0 the constraint row gives θ̈; the ball acceleration is r θ̈.
    thdd = model.beta * g * np.sin(phi) / p.ball_radius / (model.alpha + model.beta * np.cos(phi))
    assert p.ball_radius * thdd == pytest.approx(acc, rel=1e-12)
    # And the full model agrees with the torque that produces it.
    tau = model.alpha * thdd
    qdd = model.accelerations(np.array([0.0, phi]), np.zeros(2), tau)
    np.testing.assert_allclose(qdd, [thdd, 0.0], atol=1e-12)


def test_energy_conserved_without_friction_and_input() -> None:
    model = PlanarBallbot(BallbotParams().without_friction())
    x = np.array([0.0, 0.05, 0.3, -0.2])
    h = 1.0 / 4096

    def f(x):
        return np.r_[x[2:], model.accelerations(x[:2], x[2:], 0.0)]

    e0 = model.energy(x[:2], x[2:])
    # 2 s: the body falls to about 0.9 rad without hitting the floor model.
    for _ in range(2 * 4096):
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert abs(x[1]) > 0.5  # it really fell: a meaningful test of conservation
    assert abs(model.energy(x[:2], x[2:]) - e0) / abs(e0) < 1e-8


def test_flat_output_length() -> None:
    assert PlanarBallbot(BallbotParams(), plane="y").flat_output_length() == pytest.approx(
        0.986, abs=5e-4
    )
