"""The decoupled baseline ("plan, then track"): the approach the paper argues against.

A collision-free geometric path is planned first, then timed, then tracked; the
planner knows nothing of the robot's dynamics beyond speed, acceleration and jerk
limits, and nothing is verified. The pipeline (``docs/design.md``, *Decoupled
baseline*):

1. **Geometric path.** A* (8-connected, octile heuristic, no corner cutting) on the
   map's cell centres whose clearance (:attr:`WorldMap.clearance_grid`) is at least
   the footprint radius plus a safety margin (the occupancy grid inflated by the
   footprint); a start or goal closer than that to an obstacle is connected to its
   nearest inflated-free cell.
2. **Smoothing.** Greedy shortcutting (keep the farthest waypoint in line of sight,
   checked against the inflated clearance), then a clamped quintic B-spline whose
   control polygon is the shortcut polyline resampled every ``smoothing_spacing``;
   the spacing halves until the curve keeps the clearance (the polyline itself is the
   last resort).
3. **Time parameterization** within the palette's limits (:func:`motion_limits`):
   speed ≤ the fastest trim speed, |acceleration| ≤ κ · max lean of the primitive set
   (κ the flat-output gain), jerk ≤ κ · the palette's largest lean rate. A forward and
   a backward pass on the arc length with the friction-circle bound
   √(a_t² + (v² k)²) ≤ a_max and v ≤ √(lateral_fraction · a_max / |k|), then the
   speed profile is smoothed in time by three box filters of width
   T = 2 a_max / j_max (acceleration continuous, jerk ≤ j_max, snap bounded; the
   distance travelled is unchanged); where smoothing pushed the acceleration over the
   limit the speed cap is lowered and the passes repeat.
4. **Tracking.** The timed path is the desired flat output of the shape trajectory
   planner (:func:`gracenav.shape_planner.plan_shape_trajectory`, as for the
   palette's maneuvers), whose feasible state trajectory and feed-forward torques are
   tracked by the palette's Fig. 2 controllers on the scenario's plant, with the
   scenario's disturbances. At the end the goal is held (rest reference) until the
   robot is within the hybrid controller's goal tolerance.
5. **Replanning.** When the position error to the reference exceeds
   ``replan_error`` the path is replanned from the measured position and retimed
   from the measured speed along it (at most ``max_replans`` times); while a drag or
   body force acts (the robot is held) it keeps station instead and replans after.
6. **Fall detector.** The simulator's fall limit (``SimulationOptions.fall_lean``):
   the run ends with :attr:`~gracenav.execution.TaskStatus.FELL`.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline
from scipy.ndimage import uniform_filter1d

from gracenav.errors import ConfigError, PlanningError
from gracenav.params import BallbotParams
from gracenav.replanning import ReplanEvent

if TYPE_CHECKING:
    from gracenav.control import ControllerGains
    from gracenav.execution import Episode
    from gracenav.palette import Palette
    from gracenav.scenarios import Scenario, ScenarioResult
    from gracenav.simulate import Disturbance, Reference
    from gracenav.world import WorldMap

__all__ = [
    "BASELINE_POLICY",
    "DecoupledOptions",
    "DecoupledPlan",
    "MotionLimits",
    "TimedPath",
    "grid_path",
    "motion_limits",
    "plan_decoupled",
    "run_decoupled",
    "shortcut_path",
    "smooth_path",
    "time_parameterize",
    "track_decoupled",
]

FloatArray = NDArray[np.float64]

BASELINE_POLICY = -3
"""Value of :attr:`Episode.policy` while the baseline tracks its own reference: not a
library row (≥ 0), not balancing mode (−1, which :attr:`Episode.balancing_time` counts)
and not the terminal regulator (−2)."""

_BASIS_BUDGET_BYTES = 2.0e8
"""Memory budget (bytes) of the shape planner's basis tables for one baseline path: the
knot spacing stays 1/8 s (as the palette's maneuvers) up to ≈ 20 s paths, and widens
beyond."""
_DEGREE = 5
"""Degree of the smoothing B-spline: 5 makes the curvature C³, so that the timed path's
jerk is continuous and its snap bounded (a cubic's jerk jumps at every knot)."""


# --------------------------------------------------------------------------------------
# Options and limits
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DecoupledOptions:
    """Options of the decoupled baseline (tuned values, see ``docs/design.md``).

    Parameters
    ----------
    safety_margin : float
        Clearance (m) beyond the footprint radius that the grid path and the shortcuts
        keep (the inflation of the occupancy grid).
    smooth_margin : float
        Clearance (m) beyond the footprint that the smoothed curve must keep (the
        B-spline cuts the shortcut's corners); at most ``safety_margin``. The ball
        itself runs a few cm outward of the curve in turns (it rolls L φ away from the
        flat output), which this margin also absorbs.
    smoothing_spacing : float
        Initial spacing (m) of the B-spline's control points along the shortcut
        polyline; larger rounds corners more widely.
    speed_scale : float
        Fraction of the palette's fastest trim speed used as the speed limit.
    accel_scale : float
        Fraction of the palette's acceleration and jerk limits used.
    lateral_fraction : float
        Fraction of the acceleration limit that the curvature speed cap leaves to
        the lateral acceleration v² k (the rest is for speeding up and slowing down).
    replan_error : float
        Position error (m) to the reference beyond which the path is replanned.
    max_replans : int
        Most replans of one run; after that the reference is tracked whatever the error.
    hold_chunk : float
        Period (s) at which the goal test runs while the goal is held.
    path_step : float
        Arc-length step (m) of the time parameterization.
    max_retimings : int
        Most passes of the time parameterization lowering the speed cap where the
        smoothed profile exceeds the acceleration limit.
    """

    safety_margin: float = 0.25
    smooth_margin: float = 0.2
    smoothing_spacing: float = 0.5
    speed_scale: float = 1.0
    accel_scale: float = 0.9
    lateral_fraction: float = 0.6
    replan_error: float = 0.25
    max_replans: int = 5
    hold_chunk: float = 0.125
    path_step: float = 0.005
    max_retimings: int = 12

    def __post_init__(self) -> None:
        for name in ("smoothing_spacing", "hold_chunk", "path_step", "replan_error"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"DecoupledOptions.{name} must be positive, got {v!r}")
        for name in ("speed_scale", "accel_scale", "lateral_fraction"):
            v = getattr(self, name)
            if not (0 < v <= 1):
                raise ConfigError(f"DecoupledOptions.{name} must lie in (0, 1], got {v!r}")
        if not (0 <= self.smooth_margin <= self.safety_margin):
            raise ConfigError(
                "DecoupledOptions needs 0 <= smooth_margin <= safety_margin, got "
                f"{self.smooth_margin!r} and {self.safety_margin!r}"
            )
        for name in ("max_replans", "max_retimings"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 0):
                raise ConfigError(f"DecoupledOptions.{name} must be an integer >= 0, got {v!r}")


@dataclass(frozen=True)
class MotionLimits:
    """Limits of the desired flat-output trajectory.

    Attributes
    ----------
    max_speed : float
        (m/s)
    max_acceleration : float
        (m/s²)
    max_jerk : float
        (m/s³)
    """

    max_speed: float
    max_acceleration: float
    max_jerk: float

    def __post_init__(self) -> None:
        for name in ("max_speed", "max_acceleration", "max_jerk"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"MotionLimits.{name} must be positive, got {v!r}")

    @property
    def filter_time(self) -> float:
        """Width T (s) of each of the three box filters: jerk ≤ 2 a_max / T = j_max."""
        return 2.0 * self.max_acceleration / self.max_jerk


def motion_limits(palette: Palette, options: DecoupledOptions | None = None) -> MotionLimits:
    """The palette's limits, scaled by ``options.speed_scale`` and ``accel_scale``.

    Speed: the fastest trim speed (:func:`gracenav.library.max_trim_speed`).
    Acceleration: κ · ``primitive_options.max_lean``, the lean bound of the maneuvers
    (for the linearised model the flat output accelerates at ÿ = κ φ).
    Jerk: κ · the largest lean rate of the palette's primitives (jerk = κ φ̇); both
    acceleration and jerk are scaled by ``options.accel_scale``.
    """
    from gracenav.library import max_trim_speed
    from gracenav.shape_planner import flat_output_gain

    options = options if options is not None else DecoupledOptions()
    kappa = flat_output_gain(palette.params)
    speed = max_trim_speed(palette)
    if speed <= 0:
        raise ConfigError("the palette has no cruise trim: no speed limit for the baseline")
    lean_rate = max(float(np.max(np.abs(p.primitive.states[:, 6:8]))) for p in palette.policies)
    acc = kappa * palette.primitive_options.max_lean * options.accel_scale
    return MotionLimits(
        max_speed=speed * options.speed_scale,
        max_acceleration=acc,
        max_jerk=kappa * lean_rate * options.accel_scale,
    )


# --------------------------------------------------------------------------------------
# 1. Geometric path: A* on the inflated grid
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _astar(free: NDArray[np.bool_], start: int, goal: int) -> NDArray[np.int64]:  # pragma: no cover
    """Cell indices (row-major) of a shortest 8-connected path, empty if none."""
    ny, nx = free.shape
    n = ny * nx
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    di = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
    dj = np.array([-1, 0, 1, -1, 1, -1, 0, 1])
    gi, gj = goal // nx, goal % nx
    g[start] = 0.0
    heap = [(0.0, start)]
    found = False
    while len(heap) > 0:
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == goal:
            found = True
            break
        closed[u] = True
        ui, uj = u // nx, u % nx
        for k in range(8):
            vi = ui + di[k]
            vj = uj + dj[k]
            if vi < 0 or vi >= ny or vj < 0 or vj >= nx or not free[vi, vj]:
                continue
            diag = di[k] != 0 and dj[k] != 0
            if diag and not (free[ui, vj] and free[vi, uj]):
                continue  # no corner cutting
            v = vi * nx + vj
            if closed[v]:
                continue
            ng = g[u] + (1.4142135623730951 if diag else 1.0)
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                dx = abs(vj - gj)
                dy = abs(vi - gi)
                h = dx + dy + (1.4142135623730951 - 2.0) * min(dx, dy)
                heapq.heappush(heap, (ng + h, v))
    if not found:
        return np.zeros(0, dtype=np.int64)
    count = 1
    u = goal
    while u != start:
        u = parent[u]
        count += 1
    out = np.empty(count, dtype=np.int64)
    u = goal
    for k in range(count - 1, -1, -1):
        out[k] = u
        u = parent[u]
    return out


def _nearest_free(world_map: WorldMap, free: NDArray[np.bool_], p: FloatArray) -> int:
    """Row-major index of the free cell nearest to ``p`` (−1 if none)."""
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return -1
    centers = world_map.cell_centers().reshape(-1, 2)[idx]
    return int(idx[int(np.argmin(np.sum((centers - p) ** 2, axis=1)))])


def grid_path(
    world_map: WorldMap, start: ArrayLike, goal: ArrayLike, clearance: float
) -> FloatArray:
    """Shortest 8-connected path on the cell centres with clearance ≥ ``clearance`` (m).

    A* with the octile heuristic (consistent, so the path is optimal on the grid);
    diagonal moves need both side cells free. The start and goal points are joined to
    the nearest such cells.

    Parameters
    ----------
    world_map : WorldMap
    start, goal : array_like, shape (2,)
        Positions (m).
    clearance : float
        Required clearance of the visited cell centres (m): footprint + margin.

    Returns
    -------
    ndarray, shape (K, 2)
        ``start``, the cell centres, ``goal`` (m).

    Raises
    ------
    PlanningError
        If no cell is free enough or the goal's cell cannot be reached.
    """
    p0 = np.asarray(start, dtype=float).reshape(2)
    p1 = np.asarray(goal, dtype=float).reshape(2)
    free = np.ascontiguousarray(world_map.clearance_grid >= clearance)
    s = _nearest_free(world_map, free, p0)
    g = _nearest_free(world_map, free, p1)
    if s < 0 or g < 0:
        raise PlanningError(
            f"no cell of the map keeps {clearance:g} m from obstacles and the map edge: "
            "the robot does not fit; use a smaller footprint or safety margin"
        )
    cells = _astar(free, s, g)
    if cells.size == 0:
        raise PlanningError(
            f"the goal ({p1[0]:g}, {p1[1]:g}) cannot be reached from ({p0[0]:g}, {p0[1]:g}) "
            f"keeping {clearance:g} m from obstacles (footprint radius plus safety margin): "
            "every path is blocked; move the goal or lower the footprint"
        )
    centers = world_map.cell_centers().reshape(-1, 2)[cells]
    return np.asarray(np.vstack([p0, centers, p1]), dtype=np.float64)


# --------------------------------------------------------------------------------------
# 2. Shortcutting and smoothing
# --------------------------------------------------------------------------------------
def _segment_clear(
    world_map: WorldMap, a: FloatArray, b: FloatArray, clearance: float, floor: float
) -> bool:
    """Whether the segment a–b keeps ``clearance`` (m), or ``floor`` where it starts
    lower (leaving an obstacle's neighbourhood is allowed, entering one is not)."""
    length = float(np.linalg.norm(b - a))
    n = max(2, math.ceil(length / (0.25 * world_map.resolution)) + 1)
    s = np.linspace(0.0, 1.0, n)[:, None]
    c = world_map.clearance(a + s * (b - a))
    return bool(
        np.all(c >= np.minimum(clearance, np.maximum.accumulate(c) - 1e-12))
        and (np.all(c >= floor))
    )


def shortcut_path(world_map: WorldMap, path: ArrayLike, clearance: float) -> FloatArray:
    """Greedy shortcutting: from each kept waypoint, jump to the farthest waypoint of
    ``path`` (K, 2) whose straight segment keeps ``clearance`` (m). Returns (M, 2)."""
    pts = np.asarray(path, dtype=float)
    out = [pts[0]]
    i = 0
    floor = min(float(world_map.clearance(pts[:1])[0]), clearance)
    while i < len(pts) - 1:
        j = len(pts) - 1
        while j > i + 1 and not _segment_clear(world_map, pts[i], pts[j], clearance, floor):
            j -= 1
        out.append(pts[j])
        i = j
        floor = min(float(world_map.clearance(pts[i : i + 1])[0]), clearance)
    return np.asarray(np.vstack(out), dtype=np.float64)


def _bspline(polyline: FloatArray, spacing: float) -> BSpline:
    """Clamped B-spline of degree :data:`_DEGREE` whose control polygon is ``polyline``
    resampled every ``spacing`` (m) along each segment."""
    ctrl = [polyline[:1]]
    for a, b in itertools.pairwise(polyline):
        m = max(1, math.ceil(float(np.linalg.norm(b - a)) / spacing))
        ctrl.append(a + np.linspace(0.0, 1.0, m + 1)[1:, None] * (b - a))
    c = np.vstack(ctrl)
    if c.shape[0] < _DEGREE + 1:  # too few points for the degree: resample the polyline
        seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(polyline, axis=0), axis=1))]
        s = np.linspace(0.0, seg[-1], _DEGREE + 1)
        c = np.stack([np.interp(s, seg, polyline[:, k]) for k in range(2)], axis=1)
    n = c.shape[0]
    inner = np.linspace(0.0, 1.0, n - _DEGREE + 1)[1:-1]
    knots = np.concatenate([np.zeros(_DEGREE + 1), inner, np.ones(_DEGREE + 1)])
    return BSpline(knots, c, _DEGREE)


@dataclass(frozen=True)
class _Curve:
    """A smooth path sampled uniformly in arc length."""

    s: FloatArray  # (n,) arc length (m)
    xy: FloatArray  # (n, 2)
    tangent: FloatArray  # (n, 2) unit
    curvature: FloatArray  # (n,) signed (1/m)
    u: FloatArray | None = None  # (m,) dense spline parameters ...
    s_u: FloatArray | None = None  # (m,) ... and their arc lengths (m)
    spline: BSpline | None = None  # None: the polyline itself

    @property
    def length(self) -> float:
        return float(self.s[-1])


def _sample_curve(spline: BSpline | None, polyline: FloatArray, step: float) -> _Curve:
    """Arc-length samples (every ``step`` m or finer) of ``spline`` (or of the polyline)."""
    if spline is None:  # the polyline itself: curvature concentrated at the corners
        seg = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
        keep = np.r_[True, seg > 1e-12]
        polyline = polyline[keep]
        s_knots = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(polyline, axis=0), axis=1))]
        n = max(2, math.ceil(s_knots[-1] / step) + 1)
        s = np.linspace(0.0, s_knots[-1], n)
        xy = np.stack([np.interp(s, s_knots, polyline[:, k]) for k in range(2)], axis=1)
        d = np.gradient(xy, s, axis=0)
        tangent = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        heading = np.unwrap(np.arctan2(tangent[:, 1], tangent[:, 0]))
        curvature = np.gradient(heading, s)
        return _Curve(s, xy, tangent, curvature)
    d1, d2 = spline.derivative(1), spline.derivative(2)
    rough = float(np.sum(np.linalg.norm(np.diff(spline.c, axis=0), axis=1)))
    u = np.linspace(0.0, 1.0, max(200 * len(spline.c), math.ceil(rough / (0.05 * step))) + 1)
    s_u = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(spline(u), axis=0), axis=1))]
    n = max(2, math.ceil(s_u[-1] / step) + 1)
    s = np.linspace(0.0, s_u[-1], n)
    uu = np.interp(s, s_u, u)
    xy = spline(uu)
    r1, r2 = d1(uu), d2(uu)
    nrm = np.maximum(np.linalg.norm(r1, axis=1), 1e-12)
    tangent = r1 / nrm[:, None]
    curvature = (r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]) / nrm**3
    return _Curve(s, np.asarray(xy, dtype=float), tangent, curvature, u, s_u, spline)


def _on_curve(curve: _Curve, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Position (n, 2), unit tangent (n, 2) and signed curvature (n,) at arc lengths ``s``."""
    if curve.spline is None or curve.u is None or curve.s_u is None:
        xy = np.stack([np.interp(s, curve.s, curve.xy[:, k]) for k in range(2)], axis=1)
        tan = np.stack([np.interp(s, curve.s, curve.tangent[:, k]) for k in range(2)], axis=1)
        tan /= np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-12)
        return xy, tan, np.interp(s, curve.s, curve.curvature)
    u = np.interp(s, curve.s_u, curve.u)
    r1, r2 = curve.spline.derivative(1)(u), curve.spline.derivative(2)(u)
    nrm = np.maximum(np.linalg.norm(r1, axis=1), 1e-12)
    kap = (r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0]) / nrm**3
    return np.asarray(curve.spline(u), dtype=float), r1 / nrm[:, None], kap


def smooth_path(
    world_map: WorldMap,
    polyline: ArrayLike,
    clearance: float,
    *,
    spacing: float = 0.5,
    step: float = 0.005,
) -> tuple[FloatArray, float]:
    """Smooth a shortcut polyline into a curve with C³ curvature that keeps ``clearance`` (m).

    A clamped quintic B-spline on the polyline resampled every ``spacing`` (m) as its
    control polygon; the spacing halves until the curve keeps the clearance, down to
    the map resolution; then the polyline itself is returned. Where the start is closer
    to an obstacle than ``clearance``, the curve may only move away until it has it.

    Returns
    -------
    xy : ndarray, shape (n, 2)
        The curve sampled every ``step`` m of arc length (or finer).
    spacing : float
        Control-point spacing used (m); 0 for the polyline.
    """
    pts = np.asarray(polyline, dtype=float)
    curve = _smooth_curve(world_map, pts, clearance, spacing, step)
    return curve[0].xy, curve[1]


def _smooth_curve(
    world_map: WorldMap, pts: FloatArray, clearance: float, spacing: float, step: float
) -> tuple[_Curve, float]:
    floor = min(float(world_map.clearance(pts[:1])[0]), clearance)
    h = spacing
    while h >= world_map.resolution:
        curve = _sample_curve(_bspline(pts, h), pts, step)
        c = world_map.clearance(curve.xy)
        ok = c >= np.minimum(clearance, np.maximum.accumulate(c) - 1e-12)
        if np.all(ok) and np.all(c >= floor - 1e-12):
            return curve, h
        h *= 0.5
    return _sample_curve(None, pts, step), 0.0


# --------------------------------------------------------------------------------------
# 3. Time parameterization
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimedPath:
    """A desired position trajectory sampled at the control ticks.

    Satisfies :class:`gracenav.shape_planner.PositionReference`.

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
    dt: float = 1.0 / 1024.0,
    step: float = 0.005,
    max_retimings: int = 12,
) -> TimedPath:
    """Time a smooth path (n, 2) (m) from ``start_speed`` (m/s) along it to rest.

    See the module notes (step 3). The start is a trim: with ``start_speed`` > 0 the
    path's first 3·T seconds are at constant speed.

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


# --------------------------------------------------------------------------------------
# The whole plan
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DecoupledPlan:
    """One plan of the baseline.

    Attributes
    ----------
    grid : ndarray, shape (K, 2)
        A* path (m).
    shortcut : ndarray, shape (M, 2)
        Shortcut waypoints (m).
    curve : ndarray, shape (n, 2)
        Smoothed path, every ``path_step`` of arc length (m).
    spacing : float
        Control-point spacing of the smoothing (m); 0: the polyline.
    margin : float
        Safety margin used (m): ``options.safety_margin``, or 0 when no path kept it.
    timed : TimedPath
    seconds : float
        Wall time of the geometric planning and timing (s).
    """

    grid: FloatArray
    shortcut: FloatArray
    curve: FloatArray
    spacing: float
    margin: float
    timed: TimedPath
    seconds: float


def plan_decoupled(
    world_map: WorldMap,
    start: ArrayLike,
    goal: ArrayLike,
    *,
    footprint_radius: float,
    limits: MotionLimits,
    start_velocity: ArrayLike = (0.0, 0.0),
    options: DecoupledOptions | None = None,
    dt: float = 1.0 / 1024.0,
) -> DecoupledPlan:
    """Plan, shortcut, smooth and time a path from ``start`` to ``goal`` (m).

    The grid path keeps ``footprint_radius + safety_margin``; if none exists it is
    planned again keeping only the footprint (margin 0). The timing starts from the
    component of ``start_velocity`` (m/s) along the path.

    Raises
    ------
    PlanningError
        If the goal cannot be reached even without the margin.
    """
    options = options if options is not None else DecoupledOptions()
    t0 = _time.perf_counter()
    p0 = np.asarray(start, dtype=float).reshape(2)
    p1 = np.asarray(goal, dtype=float).reshape(2)
    margin = options.safety_margin
    try:
        grid = grid_path(world_map, p0, p1, footprint_radius + margin)
    except PlanningError:
        if margin == 0:
            raise
        margin = 0.0
        grid = grid_path(world_map, p0, p1, footprint_radius)
    plan_clear = footprint_radius + margin
    smooth_clear = footprint_radius + min(margin, options.smooth_margin)
    cut = shortcut_path(world_map, grid, plan_clear)
    curve, spacing = _smooth_curve(
        world_map, cut, smooth_clear, options.smoothing_spacing, options.path_step
    )
    v = np.asarray(start_velocity, dtype=float).reshape(2)
    along = float(v @ curve.tangent[0])
    timed = _time_curve(
        curve, limits, max(along, 0.0), options.lateral_fraction, dt, options.max_retimings
    )
    return DecoupledPlan(
        grid=grid,
        shortcut=cut,
        curve=curve.xy,
        spacing=spacing,
        margin=margin,
        timed=timed,
        seconds=_time.perf_counter() - t0,
    )


def _reference(timed: TimedPath, gains: ControllerGains) -> tuple[Reference, FloatArray, float]:
    """Feasible reference of the 3D model whose flat output tracks ``timed``: states,
    feed-forward torques, ball (x, y, ẋ, ẏ, ẍ, ÿ) (N, 6) and the planner's peak lean."""
    from gracenav import shape_planner
    from gracenav.simulate import Reference

    # The planner's basis tables take 48 bytes per integration step and spline
    # coefficient: widen the knot spacing of long paths to stay within the budget.
    steps = round(timed.duration / timed.dt)
    spacing = max(0.125, 48.0 * steps * steps * timed.dt / _BASIS_BUDGET_BYTES)
    spacing = math.ceil(spacing / 0.125) * 0.125
    res = shape_planner.plan_shape_trajectory(
        timed,
        gains.params,
        model="3d",
        options=shape_planner.ShapePlannerOptions(knot_spacing=spacing, step=timed.dt),
    )
    shape_planner._basis.cache_clear()  # one-off durations: do not keep their tables
    if res.status.value == "diverged":
        raise PlanningError("the shape trajectory planner diverged on the baseline's path")
    sample = res.trajectory.sample(timed.time)
    return Reference(sample.states, sample.inputs, timed.dt), sample.position, res.peak_lean


# --------------------------------------------------------------------------------------
# 4–6. Tracking, replanning, falls
# --------------------------------------------------------------------------------------
def track_decoupled(
    world_map: WorldMap,
    x0: ArrayLike,
    goal: ArrayLike,
    *,
    footprint_radius: float,
    gains: ControllerGains,
    limits: MotionLimits,
    plant_params: BallbotParams | None = None,
    plant: str = "model3d",
    disturbances: Sequence[Disturbance] = (),
    max_time: float = 120.0,
    goal_tolerance: float = 0.05,
    simulation: Any = None,
    options: DecoupledOptions | None = None,
) -> tuple[Episode, list[DecoupledPlan]]:
    """Run the baseline from the plant state ``x0`` (8,) to the rest goal ``goal``.

    Parameters
    ----------
    world_map : WorldMap
    x0 : array_like, shape (8,)
        Initial plant state.
    goal : array_like, shape (2,) or (4,)
        Goal position (m); a velocity part must be zero.
    footprint_radius : float
        (m)
    gains : ControllerGains
        The palette's Fig. 2 controllers (their parameters are the controller's model).
    limits : MotionLimits
    plant_params : BallbotParams, optional
        The simulated plant (default: the controller's).
    plant : {"model3d", "mujoco"}
    disturbances : sequence of Disturbance
        In episode time, applied as the hybrid controller applies them.
    max_time : float
        (s)
    goal_tolerance : float
        Position (m) and speed (m/s) within which the goal counts as reached at rest.
    simulation : SimulationOptions, optional
        Noise, seed, fall limit.
    options : DecoupledOptions, optional

    Returns
    -------
    (Episode, list of DecoupledPlan)
        The episode (policy :data:`BASELINE_POLICY`, no events) and every plan made
        (the first, then one per replan).

    Raises
    ------
    PlanningError
        If the first plan fails.
    """
    from gracenav.execution import (
        Episode,
        TaskStatus,
        _disturbed,
        _Recorder,
        _segment_disturbances,
    )
    from gracenav.simulate import Reference, SimulationOptions, StopReason, position_state, simulate

    options = options if options is not None else DecoupledOptions()
    sim = simulation if simulation is not None else SimulationOptions()
    plant_params = plant_params if plant_params is not None else gains.params
    g = np.asarray(goal, dtype=float)
    goal_xy = g[:2]
    dt = 1.0 / 1024.0
    r = gains.params.ball_radius
    x = np.asarray(x0, dtype=float).copy()
    p = position_state(x, r)
    at_goal = bool(np.linalg.norm(p[:2] - goal_xy) <= goal_tolerance)
    plans = []
    if not at_goal:  # else the goal is only held
        plans.append(
            plan_decoupled(
                world_map,
                p[:2],
                goal_xy,
                footprint_radius=footprint_radius,
                limits=limits,
                start_velocity=p[2:],
                options=options,
                dt=dt,
            )
        )
    record = _Recorder()
    applied: set[int] = set()
    t = 0.0
    ticks = 0
    max_ticks = max(1, math.ceil(max_time / dt - 1e-9))
    replans = 0
    log: list[ReplanEvent] = []  # the replans that made a new plan
    status = TaskStatus.TIMEOUT
    tracking = not at_goal
    hold_xy = goal_xy
    err2 = 1.0 / options.replan_error**2

    def run_segment(ref: Reference, ref_pos: FloatArray, monitor: bool) -> Any:
        nonlocal t, ticks, x, p
        n_seg = min(ref.num_ticks, max_ticks - ticks)
        if n_seg < ref.num_ticks:
            ref = Reference(ref.states[: n_seg + 1], ref.inputs[: n_seg + 1], ref.dt)
            ref_pos = ref_pos[: n_seg + 1]
        mon = None
        if monitor:
            shapes = np.zeros((n_seg + 1, 4, 4))
            shapes[:, 0, 0] = shapes[:, 1, 1] = err2
            mon = (np.ascontiguousarray(ref_pos[:, :4]), shapes)
        local, inst_idx = _segment_disturbances(disturbances, t, dt, n_seg, applied)
        res = simulate(
            x,
            ref,
            gains,
            params=plant_params,
            plant=plant,  # type: ignore[arg-type]
            disturbances=local,
            options=sim,
            monitor=mon,
            stop_on_exit=monitor,
        )
        last = res.states.shape[0] - 1
        for i in inst_idx:
            if round((disturbances[i].time - t) / dt) <= last:  # type: ignore[union-attr]
                applied.add(i)
        record.add(t, res, BASELINE_POLICY, ref_pos)
        t += last * dt
        ticks += last
        x = res.states[-1].copy()
        p = position_state(x, r)
        return res

    def replan() -> bool:
        nonlocal replans
        replans += 1
        if np.linalg.norm(p[:2] - goal_xy) <= goal_tolerance:
            return False  # too short a path to plan: hold the goal
        try:
            plans.append(
                plan_decoupled(
                    world_map,
                    p[:2],
                    goal_xy,
                    footprint_radius=footprint_radius,
                    limits=limits,
                    start_velocity=p[2:],
                    options=options,
                    dt=dt,
                )
            )
        except PlanningError:
            return False
        log.append(ReplanEvent(t, "tracking_error", plans[-1].seconds, 0, 0))
        return True

    while ticks < max_ticks:
        if tracking:
            ref, ref_pos, _ = _reference(plans[-1].timed, gains)
            res = run_segment(ref, ref_pos, replans < options.max_replans)
            if res.stop_reason is StopReason.FELL:
                status = TaskStatus.FELL
                break
            if res.stop_reason is StopReason.DOMAIN_EXIT:
                if _disturbed(disturbances, t):  # held and moved: wait, replan after
                    tracking = False
                    hold_xy = p[:2].copy()
                elif not replan():  # no path from here: keep station until one exists
                    tracking = False
                    near = np.linalg.norm(p[:2] - goal_xy) <= goal_tolerance
                    hold_xy = goal_xy if near else p[:2].copy()
                continue
            tracking = False
        else:
            hold = Reference.hold(hold_xy, options.hold_chunk, params=gains.params)
            ref_pos = np.zeros((hold.num_ticks + 1, 6))
            ref_pos[:, :2] = hold_xy
            res = run_segment(hold, ref_pos, False)
            if res.stop_reason is StopReason.FELL:
                status = TaskStatus.FELL
                break
        if (
            np.linalg.norm(p[:2] - goal_xy) <= goal_tolerance
            and np.linalg.norm(p[2:]) <= goal_tolerance
        ):
            status = TaskStatus.GOAL_REACHED
            break
        far = np.linalg.norm(p[:2] - goal_xy) > options.replan_error
        if (
            not tracking
            and far
            and replans < options.max_replans
            and not _disturbed(disturbances, t)
            and replan()
        ):
            tracking = True
            hold_xy = goal_xy
    time, states, inputs, policy, reference = record.arrays(t, x)
    episode = Episode(
        time=time,
        states=states,
        inputs=inputs,
        policy=policy,
        reference=reference,
        events=(),
        status=status,
        goals_reached=((t, 0),) if status is TaskStatus.GOAL_REACHED else (),
        tree_seconds=tuple(pl.seconds for pl in plans),
        radius=plant_params.ball_radius,
        replans=tuple(log),
    )
    return episode, plans


def run_decoupled(
    scenario: Scenario,
    *,
    palette: Palette | None = None,
    params: BallbotParams | None = None,
    progress: Callable[[int, int], None] | None = None,
    options: DecoupledOptions | None = None,
) -> ScenarioResult:
    """Run a point-to-point scenario with the decoupled baseline instead of the library.

    Same map loading and checks, plant (``params`` with the scenario's plant factors),
    disturbances, noise, seed, ``max_time``, goal tolerance and run summaries as
    :func:`gracenav.scenarios.run_scenario`, so the metrics compare one to one. The
    result has no library (``library=None``, size 0, 0 edges, coverage NaN);
    ``library_seconds`` is the median planning time of the first plans (s) and
    ``tree_ms`` of each run the median planning time of its plans.

    Raises
    ------
    ConfigError
        For a surveillance task (the baseline does point-to-point only), and as
        :func:`~gracenav.scenarios.check_scenario`.
    PlanningError
        As :func:`~gracenav.scenarios.check_scenario`, and for a goal no collision-free
        path reaches from a start (naming the key).
    """
    from gracenav.execution import ExecutionOptions
    from gracenav.palette import load_palette
    from gracenav.scenarios import (
        ScenarioResult,
        _summarise,
        apply_plant_factors,
        check_scenario,
        load_scenario_map,
    )
    from gracenav.simulate import SimulationOptions, state_from_position

    if scenario.kind != "point_to_point":
        raise ConfigError(
            f"{scenario.source}: 'task.kind' surveillance is not supported by the decoupled "
            "baseline (point-to-point only); use the gracenav planner for surveillance"
        )
    palette = palette if palette is not None else load_palette()
    plant_params = apply_plant_factors(scenario, params if params is not None else palette.params)
    if scenario.moving_obstacles:
        raise ConfigError(
            f"{scenario.source}: 'moving_obstacles' are not supported by the decoupled "
            "baseline (it plans once on the static map); use the gracenav planner"
        )
    world_map = load_scenario_map(scenario)
    check_scenario(scenario, world_map, palette)
    options = options if options is not None else DecoupledOptions()
    limits = motion_limits(palette, options)
    sim = SimulationOptions(position_noise_std=scenario.position_noise_std, seed=scenario.seed)
    tolerance = ExecutionOptions().goal_tolerance
    radius = palette.params.ball_radius
    goal = scenario.goals[0]
    for i, start in enumerate(scenario.starts):  # every start plannable before any run
        try:
            grid_path(world_map, start[:2], goal[:2], scenario.footprint_radius)
        except PlanningError as exc:
            raise PlanningError(f"{scenario.source}: 'task.starts[{i}]': {exc}") from None
    episodes = []
    runs = []
    first_plan = []
    for i, start in enumerate(scenario.starts):
        x0 = state_from_position(np.asarray(start), radius)
        ep, plans = track_decoupled(
            world_map,
            x0,
            goal,
            footprint_radius=scenario.footprint_radius,
            gains=palette.gains,
            limits=limits,
            plant_params=plant_params,
            plant=scenario.plant,
            disturbances=scenario.disturbances,
            max_time=scenario.max_time,
            goal_tolerance=tolerance,
            simulation=sim,
            options=options,
        )
        first_plan.append(plans[0].seconds if plans else 0.0)
        episodes.append(ep)
        runs.append(_summarise(ep, start, scenario, world_map, plant_params))
        if progress is not None:
            progress(i + 1, len(scenario.starts))
    return ScenarioResult(
        scenario=scenario,
        episodes=tuple(episodes),
        runs=tuple(runs),
        library_size=0,
        graph_edges=0,
        coverage=float("nan"),
        library_seconds=float(np.median(first_plan)),
        world_map=world_map,
        library=None,
        plant_params=plant_params,
    )
