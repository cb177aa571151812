"""Optimal shape trajectory planner (paper Sec. III-A, refs [15], [16]).

Given a desired position trajectory, find a *feasible* state trajectory of the
ballbot, position and shape, that satisfies the dynamic constraint (the two
shape rows of the equations of motion, which contain no input) and best tracks
the desired motion. Torques then follow from the two position rows.

Formulation (DESIGN.md §4):

* The desired trajectory is the **flat output** y = x + L φ per axis, with
  L = r_w (γ + β)/(α + β) of that axis' plane (x uses ``body_inertia_y``, y
  uses ``body_inertia_x``). For the model linearised about upright ÿ = κ φ
  with κ = β g/(α + β), so the lean is φ = ÿ/κ and the ball x = y − L φ.
* The lean φ(t) of each axis is a quintic B-spline on [0, t_f] whose first and
  last three coefficients are zero, so φ, φ̇, φ̈ = 0 at both ends: the ends are
  exact trims (upright, ball position = y).
* The ball angles θ(t) follow by integrating the dynamic constraint
  (θ̈ solved from the shape rows given φ, φ̇, φ̈, θ̇) from the start trim, with
  fixed-step RK4 (step 1/1024 s by default).
* The spline coefficients minimise

      (1/t_f) ∫ |y_achieved − y_desired|² dt + λ (1/t_f) ∫ |φ̈|² dt

  subject to the end state equalities x(t_f) = y_d(t_f), ẋ(t_f) = ẏ_d(t_f)
  (imposed exactly through the KKT system of each step). The problem is solved
  by Gauss–Newton on the nonlinear constraint. Its Jacobian is that of the
  linearised model (double integrals of the basis functions, exact for the
  linearised model; the nonlinear 3D terms at a few degrees of lean change it
  by about a percent), so each iteration costs one integration of the
  nonlinear model, and the iteration contracts fast.
  Starting from φ = 0, the first step *is* the flat-output solution of the
  linearised model (the required initial guess); later steps correct for the
  nonlinear model until the end state is met to ``end_tolerance``.

The tracking error reported is that of the achieved flat output
y = r_w (θ + φ) + L φ against the desired one, over the integration nodes.

Models: ``"3d"`` (the full 3D model, :class:`gracenav.model.Ballbot3D`),
``"planar"`` (two decoupled nonlinear planar models, one per axis) and
``"linear"`` (their linearisation about upright; friction is kept in the
torque). States are always the 3D model's x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y,
φ̇_x, φ̇_y]."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import BSpline

from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants
from gracenav.model.planar import PlanarBallbot
from gracenav.params import BallbotParams
from gracenav.primitives.dynamics import (
    _KIND,
    ModelName,
    _integrate,
    _inverse_dynamics,
    _model_constants,
)
from gracenav.primitives.references import (
    _DEGREE,
    BrakeReference,
    NonicReference,
    PositionReference,
    ShortestBrakeReference,
    _lean_knots,
    flat_output_gain,
    flat_output_lengths,
)
from gracenav.primitives.trajectory import (
    ShapePlannerOptions,
    ShapePlannerResult,
    ShapePlannerStatus,
    ShapeTrajectory,
    TrajectorySample,
)

__all__ = [
    "BrakeReference",
    "NonicReference",
    "PositionReference",
    "ShapePlannerOptions",
    "ShapePlannerResult",
    "ShapePlannerStatus",
    "ShapeTrajectory",
    "ShortestBrakeReference",
    "TrajectorySample",
    "flat_output_gain",
    "flat_output_lengths",
    "plan_shape_trajectory",
]

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------------------
# The planner
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Basis:
    knots: FloatArray
    n_free: int
    half: FloatArray  # (3, 2N+1, n_free): φ, φ̇, φ̈ at the half-step grid
    dint: FloatArray  # (N+1, n_free): double integral from 0 at the nodes
    sint_end: FloatArray  # (n_free,): single integral over [0, t_f]
    gram: FloatArray  # (n_free, n_free): ∫ B̈ B̈ᵀ dt / t_f
    weights: FloatArray  # (N+1,): trapezoid weights / t_f


@functools.lru_cache(maxsize=4)  # a few MB each; the 0° and 90° plans share one
def _basis(n_steps: int, step: float, knot_spacing: float) -> _Basis:
    duration = n_steps * step
    knots = _lean_knots(duration, knot_spacing)
    nb = knots.size - _DEGREE - 1
    free = np.eye(nb)[:, 3 : nb - 3]
    spl = BSpline(knots, free, _DEGREE)
    th = np.arange(2 * n_steps + 1) * (0.5 * step)
    half = np.stack([spl(th), spl.derivative(1)(th), spl.derivative(2)(th)])
    nodes = np.arange(n_steps + 1) * step
    dint = spl.antiderivative(2)(nodes)
    sint_end = spl.antiderivative(1)(np.array([duration]))[0]
    wh = np.full(2 * n_steps + 1, 0.5 * step)
    wh[0] = wh[-1] = 0.25 * step
    b2 = half[2]
    gram = (b2 * wh[:, None]).T @ b2 / duration
    w = np.full(n_steps + 1, step / duration)
    w[0] = w[-1] = 0.5 * step / duration
    for a in (half, dint, sint_end, gram, w):
        a.setflags(write=False)
    return _Basis(knots, nb - 6, half, dint, sint_end, gram, w)


def _check_reference(reference: PositionReference, step: float) -> int:
    n = round(reference.duration / step)
    if n < 1 or abs(n * step - reference.duration) > 1e-9 * max(1.0, reference.duration):
        raise ConfigError(
            f"reference duration {reference.duration} s must be a positive whole number of "
            f"integration steps of {step} s"
        )
    ends = np.array([0.0, reference.duration])
    for order in (2, 3, 4):
        if np.max(np.abs(reference.value(ends, order))) > 1e-9:
            raise ConfigError(
                "the reference must start and end at trims: acceleration, jerk and snap "
                "must be zero at both ends"
            )
    return int(n)


def _dynamics_residual(
    params: BallbotParams,
    model: ModelName,
    q: FloatArray,
    qd: FloatArray,
    qdd: FloatArray,
    tau: FloatArray,
) -> float:
    """Max |M q̈ + bias + friction − [τ, 0]| (N m) with the numpy models."""
    if model == "3d":
        from gracenav.model.ballbot3d import Ballbot3D

        m3 = Ballbot3D(params)
        lhs = np.einsum("nij,nj->ni", m3.mass_matrix(q), qdd) + m3.bias(q, qd)
        lhs[:, :2] += m3.friction(qd) - tau
        return float(np.max(np.abs(lhs)))
    worst = 0.0
    for i, plane in enumerate(("x", "y")):
        pm = PlanarBallbot(params, plane)  # type: ignore[arg-type]
        qp = q[:, [i, 2 + i]]
        qdp = qd[:, [i, 2 + i]]
        qddp = qdd[:, [i, 2 + i]]
        if model == "planar":
            lhs = np.einsum("nij,nj->ni", pm.mass_matrix(qp), qddp) + pm.bias(qp, qdp)
        else:
            m0 = pm.mass_matrix(np.zeros(2))
            lhs = qddp @ m0.T
            lhs[:, 1] -= pm.beta * params.gravity / params.ball_radius * qp[:, 1]
        lhs[:, 0] += pm.friction(qdp) - tau[:, i]
        worst = max(worst, float(np.max(np.abs(lhs))))
    return worst


def plan_shape_trajectory(
    reference: PositionReference,
    params: BallbotParams | None = None,
    *,
    model: ModelName = "3d",
    options: ShapePlannerOptions | None = None,
) -> ShapePlannerResult:
    """Plan a feasible state trajectory whose flat output best tracks ``reference``.

    Parameters
    ----------
    reference : PositionReference
        Desired flat output y(t) of both axes (m) on [0, t_f], starting and
        ending at trims (zero acceleration, jerk and snap at both ends), e.g. a
        :class:`NonicReference`. t_f must be a whole number of integration steps.
    params : BallbotParams, optional
        Physical parameters (default: the CMU ballbot).
    model : {"3d", "planar", "linear"}
        Dynamic model whose constraint the trajectory satisfies (see module docs).
    options : ShapePlannerOptions, optional

    Returns
    -------
    ShapePlannerResult
        With the trajectory in the reference's frame: θ(0) = y(0)/r_w,
        θ̇(0) = ẏ(0)/r_w, upright at both ends, and ball position and velocity at
        t_f equal to y(t_f), ẏ(t_f) to ``options.end_tolerance`` when converged.
    """
    params = params if params is not None else BallbotParams()
    options = options if options is not None else ShapePlannerOptions()
    if model not in _KIND:
        raise ConfigError(f"model must be one of {sorted(_KIND)}, got {model!r}")
    kind = _KIND[model]
    h = options.step
    n = _check_reference(reference, h)
    basis = _basis(n, h, options.knot_spacing)
    r = params.ball_radius
    kappa = flat_output_gain(params)
    lengths = flat_output_lengths(params)
    c = _model_constants(params, kind)
    nodes = np.arange(n + 1) * h
    y_des = reference.value(nodes)
    y0 = y_des[0]
    v0 = reference.value(np.array([0.0]), 1)[0]
    y1 = y_des[-1]
    v1 = reference.value(np.array([reference.duration]), 1)[0]
    s0 = np.concatenate([y0 / r, v0 / r])

    # KKT matrix of the linearised problem (the same for both axes).
    nf = basis.n_free
    jac = kappa * basis.dint  # d y(t_k) / d coef
    jw = jac * basis.weights[:, None]
    hess = jw.T @ jac + options.regularization * basis.gram
    ends = kappa * np.stack([basis.dint[-1], basis.sint_end])  # d [x, ẋ](t_f) / d coef
    kkt = np.zeros((nf + 2, nf + 2))
    kkt[:nf, :nf] = hess
    kkt[:nf, nf:] = ends.T
    kkt[nf:, :nf] = ends
    kkt_inv = np.linalg.inv(kkt)

    coef = np.zeros((nf, 2))
    th = np.empty((n + 1, 2))
    thd = np.empty((n + 1, 2))
    thdd = np.empty((n + 1, 2))
    status = ShapePlannerStatus.MAX_ITERATIONS
    iterations = 0
    phi_h = np.zeros((3, 2 * n + 1, 2))

    def integrate(cf: FloatArray) -> None:
        for d in range(3):
            phi_h[d] = basis.half[d] @ cf
        _integrate(kind, c, phi_h[0], phi_h[1], phi_h[2], s0, h, th, thd, thdd)

    integrate(coef)
    for it in range(options.max_iterations):
        iterations = it + 1
        phi_n = phi_h[0, ::2]
        err = r * (th + phi_n) + lengths * phi_n - y_des
        end_err = np.stack([r * th[-1] - y1, r * thd[-1] - v1])
        grad = jw.T @ err + options.regularization * (basis.gram @ coef)
        rhs = np.concatenate([-grad, -end_err])
        delta = (kkt_inv @ rhs)[:nf]
        coef = coef + delta
        integrate(coef)
        if not (np.all(np.isfinite(th)) and np.all(np.isfinite(thd))):
            status = ShapePlannerStatus.DIVERGED
            break
        end_now = max(
            float(np.max(np.abs(r * th[-1] - y1))), float(np.max(np.abs(r * thd[-1] - v1)))
        )
        if end_now <= options.end_tolerance and float(np.max(np.abs(delta))) <= (
            options.step_tolerance
        ):
            status = ShapePlannerStatus.CONVERGED
            break

    full = np.zeros((nf + 6, 2))
    full[3:-3] = coef
    trajectory = ShapeTrajectory(
        params, model, n * h, h, basis.knots, full, th.copy(), thd.copy(), thdd.copy()
    )
    return _summarise(trajectory, status, iterations, y_des, y1, v1, phi_h, kind, c, s0)


def _summarise(
    trajectory: ShapeTrajectory,
    status: ShapePlannerStatus,
    iterations: int,
    y_des: FloatArray,
    y1: FloatArray,
    v1: FloatArray,
    phi_h: FloatArray,
    kind: int,
    c: FloatArray,
    s0: FloatArray,
) -> ShapePlannerResult:
    params = trajectory.params
    r = params.ball_radius
    lengths = flat_output_lengths(params)
    th, thd = trajectory.theta, trajectory.theta_dot
    ph = phi_h[0, ::2]
    phd = phi_h[1, ::2]
    phdd = np.ascontiguousarray(phi_h[2, ::2])
    ball = r * (th + ph)
    e_flat = np.linalg.norm(ball + lengths * ph - y_des, axis=1)
    e_ball = np.linalg.norm(ball - y_des, axis=1)
    n = th.shape[0] - 1
    w = np.full(n + 1, 1.0 / n)
    w[0] = w[-1] = 0.5 / n
    q = np.ascontiguousarray(np.concatenate([th, ph], axis=1))
    qd = np.ascontiguousarray(np.concatenate([thd, phd], axis=1))
    qdd = np.empty_like(q)
    tau = np.empty((n + 1, 2))
    _inverse_dynamics(kind, c, friction_constants(params), q, qd, phdd, qdd, tau)
    tilt = np.arccos(np.clip(np.cos(ph[:, 0]) * np.cos(ph[:, 1]), -1.0, 1.0))
    # Richardson estimate of the integration error: integrate with step 2h.
    integration_error = float("nan")
    if n % 2 == 0 and n >= 2:
        n2 = n // 2
        th2 = np.empty((n2 + 1, 2))
        thd2 = np.empty((n2 + 1, 2))
        thdd2 = np.empty((n2 + 1, 2))
        _integrate(
            kind,
            c,
            np.ascontiguousarray(phi_h[0, ::2]),
            np.ascontiguousarray(phi_h[1, ::2]),
            phdd,
            s0,
            2 * trajectory.step,
            th2,
            thd2,
            thdd2,
        )
        integration_error = float(np.max(np.abs(th2[-1] - th[-1]))) / 15.0
    end_error = max(float(np.max(np.abs(r * th[-1] - y1))), float(np.max(np.abs(r * thd[-1] - v1))))
    return ShapePlannerResult(
        status=status,
        iterations=iterations,
        trajectory=trajectory,
        tracking_rms=float(np.sqrt(np.sum(w * e_flat**2))),
        tracking_max=float(np.max(e_flat)),
        ball_rms=float(np.sqrt(np.sum(w * e_ball**2))),
        ball_max=float(np.max(e_ball)),
        end_error=end_error,
        peak_lean=float(np.max(tilt)),
        peak_torque=float(np.max(np.abs(tau))),
        dynamics_residual=_dynamics_residual(params, trajectory.model, q, qd, qdd, tau),
        integration_error=integration_error,
    )
