"""One plan of the decoupled baseline: grid path, shortcut, smoothing and timing."""

from __future__ import annotations

import time as _time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.baseline.options import DecoupledOptions, MotionLimits
from gracenav.baseline.path import _smooth_curve, grid_path, shortcut_path
from gracenav.baseline.timing import TimedPath, _time_curve
from gracenav.control import CONTROL_RATE
from gracenav.errors import PlanningError

if TYPE_CHECKING:
    from gracenav.world import WorldMap

__all__ = ["DecoupledPlan", "plan_decoupled"]

FloatArray = NDArray[np.float64]


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
    dt: float = 1.0 / CONTROL_RATE,
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
