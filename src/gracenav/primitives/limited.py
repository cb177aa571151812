"""Maneuver references that use the robot's limits: for a maneuver's end conditions, the
shortest duration on a grid for which a polynomial flat output keeps the lean and the
torque within their limits, the polynomial chosen by a linear program.

The nonic of :class:`~gracenav.primitives.references.NonicReference` is the only
degree-9 polynomial with the end conditions (position and velocity given, acceleration,
jerk and snap zero at both ends, so the flat output is C⁴ at the switches); its
acceleration peaks sharply, so at the lean limit it spends most of the maneuver well
below it. A polynomial of higher degree n keeps the same end conditions (ten per axis)
and has n − 9 free control points per axis (in Bernstein form, the first and last
five fixed by the ends); for a duration T they are chosen to minimise
the largest load

    z = max over samples of max(|φ| / φ_max, |τ_lin| / (τ_max − D_c))

with φ = ÿ/κ the lean of the linearised model's flat output (κ =
:func:`~gracenav.primitives.references.flat_output_gain`), |φ| taken as the largest
projection on 16 directions (an inscribed polygon, so |φ| ≤ φ_max holds), and τ_lin
the torque of the linearised model without Coulomb friction, whose D_c the bound
leaves room for (as :func:`~gracenav.primitives.design._linear_estimate` writes
them). The speed cap and the "no backward motion" rule of the palette's references are
linear constraints too. A linear program (HiGHS) at each candidate duration; the
shortest with z ≤ 1 is the duration, and the shape trajectory planner then makes the
reference feasible on the 3D model exactly as it does the nonic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BPoly
from scipy.optimize import linprog

from gracenav.errors import ConfigError
from gracenav.params import BallbotParams
from gracenav.primitives.references import flat_output_gain, flat_output_lengths

__all__ = ["LimitedReferenceOptions", "PolynomialReference", "limited_reference"]

FloatArray = NDArray[np.float64]

_DIRECTIONS = 16
"""Directions of the polygon that bounds the lean's norm (inscribed in its circle)."""


@dataclass(frozen=True)
class PolynomialReference:
    """A polynomial position reference of both axes in Bernstein form,
    y(t) = Σ_k b_k C(n, k) s^k (1 − s)^(n−k), s = t / t_f.

    The control points b_k keep the numbers near the path's own (the power basis of a
    degree-15 polynomial needs coefficients of 10⁶ m and loses the end conditions to
    rounding).

    Parameters
    ----------
    duration : float
        t_f (s), positive.
    control_points : ndarray, shape (n + 1, 2)
        b_k (m).
    """

    duration: float
    control_points: FloatArray

    def _poly(self) -> BPoly:
        c = np.asarray(self.control_points, dtype=float)[:, None, :]
        return BPoly(c, np.array([0.0, self.duration]))

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` at times ``t`` (s), shape (N, 2) (m/s^order)."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        poly = self._poly()
        if order:
            poly = poly.derivative(order)
        return np.asarray(poly(tt), dtype=np.float64).reshape(tt.shape[0], 2)

    def rotated(self, rotation: ArrayLike) -> PolynomialReference:
        """The reference turned by the 2 × 2 ``rotation`` about the origin."""
        r = np.asarray(rotation, dtype=float).reshape(2, 2)
        return PolynomialReference(self.duration, self.control_points @ r.T)


@dataclass(frozen=True)
class LimitedReferenceOptions:
    """Options of :func:`limited_reference`.

    Parameters
    ----------
    degree : int
        Polynomial degree, >= 10 (9 is the nonic, which has no freedom).
    samples : int
        Samples of [0, t_f] where the limits are imposed (the 3D plan checks all).
    max_speed : float
        Largest speed of the reference (m/s).
    max_backward_speed : float
        Largest backward speed (m/s) along an axis whose end velocities are >= 0.
    max_ball_jerk : float or None
        Largest jerk of the ball (m/s³), x⃛ = y⃛ − (L/κ) y⁽⁵⁾ on the linearised model
        (the ball moves against the lean, so a lean that changes fast jerks the ball
        however smooth y is); None: unbounded. The nonic of rest to rest over 0.5 m in
        2.75 s reaches 5.6 m/s³.
    """

    degree: int = 15
    samples: int = 161
    max_speed: float = 0.8
    max_backward_speed: float = 0.02
    max_ball_jerk: float | None = 6.0

    def __post_init__(self) -> None:
        if not (isinstance(self.degree, int) and self.degree >= 10):
            raise ConfigError(f"degree must be an integer >= 10, got {self.degree!r}")
        if not (isinstance(self.samples, int) and self.samples >= 11):
            raise ConfigError(f"samples must be an integer >= 11, got {self.samples!r}")
        for name in ("max_speed", "max_backward_speed", "max_ball_jerk"):
            v = getattr(self, name)
            if name == "max_ball_jerk" and v is None:
                continue
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be positive, got {v!r}")


def _basis(degree: int, duration: float, t: FloatArray, order: int) -> FloatArray:
    """d^order/dt^order of the Bernstein basis on [0, ``duration``] at ``t``: shape
    (len(t), degree + 1)."""
    eye = np.eye(degree + 1)[:, None, :]
    poly = BPoly(eye, np.array([0.0, duration]))
    if order:
        poly = poly.derivative(order)
    return np.asarray(poly(t), dtype=np.float64).reshape(t.shape[0], degree + 1)


def _load_program(
    duration: float,
    v0: FloatArray,
    disp: FloatArray,
    v1: FloatArray,
    params: BallbotParams,
    max_lean: float,
    torque_limit: float,
    options: LimitedReferenceOptions,
) -> tuple[float, FloatArray] | None:
    """The least load z and its control points (n + 1, 2) at ``duration``; None if the
    linear constraints (speed, backward motion) cannot hold."""
    n, T = options.degree, duration
    t = np.linspace(0.0, T, options.samples)
    d = [_basis(n, T, t, o) for o in range(6)]  # y^(o)(t) per control point
    kappa = flat_output_gain(params)
    lengths = flat_output_lengths(params)
    r = params.ball_radius
    alpha, beta = params.alpha(), params.beta()
    # b = b_p + N w per axis, w = (b_5, ..., b_(n−5)): the first and last five control
    # points lie evenly on the end velocities' lines, which makes position and velocity
    # those of the ends and acceleration, jerk and snap zero there, whatever w.
    f = n - 9
    null = np.zeros((n + 1, f))
    null[5 : n - 4] = np.eye(f)
    part = []
    steps = np.arange(5.0)
    for axis in range(2):
        b = np.zeros(n + 1)
        b[:5] = steps * v0[axis] * T / n
        b[n - 4 :] = disp[axis] - steps[::-1] * v1[axis] * T / n
        part.append(b)
    nv = 2 * f + 1
    a_ub: list[FloatArray] = []
    b_ub: list[FloatArray] = []

    def block(axis: int, rows: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(matrix over x, constant) of ``rows`` @ a_axis."""
        out = np.zeros((rows.shape[0], nv))
        out[:, axis * f : (axis + 1) * f] = rows @ null
        return out, rows @ part[axis]

    # Lean: u · ÿ / κ <= z φ_max cos(π/16) for 16 directions u.
    lean_cap = max_lean * math.cos(math.pi / _DIRECTIONS)
    for ang in np.arange(_DIRECTIONS) * 2 * math.pi / _DIRECTIONS:
        (mx, cx), (my, cy) = block(0, d[2]), block(1, d[2])
        rows = (math.cos(ang) * mx + math.sin(ang) * my) / kappa
        rows[:, -1] = -lean_cap
        a_ub.append(rows)
        b_ub.append(-(math.cos(ang) * cx + math.sin(ang) * cy) / kappa)
    # Torque per axis, linearised without Coulomb friction: ±τ_lin <= z (τ_max − D_c).
    tau_cap = torque_limit - params.coulomb_friction
    for axis in range(2):
        phd, phdd = d[3] / kappa, d[4] / kappa
        thd = (d[1] - lengths[axis] * phd) / r - phd
        thdd = (d[2] - lengths[axis] * phdd) / r - phdd
        tau = alpha * thdd + (alpha + beta) * phdd + params.viscous_friction * thd
        mt, ct = block(axis, tau)
        for sign in (1.0, -1.0):
            rows = sign * mt
            rows[:, -1] = -tau_cap
            a_ub.append(rows)
            b_ub.append(-sign * ct)
    # The ball's jerk (inscribed polygon): y⁽³⁾ − (L/κ) y⁽⁵⁾ per axis.
    if options.max_ball_jerk is not None:
        jerk_cap = options.max_ball_jerk * math.cos(math.pi / _DIRECTIONS)
        jx = block(0, d[3] - lengths[0] / kappa * d[5])
        jy = block(1, d[3] - lengths[1] / kappa * d[5])
        for ang in np.arange(_DIRECTIONS) * 2 * math.pi / _DIRECTIONS:
            a_ub.append(math.cos(ang) * jx[0] + math.sin(ang) * jy[0])
            b_ub.append(jerk_cap - (math.cos(ang) * jx[1] + math.sin(ang) * jy[1]))
    # Speed cap (inscribed polygon) and no backward motion.
    speed_cap = options.max_speed * math.cos(math.pi / _DIRECTIONS)
    for ang in np.arange(_DIRECTIONS) * 2 * math.pi / _DIRECTIONS:
        (mx, cx), (my, cy) = block(0, d[1]), block(1, d[1])
        a_ub.append(math.cos(ang) * mx + math.sin(ang) * my)
        b_ub.append(speed_cap - (math.cos(ang) * cx + math.sin(ang) * cy))
    for axis in range(2):
        if v0[axis] >= 0 and v1[axis] >= 0:
            mv, cv = block(axis, d[1])
            a_ub.append(-mv)
            b_ub.append(options.max_backward_speed + cv)
    cost = np.zeros(nv)
    cost[-1] = 1.0
    res = linprog(
        cost,
        A_ub=np.vstack(a_ub),
        b_ub=np.concatenate(b_ub),
        bounds=[(None, None)] * (nv - 1) + [(0.0, None)],
        method="highs",
    )
    if res.status != 0:
        return None
    x = np.asarray(res.x, dtype=float)
    coef = [part[a] + null @ x[a * f : (a + 1) * f] for a in range(2)]
    return float(x[-1]), np.column_stack(coef)


def limited_reference(
    start_velocity: ArrayLike,
    displacement: ArrayLike,
    end_velocity: ArrayLike,
    params: BallbotParams,
    *,
    max_lean: float,
    durations: ArrayLike,
    torque_limit: float | None = None,
    options: LimitedReferenceOptions | None = None,
) -> PolynomialReference | None:
    """The shortest of ``durations`` (ascending, s) with a polynomial reference from the
    origin at ``start_velocity`` to ``displacement`` at ``end_velocity`` (m/s, m, m/s;
    each (2,)) whose linearised lean and torque stay within ``max_lean`` (rad) and
    ``torque_limit`` (N m; default ``params.torque_limit``), C⁴ with zero acceleration,
    jerk and snap at both ends; None if the longest has none (see the module docstring).
    The durations are bisected: the first of a run of feasible ones is found when
    feasibility does not come and go along the grid.
    """
    options = options if options is not None else LimitedReferenceOptions()
    tau = float(params.torque_limit if torque_limit is None else torque_limit)
    ends = (start_velocity, displacement, end_velocity)
    v0, disp, v1 = (np.asarray(a, dtype=float).reshape(2) for a in ends)
    grid = np.asarray(durations, dtype=float)

    solved: dict[int, PolynomialReference | None] = {}

    def at(k: int) -> PolynomialReference | None:
        if k not in solved:
            got = _load_program(float(grid[k]), v0, disp, v1, params, max_lean, tau, options)
            ok = got is not None and got[0] <= 1.0
            solved[k] = PolynomialReference(float(grid[k]), got[1]) if ok and got else None
        return solved[k]

    # Longer is easier (a reference of duration T, slowed down, loads less) up to the
    # backward-motion rule: bisect for the shortest, then check it.
    if grid.size == 0 or at(grid.size - 1) is None:
        return None
    lo, hi = -1, grid.size - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if at(mid) is not None:
            hi = mid
        else:
            lo = mid
    return at(hi)
