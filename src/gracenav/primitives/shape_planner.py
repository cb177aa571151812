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

import enum
import functools
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from scipy.interpolate import BSpline

from gracenav._kernels import bias as _bias3
from gracenav._kernels import friction as _friction
from gracenav._kernels import mass_matrix as _mm3
from gracenav._util.hermite import quintic_hermite
from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants
from gracenav.model.planar import PlanarBallbot
from gracenav.params import BallbotParams
from gracenav.primitives.references import (
    _DEGREE,
    BrakeReference,
    FloatArray,
    NonicReference,
    PositionReference,
    ShortestBrakeReference,
    _lean_knots,
    flat_output_gain,
    flat_output_lengths,
)

__all__ = [
    "BrakeReference",
    "ModelName",
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

ModelName = Literal["3d", "planar", "linear"]

_KIND = {"3d": 0, "planar": 1, "linear": 2}


def _model_constants(params: BallbotParams, kind: int) -> FloatArray:
    if kind == 0:
        from gracenav.model.ballbot3d import Ballbot3D

        return np.ascontiguousarray(Ballbot3D(params).constants(), dtype=float)
    return np.array(
        [
            params.ball_radius,
            params.alpha(),
            params.beta(),
            PlanarBallbot(params, "x").gamma,
            PlanarBallbot(params, "y").gamma,
            params.gravity,
        ]
    )


# --------------------------------------------------------------------------------------
# Compiled kernels
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _shape_accel(kind, c, q, qd, phdd, wm, wb, out):
    """θ̈ (2,) from the shape rows given q (4,), q̇ (4,) and φ̈ (2,)."""
    if kind == 0:
        _mm3(c, q, wm)
        _bias3(c, q, qd, wb)
        r0 = -(wm[2, 2] * phdd[0] + wm[2, 3] * phdd[1] + wb[2])
        r1 = -(wm[3, 2] * phdd[0] + wm[3, 3] * phdd[1] + wb[3])
        a = wm[2, 0]
        b = wm[2, 1]
        cc = wm[3, 0]
        d = wm[3, 1]
        det = a * d - b * cc
        out[0] = (d * r0 - b * r1) / det
        out[1] = (a * r1 - cc * r0) / det
    else:
        r = c[0]
        alpha = c[1]
        beta = c[2]
        g = c[5]
        for i in range(2):
            ph = q[2 + i]
            phd = qd[2 + i]
            gam = c[3 + i]
            if kind == 1:
                cb = beta * np.cos(ph)
                sb = beta * np.sin(ph)
                out[i] = (sb * g / r + sb * phd * phd - (alpha + gam + 2.0 * cb) * phdd[i]) / (
                    alpha + cb
                )
            else:
                out[i] = (beta * ph * g / r - (alpha + gam + 2.0 * beta) * phdd[i]) / (alpha + beta)


@njit(cache=True)
def _integrate(kind, c, ph, phd, phdd, s0, h, th, thd, thdd):
    """RK4 of (θ, θ̇) under the dynamic constraint.

    ``ph``, ``phd``, ``phdd`` (2N+1, 2) are φ, φ̇, φ̈ at the half-step grid;
    ``s0`` (4,) = [θ_x, θ_y, θ̇_x, θ̇_y] at t = 0; outputs (N+1, 2) at the nodes.
    """
    n = th.shape[0] - 1
    wm = np.empty((4, 4))
    wb = np.empty(4)
    q = np.empty(4)
    qd = np.empty(4)
    a = np.empty(2)
    s = s0.copy()
    st = np.empty(4)
    k1 = np.empty(4)
    k2 = np.empty(4)
    k3 = np.empty(4)
    for k in range(n + 1):
        j = 2 * k
        q[0] = s[0]
        q[1] = s[1]
        q[2] = ph[j, 0]
        q[3] = ph[j, 1]
        qd[0] = s[2]
        qd[1] = s[3]
        qd[2] = phd[j, 0]
        qd[3] = phd[j, 1]
        _shape_accel(kind, c, q, qd, phdd[j], wm, wb, a)
        th[k, 0] = s[0]
        th[k, 1] = s[1]
        thd[k, 0] = s[2]
        thd[k, 1] = s[3]
        thdd[k, 0] = a[0]
        thdd[k, 1] = a[1]
        if k == n:
            break
        k1[0] = s[2]
        k1[1] = s[3]
        k1[2] = a[0]
        k1[3] = a[1]
        # stage 2 and 3 at the half step, stage 4 at the next node
        for stage in range(3):
            jj = j + 1 if stage < 2 else j + 2
            hh = 0.5 * h if stage < 2 else h
            kin = k1 if stage == 0 else (k2 if stage == 1 else k3)
            for i in range(4):
                st[i] = s[i] + hh * kin[i]
            q[0] = st[0]
            q[1] = st[1]
            q[2] = ph[jj, 0]
            q[3] = ph[jj, 1]
            qd[0] = st[2]
            qd[1] = st[3]
            qd[2] = phd[jj, 0]
            qd[3] = phd[jj, 1]
            _shape_accel(kind, c, q, qd, phdd[jj], wm, wb, a)
            if stage == 0:
                k2[0] = st[2]
                k2[1] = st[3]
                k2[2] = a[0]
                k2[3] = a[1]
            elif stage == 1:
                k3[0] = st[2]
                k3[1] = st[3]
                k3[2] = a[0]
                k3[3] = a[1]
            else:
                for i in range(2):
                    s[i] += h * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + st[2 + i]) / 6.0
                for i in range(2):
                    s[2 + i] += h * (k1[2 + i] + 2.0 * k2[2 + i] + 2.0 * k3[2 + i] + a[i]) / 6.0


@njit(cache=True)
def _inverse_dynamics(kind, c, fr, q, qd, phdd, qdd, tau):
    """θ̈ from the shape rows and τ from the position rows (friction included).

    ``q``, ``qd`` (M, 4), ``phdd`` (M, 2); outputs ``qdd`` (M, 4), ``tau`` (M, 2).
    """
    wm = np.empty((4, 4))
    wb = np.empty(4)
    a = np.empty(2)
    for m in range(q.shape[0]):
        _shape_accel(kind, c, q[m], qd[m], phdd[m], wm, wb, a)
        qdd[m, 0] = a[0]
        qdd[m, 1] = a[1]
        qdd[m, 2] = phdd[m, 0]
        qdd[m, 3] = phdd[m, 1]
        if kind == 0:
            # wm, wb hold M and the bias at q[m], qd[m]
            for i in range(2):
                s = wb[i]
                for j in range(4):
                    s += wm[i, j] * qdd[m, j]
                tau[m, i] = s + _friction(fr, qd[m, i])
        else:
            alpha = c[1]
            beta = c[2]
            for i in range(2):
                ph = q[m, 2 + i]
                phd = qd[m, 2 + i]
                if kind == 1:
                    t = alpha * a[i] + (alpha + beta * np.cos(ph)) * phdd[m, i]
                    t -= beta * np.sin(ph) * phd * phd
                else:
                    t = alpha * a[i] + (alpha + beta) * phdd[m, i]
                tau[m, i] = t + _friction(fr, qd[m, i])


# --------------------------------------------------------------------------------------
# Options, results, trajectories
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShapePlannerOptions:
    """Options of :func:`plan_shape_trajectory`.

    Parameters
    ----------
    knot_spacing : float
        Target spacing (s) of the interior knots of the lean B-spline (uniform
        knots; the count is round(t_f / knot_spacing) − 1, at least 1).
    regularization : float
        λ (m² s⁴ / rad²) of the lean-acceleration penalty λ (1/t_f) ∫ |φ̈|² dt.
    max_iterations : int
        Gauss–Newton iterations at most.
    end_tolerance : float
        Required end state accuracy (m for position, m/s for velocity).
    step_tolerance : float
        Convergence when the largest change of a spline coefficient is below
        this (rad) and the end state is met.
    step : float
        Integration step h (s) of the dynamic constraint; t_f must be a whole
        number of steps. 1/1024 s is exact in binary and equals the control period.
    """

    knot_spacing: float = 0.125
    regularization: float = 1e-10
    max_iterations: int = 30
    end_tolerance: float = 1e-11
    step_tolerance: float = 1e-10
    step: float = 1.0 / CONTROL_RATE

    def __post_init__(self) -> None:
        for name in ("knot_spacing", "end_tolerance", "step_tolerance", "step"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"ShapePlannerOptions.{name} must be positive, got {v!r}")
        if not (math.isfinite(self.regularization) and self.regularization >= 0):
            raise ConfigError(
                f"ShapePlannerOptions.regularization must be >= 0, got {self.regularization!r}"
            )
        if not (isinstance(self.max_iterations, int) and self.max_iterations >= 1):
            raise ConfigError(
                f"ShapePlannerOptions.max_iterations must be an integer >= 1, "
                f"got {self.max_iterations!r}"
            )


class ShapePlannerStatus(enum.Enum):
    """Outcome of :func:`plan_shape_trajectory`."""

    CONVERGED = "converged"
    """End state met to ``end_tolerance`` and the iteration settled."""
    MAX_ITERATIONS = "max_iterations"
    """Iteration limit reached before convergence."""
    DIVERGED = "diverged"
    """The iteration produced non-finite values."""


@dataclass(frozen=True)
class TrajectorySample:
    """A state trajectory sampled at given times.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Sample times (s).
    states : ndarray, shape (N, 8)
        x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y] (rad, rad/s).
    accelerations : ndarray, shape (N, 4)
        q̈ (rad/s²).
    inputs : ndarray, shape (N, 2)
        Generalised torques τ (N m), friction included.
    position : ndarray, shape (N, 6)
        Ball x, y, ẋ, ẏ, ẍ, ÿ (m, m/s, m/s²): x = r_w (θ_x + φ_x) etc.
    """

    time: FloatArray
    states: FloatArray
    accelerations: FloatArray
    inputs: FloatArray
    position: FloatArray


@dataclass(frozen=True)
class ShapeTrajectory:
    """A feasible state trajectory: lean B-splines plus the integrated ball angles.

    Sampling evaluates the lean spline exactly, interpolates θ, θ̇ between the
    integration nodes (quintic Hermite from θ, θ̇, θ̈; exact at the nodes) and
    recomputes θ̈ and τ from the equations of motion, so every sample satisfies
    the equations of motion to rounding.

    Attributes
    ----------
    params : BallbotParams
    model : {"3d", "planar", "linear"}
    duration : float
        t_f (s).
    step : float
        Integration step h (s).
    knots : ndarray, shape (n + 6,)
        Knot vector of the quintic lean splines.
    coefficients : ndarray, shape (n, 2)
        Spline coefficients of φ_x, φ_y (rad); the first and last three are 0.
    theta, theta_dot, theta_ddot : ndarray, shape (N + 1, 2)
        θ (rad), θ̇ (rad/s), θ̈ (rad/s²) at the nodes t_k = k h.
    """

    params: BallbotParams
    model: ModelName
    duration: float
    step: float
    knots: FloatArray
    coefficients: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    _spline: BSpline = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = round(self.duration / self.step)
        for name in ("knots", "coefficients", "theta", "theta_dot", "theta_ddot"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if (
            self.theta.shape != (n + 1, 2)
            or self.theta_dot.shape != self.theta.shape
            or (self.theta_ddot.shape != self.theta.shape)
        ):
            raise ConfigError(f"node arrays must have shape ({n + 1}, 2)")
        if self.coefficients.shape != (self.knots.shape[0] - _DEGREE - 1, 2):
            raise ConfigError("coefficients do not match the knots")
        object.__setattr__(self, "_spline", BSpline(self.knots, self.coefficients, _DEGREE))

    def lean(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` of the lean [φ_x, φ_y] (rad/s^order) at ``t`` (s), shape (N, 2)."""
        tt = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        spl = self._spline if order == 0 else self._spline.derivative(order)
        return np.asarray(spl(tt), dtype=float)

    def sample(self, timepts: ArrayLike) -> TrajectorySample:
        """Sample states, accelerations, torques and ball motion at ``timepts`` (s), (N,).

        Times must lie in [0, t_f] (up to 1e-9 s).
        """
        t = np.atleast_1d(np.asarray(timepts, dtype=float))
        if t.ndim != 1:
            raise ConfigError(f"timepts must be one-dimensional, got shape {t.shape}")
        if t.size and (t.min() < -1e-9 or t.max() > self.duration + 1e-9):
            raise ConfigError(
                f"sample times must lie in [0, {self.duration}] s, got [{t.min()}, {t.max()}]"
            )
        t = np.clip(t, 0.0, self.duration)
        th, thd = quintic_hermite(t, self.step, self.theta, self.theta_dot, self.theta_ddot)
        ph = self.lean(t)
        phd = self.lean(t, 1)
        phdd = self.lean(t, 2)
        q = np.ascontiguousarray(np.concatenate([th, ph], axis=1))
        qd = np.ascontiguousarray(np.concatenate([thd, phd], axis=1))
        kind = _KIND[self.model]
        qdd = np.empty_like(q)
        tau = np.empty((t.size, 2))
        _inverse_dynamics(
            kind,
            _model_constants(self.params, kind),
            friction_constants(self.params),
            q,
            qd,
            np.ascontiguousarray(phdd),
            qdd,
            tau,
        )
        r = self.params.ball_radius
        pos = np.concatenate(
            [r * (q[:, :2] + q[:, 2:]), r * (qd[:, :2] + qd[:, 2:]), r * (qdd[:, :2] + qdd[:, 2:])],
            axis=1,
        )
        return TrajectorySample(t, np.concatenate([q, qd], axis=1), qdd, tau, pos)


@dataclass(frozen=True)
class ShapePlannerResult:
    """Result of :func:`plan_shape_trajectory`.

    Attributes
    ----------
    status : ShapePlannerStatus
    iterations : int
        Gauss–Newton iterations done.
    trajectory : ShapeTrajectory
        The planned feasible trajectory (the last iterate if not converged).
    tracking_rms, tracking_max : float
        RMS and maximum over the integration nodes of |y_achieved − y_desired| (m),
        y the flat output r_w (θ + φ) + L φ per axis.
    ball_rms, ball_max : float
        The same for the ball position r_w (θ + φ) against the desired flat
        output (m): includes the physical roll-back/overshoot L φ.
    end_error : float
        Largest end position (m) or velocity (m/s) error against the reference.
    peak_lean : float
        Largest body tilt from vertical, arccos(cos φ_x cos φ_y) (rad).
    peak_torque : float
        Largest |τ_x|, |τ_y| (N m), friction included.
    dynamics_residual : float
        Largest |M q̈ + bias + [D(θ̇), 0] − [τ, 0]| over the nodes (N m), evaluated
        with the model's numpy implementation (independent of the kernels).
    integration_error : float
        Richardson estimate of the RK4 error of θ (rad): |θ_h − θ_2h|/15 at t_f.
    """

    status: ShapePlannerStatus
    iterations: int
    trajectory: ShapeTrajectory
    tracking_rms: float
    tracking_max: float
    ball_rms: float
    ball_max: float
    end_error: float
    peak_lean: float
    peak_torque: float
    dynamics_residual: float
    integration_error: float

    @property
    def converged(self) -> bool:
        """Whether the planner converged."""
        return self.status is ShapePlannerStatus.CONVERGED


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
