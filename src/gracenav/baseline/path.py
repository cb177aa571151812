"""Geometric path of the decoupled baseline (steps 1–2 of :mod:`gracenav.baseline`).

A* on the map's cells that keep the footprint plus a margin, greedy shortcutting in
line of sight, and the clamped quintic B-spline that smooths the shortcut polyline;
the smoothed curve is sampled in arc length (:class:`_Curve`) for the timing.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline

from gracenav.errors import PlanningError
from gracenav.world.grid_search import astar_cells

if TYPE_CHECKING:
    from gracenav.world import WorldMap

__all__ = ["grid_path", "shortcut_path", "smooth_path"]

FloatArray = NDArray[np.float64]

_DEGREE = 5
"""Degree of the smoothing B-spline: 5 makes the curvature C³, so that the timed path's
jerk is continuous and its snap bounded (a cubic's jerk jumps at every knot)."""


# --------------------------------------------------------------------------------------
# 1. Geometric path: A* on the inflated grid
# --------------------------------------------------------------------------------------
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
    cells = astar_cells(free, s, g)
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
