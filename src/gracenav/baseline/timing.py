"""Time parameterization of the decoupled baseline (step 3 of :mod:`gracenav.baseline`).

Forward and backward passes on the arc length under the friction circle and the
curvature speed cap, three box filters in time for a bounded jerk, and local retiming
where the smoothed profile exceeds the acceleration limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter1d

from gracenav.baseline.options import MotionLimits
from gracenav.baseline.path import _Curve, _on_curve, _sample_curve
from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError

__all__ = ["TimedPath", "time_parameterize"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TimedPath:
    """A desired position trajectory sampled at the control ticks.

    Satisfies :class:`gracenav.primitives.shape_planner.PositionReference`.

    Attributes
    ----------
    dt : float
        Sample period (s).
    position, velocity, acceleration, jerk, snap : ndarray, shape (N, 2)
        Derivatives 0–4 (m/s^k) at t_k = k·dt. Acceleration is exact (chain rule on
        the curve); jerk and snap are central differences. The two ends are trims
        (acceleration, jerk and snap zero).
    arc_length : ndarray, shape (N,)
        Distance along the path (m).
    speed : ndarray, shape (N,)
        ṡ (m/s).
    """

    dt: float
    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    jerk: FloatArray
    snap: FloatArray
    arc_length: FloatArray
    speed: FloatArray

    @property
    def duration(self) -> float:
        """t_f (s)."""
        return (self.position.shape[0] - 1) * self.dt

    @property
    def time(self) -> FloatArray:
        """Sample times (s), shape (N,)."""
        return np.arange(self.position.shape[0], dtype=np.float64) * self.dt

    def value(self, t: ArrayLike, order: int = 0) -> FloatArray:
        """Derivative ``order`` (0–4) at times ``t`` (s), linear between samples, (M, 2)."""
        arrays = (self.position, self.velocity, self.acceleration, self.jerk, self.snap)
        if not 0 <= order < len(arrays):
            raise ConfigError(f"order must be 0..4, got {order!r}")
        a = arrays[order]
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        grid = self.time
        return np.stack([np.interp(tt, grid, a[:, k]) for k in range(2)], axis=1)


def _passes(
    curve: _Curve, cap: FloatArray, a_max: float, v0: float
) -> FloatArray:  # forward-backward on v(s)
    """Speed v(s) (m/s) from ``v0`` to rest under ``cap`` and the friction circle."""
    ds = np.diff(curve.s)
    k = np.abs(curve.curvature)
    n = cap.size
    v = np.empty(n)
    v[0] = min(v0, cap[0])
    for i in range(n - 1):
        at = math.sqrt(max(a_max**2 - (v[i] ** 2 * k[i]) ** 2, 0.04 * a_max**2))
        v[i + 1] = min(cap[i + 1], math.sqrt(v[i] ** 2 + 2.0 * at * ds[i]))
    v[-1] = 0.0
    for i in range(n - 2, -1, -1):
        at = math.sqrt(max(a_max**2 - (v[i + 1] ** 2 * k[i + 1]) ** 2, 0.04 * a_max**2))
        v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2.0 * at * ds[i]))
    return v


def _box3(v: FloatArray, m: int) -> FloatArray:
    out = v
    for _ in range(3):
        out = uniform_filter1d(out, m, mode="nearest")
    return out


def _profile(
    curve: _Curve, cap: FloatArray, limits: MotionLimits, v0: float, dt: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Timed arc length: times t_k = k dt, s(t_k), ṡ(t_k), s̈(t_k)."""
    a_max = limits.max_acceleration
    m = max(1, round(limits.filter_time / dt)) | 1  # odd window (samples)
    prefix_time = 3 * m * dt  # constant-speed start: the filters leave the start a trim
    vs = v0
    for _ in range(30):
        c = cap.copy()
        pre = curve.s <= vs * prefix_time
        vs = min(vs, float(np.min(c[pre])))
        c[pre] = np.minimum(c[pre], vs)
        v = _passes(curve, c, a_max, vs)
        if vs <= 0 or float(np.min(v[pre])) >= vs - 1e-9:
            break
        vs = float(np.min(v[pre]))
    v[0] = vs
    # time along the path, then the speed at uniform times
    ds = np.diff(curve.s)
    dtk = 2.0 * ds / np.maximum(v[1:] + v[:-1], 1e-9)
    t_s = np.r_[0.0, np.cumsum(dtk)]
    n = math.ceil(t_s[-1] / dt) + 1
    t = np.arange(n) * dt
    speed = np.interp(t, t_s, v)
    pad = 2 * m
    padded = np.r_[np.full(pad, vs), speed, np.zeros(pad)]
    f = _box3(padded, m)
    f[f < 1e-9 * limits.max_speed] = 0.0  # the running sums' rounding where it is at rest
    if vs > 0:
        f = f[pad:]  # t = 0 inside the constant-speed prefix: already a trim
    else:
        moving = np.flatnonzero(f > 0.0)
        f = f[max(int(moving[0]) - 1, 0) :] if moving.size else f[:1]
    moving = np.flatnonzero(f > 0.0)
    f = f[: int(moving[-1]) + 2] if moving.size else f[:2]
    f[-1] = 0.0
    s = np.r_[0.0, np.cumsum(0.5 * (f[1:] + f[:-1]) * dt)]
    scale = curve.length / s[-1]  # the discrete filters' rounding: end exactly at the goal
    acc = np.gradient(f, dt) * scale
    acc[0] = acc[-1] = 0.0
    return s * scale, f * scale, acc


def _timed(curve: _Curve, s: FloatArray, sd: FloatArray, sdd: FloatArray, dt: float) -> TimedPath:
    xy, tan, kap = _on_curve(curve, s)
    nor = np.stack([-tan[:, 1], tan[:, 0]], axis=1)
    vel = tan * sd[:, None]
    acc = tan * sdd[:, None] + nor * (kap * sd**2)[:, None]
    jerk = np.gradient(acc, dt, axis=0)
    snap = np.gradient(jerk, dt, axis=0)
    for a in (acc, jerk, snap):
        a[0] = a[-1] = 0.0
    return TimedPath(dt, xy, vel, acc, jerk, snap, s, sd)


def time_parameterize(
    path: ArrayLike,
    limits: MotionLimits,
    *,
    start_speed: float = 0.0,
    lateral_fraction: float = 0.6,
    dt: float = 1.0 / CONTROL_RATE,
    step: float = 0.005,
    max_retimings: int = 12,
) -> TimedPath:
    """Time a smooth path (n, 2) (m) from ``start_speed`` (m/s) along it to rest.

    See the notes of :mod:`gracenav.baseline` (step 3). The start is a trim: with
    ``start_speed`` > 0 the path's first 3·T seconds are at constant speed.

    Raises
    ------
    ConfigError
        For a path with fewer than two distinct points.
    """
    pts = np.asarray(path, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
        raise ConfigError(f"path must have shape (n >= 2, 2), got {pts.shape}")
    curve = _sample_curve(None, pts, step)
    if curve.length <= 0:
        raise ConfigError("path has zero length")
    return _time_curve(curve, limits, start_speed, lateral_fraction, dt, max_retimings)


def _time_curve(
    curve: _Curve,
    limits: MotionLimits,
    start_speed: float,
    lateral_fraction: float,
    dt: float,
    max_retimings: int,
) -> TimedPath:
    a_max = limits.max_acceleration
    k = np.abs(curve.curvature)
    cap = np.minimum(limits.max_speed, np.sqrt(lateral_fraction * a_max / np.maximum(k, 1e-12)))
    v0 = float(np.clip(start_speed, 0.0, limits.max_speed))
    timed = None
    for _ in range(max_retimings + 1):
        s, sd, sdd = _profile(curve, cap, limits, v0, dt)
        timed = _timed(curve, s, sd, sdd, dt)
        amag = np.linalg.norm(timed.acceleration, axis=1)
        over = amag > a_max * (1 + 1e-3)
        if not np.any(over):
            break
        # lower the cap around every violation by the excess, and retime
        bad = np.zeros(curve.s.size, dtype=bool)
        for sv in s[over]:
            bad |= np.abs(curve.s - sv) <= 0.5 * limits.filter_time * limits.max_speed
        ratio = float(np.max(amag[over]) / a_max)
        cap = np.where(bad, cap / math.sqrt(ratio) * 0.97, cap)
        cap = np.where(bad, np.minimum(cap, np.max(sd[over]) / math.sqrt(ratio)), cap)
    assert timed is not None
    return timed
