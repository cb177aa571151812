"""Desired flat outputs the shape trajectory planner makes feasible: nonic references of
the palette's maneuvers, braking references, and the shortest brake within the lean
and torque limits."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline, PPoly

from gracenav.errors import ConfigError
from gracenav.model.planar import PlanarBallbot
from gracenav.params import BallbotParams

__all__ = [
    "BrakeReference",
    "NonicReference",
    "PositionReference",
    "ShortestBrakeReference",
    "flat_output_gain",
    "flat_output_lengths",
]

FloatArray = NDArray[np.float64]

_DEGREE = 5


# --------------------------------------------------------------------------------------
# Desired position trajectories
# --------------------------------------------------------------------------------------
class PositionReference(Protocol):
    """A desired planar position trajectory (the flat output y of both axes)."""

    @property
    def duration(self) -> float:
        """Duration t_f (s)."""
        ...

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` of the position (m/s^order) at times ``t`` (s), shape (N, 2)."""
        ...


@functools.lru_cache(maxsize=1)
def _nonic_end_matrix() -> FloatArray:
    # Rows: derivative orders 0..4 at s = 1 of s^k, k = 5..9.
    m = np.zeros((5, 5))
    for order in range(5):
        for j, k in enumerate(range(5, 10)):
            m[order, j] = math.perm(k, order)
    return np.asarray(np.linalg.inv(m), dtype=np.float64)


@dataclass(frozen=True)
class NonicReference:
    """Nonic (degree-9) polynomial position reference for both axes.

    Position, velocity, acceleration, jerk and snap are fixed at both ends;
    this class fixes acceleration, jerk and snap to zero at both ends, so the
    reference starts and ends at trims (constant velocity).

    Parameters
    ----------
    duration : float
        t_f (s), positive.
    coefficients : ndarray, shape (10, 2)
        Coefficients a_k of y(t) = Σ a_k (t/t_f)^k per axis (m).
    """

    duration: float
    coefficients: FloatArray

    @classmethod
    def between(
        cls,
        duration: float,
        start_position: ArrayLike,
        start_velocity: ArrayLike,
        end_position: ArrayLike,
        end_velocity: ArrayLike,
    ) -> NonicReference:
        """The nonic from (p0, v0) to (p1, v1) in ``duration`` (s), zero acc/jerk/snap at the ends.

        Positions in m, velocities in m/s, each shape (2,).
        """
        if not (duration > 0 and math.isfinite(duration)):
            raise ConfigError(f"reference duration must be positive and finite, got {duration!r}")
        p0, v0, p1, v1 = (
            np.asarray(a, dtype=float).reshape(2)
            for a in (start_position, start_velocity, end_position, end_velocity)
        )
        a = np.zeros((10, 2))
        a[0] = p0
        a[1] = v0 * duration
        rhs = np.zeros((5, 2))
        rhs[0] = p1 - a[0] - a[1]
        rhs[1] = v1 * duration - a[1]
        a[5:] = _nonic_end_matrix() @ rhs
        return cls(float(duration), a)

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` (0-4 or more) at times ``t`` (s), shape (N, 2) (m/s^order)."""
        s = np.atleast_1d(np.asarray(t, dtype=float)) / self.duration
        c = self.coefficients
        for _ in range(order):
            c = c[1:] * np.arange(1, c.shape[0])[:, None]
        out = np.zeros((s.shape[0], 2))
        for k in range(c.shape[0] - 1, -1, -1):
            out = out * s[:, None] + c[k]
        return np.asarray(out / self.duration**order, dtype=np.float64)


#: The septic smooth step 35s⁴ − 84s⁵ + 70s⁶ − 20s⁷ on [0, 1]: rises from 0 to 1 with
#: its first three derivatives zero at both ends; its integral over [0, 1] is 1/2.
_SEPTIC_STEP = (0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0)


@dataclass(frozen=True)
class BrakeReference:
    """Braking from a velocity to rest along a straight line with a smooth trapezoidal
    deceleration: it rises to its peak over ``ramp`` s (a septic smooth step, so the
    jerk and snap are zero at both ends), holds it, and falls back over ``ramp`` s.

    For the same peak deceleration a_max this stops in T = v₀/a_max + ramp, where the
    nonic to rest (:class:`NonicReference`) needs T = 35/16 v₀/a_max: the
    distance, v₀ T/2 in both cases, is much shorter when the peak lean (≈ a_max/g) is
    what limits it. The deceleration profile is symmetric about T/2, so the reference
    stops at ``velocity`` × T/2 from its start.

    Parameters
    ----------
    duration : float
        T (s), at least 2 ``ramp``.
    velocity : ndarray, shape (2,)
        Initial velocity v₀ (m/s); the reference starts at the origin.
    ramp : float
        Rise (and fall) time of the deceleration (s), positive.
    """

    duration: float
    velocity: FloatArray
    ramp: float
    _position: PPoly = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        t, r = float(self.duration), float(self.ramp)
        if not (math.isfinite(t) and math.isfinite(r) and r > 0 and t >= 2.0 * r):
            raise ConfigError(
                f"a brake reference needs 0 < ramp <= duration/2, got ramp {r!r} s and "
                f"duration {t!r} s"
            )
        v = np.asarray(self.velocity, dtype=float).reshape(2)
        v.setflags(write=False)
        object.__setattr__(self, "velocity", v)
        step = np.polynomial.Polynomial(_SEPTIC_STEP)
        rise = step(np.polynomial.Polynomial([0.0, 1.0 / r])).coef  # in t − 0
        fall = step(np.polynomial.Polynomial([1.0, -1.0 / r])).coef  # in t − (T − r)
        coef = np.zeros((8, 3))
        coef[8 - rise.size :, 0] = rise[::-1]
        coef[-1, 1] = 1.0
        coef[8 - fall.size :, 2] = fall[::-1]
        # Unit speed along the motion: deceleration 1/(T − r) at its peak.
        accel = PPoly(-coef / (t - r), np.array([0.0, r, t - r, t]))
        speed = accel.antiderivative(1)
        speed.c[-1] += 1.0  # piecewise constants of a continuous antiderivative
        object.__setattr__(self, "_position", speed.antiderivative(1))

    @property
    def peak_deceleration(self) -> float:
        """a_max = |v₀|/(T − ramp) (m/s²)."""
        return float(np.hypot(*self.velocity) / (self.duration - self.ramp))

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` at times ``t`` (s), shape (N, 2) (m/s^order); constant
        (at rest) after T."""
        s = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        f = self._position.derivative(order) if order > 0 else self._position
        out = f(s)
        if order > 0:
            out = np.where(np.atleast_1d(np.asarray(t, dtype=float)) > self.duration, 0.0, out)
        return np.asarray(out[:, None] * self.velocity[None, :], dtype=np.float64)


#: Weight (m per rad) of the lean spline's second differences in the objective of
#: :meth:`ShortestBrakeReference.plan`: it only settles the motion after the path's
#: farthest point, which the reach alone leaves free (a few 0.1 mm of reach at most).
_BRAKE_SMOOTHING = 1e-3

#: Constraint samples per second of :meth:`ShortestBrakeReference.plan`.
_BRAKE_SAMPLES = 256


def _lean_knots(duration: float, knot_spacing: float) -> FloatArray:
    """Knots of the planner's quintic lean B-spline on [0, ``duration``]: uniform
    interior knots round(t_f / ``knot_spacing``) − 1 of them (at least 1)."""
    n_int = max(1, round(duration / knot_spacing) - 1)
    return np.concatenate(
        [
            np.zeros(_DEGREE + 1),
            np.linspace(0.0, duration, n_int + 2)[1:-1],
            np.full(_DEGREE + 1, duration),
        ]
    )


@dataclass(frozen=True)
class ShortestBrakeReference:
    """Braking from a velocity to rest along a straight line so that the ball goes as
    little ahead as the lean and torque limits allow.

    The flat output y along the motion is y(t) = v₀ t + κ ∬φ, the lean φ a quintic
    B-spline in the planner's own basis (knots every ``knot_spacing``, first and last
    three coefficients zero, so the ends are trims). :meth:`plan` chooses φ by linear
    programming on the planar model linearised about upright (plane x, viscous
    friction; Coulomb friction is taken off the torque limit): it minimises the
    farthest ball position x = y − L φ subject to |φ| ≤ ``max_lean`` and |τ| ≤
    ``max_torque`` at 256 samples per second (between them they hold to 0.01 % and
    0.1 %), and ẏ(t_f) = 0. The optimum first drives the ball *forward* to lean the
    body back, then brakes at the torque limit. At 0.35 and 0.6 m/s (7.5°, 52 N m) it
    goes 0.81 times as far ahead as the best smooth trapezoidal deceleration with the
    same limits, and 1.08 times as far as the optimum over free torque sequences; the
    capture point v₀/ω (ω = √(κ/L)) bounds any stop. The shape planner makes it
    feasible on the 3D model; on the linearised model, without the lean-acceleration
    penalty, it reproduces the lean exactly.

    Parameters
    ----------
    duration : float
        t_f (s).
    velocity : ndarray, shape (2,)
        Initial velocity v₀ (m/s); the reference starts at the origin.
    knots : ndarray
        Knots of the lean B-spline (see :func:`_lean_knots`).
    lean : ndarray
        Its coefficients (rad), the first and last three zero.
    gain : float
        κ (m/s² per rad).
    """

    duration: float
    velocity: FloatArray
    knots: FloatArray
    lean: FloatArray
    gain: float
    _along: tuple[BSpline, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        phi = BSpline(self.knots, self.lean, _DEGREE)
        object.__setattr__(
            self,
            "_along",
            (
                phi.antiderivative(2),
                phi.antiderivative(1),
                phi,
                *(phi.derivative(k) for k in (1, 2)),
            ),
        )

    @classmethod
    def plan(
        cls,
        duration: float,
        velocity: ArrayLike,
        params: BallbotParams,
        *,
        max_lean: float,
        max_torque: float,
        knot_spacing: float = 0.125,
    ) -> ShortestBrakeReference | None:
        """The shortest-reach braking of ``duration`` (s) from ``velocity`` (m/s, shape
        (2,)) with lean at most ``max_lean`` (rad) and torque at most ``max_torque``
        (N m) on the linearised model, or None if no lean in the basis meets them."""
        from scipy.optimize import linprog

        v0 = np.asarray(velocity, dtype=float).reshape(2)
        speed = float(np.hypot(*v0))
        if not (math.isfinite(duration) and duration > 0 and speed > 0):
            raise ConfigError(
                f"a brake needs a positive duration and speed, got {duration!r} s and {speed!r} m/s"
            )
        planar = PlanarBallbot(params, "x")
        a, b, g = planar.alpha, planar.beta, planar.gamma
        r = params.ball_radius
        kappa = flat_output_gain(params)
        length = planar.flat_output_length()
        knots = _lean_knots(duration, knot_spacing)
        nb = knots.size - _DEGREE - 1
        free = np.eye(nb)[:, 3 : nb - 3]
        spl = BSpline(knots, free, _DEGREE)
        ts = np.linspace(0.0, duration, max(2, round(duration * _BRAKE_SAMPLES)) + 1)
        phi, phid, phidd = spl(ts), spl.derivative(1)(ts), spl.derivative(2)(ts)
        int1, int2 = spl.antiderivative(1)(ts), spl.antiderivative(2)(ts)
        ball = kappa * int2 - length * phi  # x − v₀ t
        theta_rate = (kappa * int1 - length * phid) / r - phid  # θ̇ − v₀/r
        theta_acc = (b * params.gravity / r * phi - (a + g + 2.0 * b) * phidd) / (a + b)
        torque = a * theta_acc + (a + b) * phidd + params.viscous_friction * theta_rate
        torque_free = params.viscous_friction * speed / r
        room = max_torque - params.coulomb_friction
        nf = free.shape[1]
        # Variables: lean coefficients c (nf), reach z, second-difference bounds s (nf − 2).
        diff = np.diff(np.eye(nf), n=2, axis=0)
        nd = diff.shape[0]

        def rows(m: FloatArray, z: float = 0.0, s: FloatArray | None = None) -> FloatArray:
            out = np.zeros((m.shape[0], nf + 1 + nd))
            out[:, :nf] = m
            out[:, nf] = z
            if s is not None:
                out[:, nf + 1 :] = s
            return out

        a_ub = np.vstack(
            [
                rows(ball, -1.0),
                rows(phi),
                rows(-phi),
                rows(torque),
                rows(-torque),
                rows(diff, 0.0, -np.eye(nd)),
                rows(-diff, 0.0, -np.eye(nd)),
            ]
        )
        n = ts.size
        b_ub = np.concatenate(
            [
                -speed * ts,
                np.full(2 * n, max_lean),
                np.full(n, room - torque_free),
                np.full(n, room + torque_free),
                np.zeros(2 * nd),
            ]
        )
        a_eq = rows(kappa * spl.antiderivative(1)(np.array([duration])))
        cost = np.zeros(nf + 1 + nd)
        cost[nf] = 1.0
        cost[nf + 1 :] = _BRAKE_SMOOTHING
        bounds = [(None, None)] * (nf + 1) + [(0.0, None)] * nd
        res = linprog(cost, a_ub, b_ub, a_eq, [-speed], bounds=bounds, method="highs")
        if res.status != 0:
            return None
        return cls(float(duration), v0, knots, free @ res.x[:nf], kappa)

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` (0-4) at times ``t`` (s), shape (N, 2) (m/s^order);
        at rest after t_f."""
        if not 0 <= order <= 4:
            raise ConfigError(f"a brake reference has derivatives 0-4, got order {order!r}")
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        s = np.clip(tt, 0.0, self.duration)
        speed = float(np.hypot(*self.velocity))
        along = self.gain * self._along[order](s)
        if order == 0:
            along = along + speed * s
        elif order == 1:
            along = np.where(tt > self.duration, 0.0, along + speed)
        else:
            along = np.where(tt > self.duration, 0.0, along)
        unit = self.velocity / speed
        return np.asarray(along[:, None] * unit[None, :], dtype=np.float64)


# --------------------------------------------------------------------------------------
# Model constants
# --------------------------------------------------------------------------------------
def flat_output_lengths(params: BallbotParams) -> FloatArray:
    """L of the x and y axes (m), shape (2,): y = x + L φ is flat for the linearised model."""
    return np.array(
        [
            PlanarBallbot(params, "x").flat_output_length(),
            PlanarBallbot(params, "y").flat_output_length(),
        ]
    )


def flat_output_gain(params: BallbotParams) -> float:
    """κ = β g/(α + β) (m/s² per rad): ÿ = κ φ for the linearised model (both axes)."""
    return params.beta() * params.gravity / (params.alpha() + params.beta())
