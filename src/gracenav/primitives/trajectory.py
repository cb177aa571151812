"""What the shape trajectory planner returns: the feasible state trajectory of the 3D
(or planar, or linearised) model, its samples at any times, the planner's options,
status and result."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import BSpline

from gracenav._util.hermite import quintic_hermite
from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants
from gracenav.params import BallbotParams
from gracenav.primitives.dynamics import _KIND, ModelName, _inverse_dynamics, _model_constants
from gracenav.primitives.references import _DEGREE, FloatArray

__all__ = [
    "ShapePlannerOptions",
    "ShapePlannerResult",
    "ShapePlannerStatus",
    "ShapeTrajectory",
    "TrajectorySample",
]


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

    def within(self, max_lean: float, torque_limit: float) -> bool:
        """Whether the plan is feasible: converged, its lean within ``max_lean`` (rad)
        and its torque within ``torque_limit`` (N m)."""
        return self.converged and self.peak_lean <= max_lean and self.peak_torque <= torque_limit
