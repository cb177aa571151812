"""Options of the decoupled baseline and the motion limits of its timed paths."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gracenav.errors import ConfigError

if TYPE_CHECKING:
    from gracenav.palette import Palette

__all__ = ["DecoupledOptions", "MotionLimits", "motion_limits"]


@dataclass(frozen=True)
class DecoupledOptions:
    """Options of the decoupled baseline (tuned values, see ``docs/design/baseline.md``).

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
        Fraction of the palette's acceleration limit used, and of its jerk limit unless
        ``jerk_scale`` is given.
    jerk_scale : float, optional
        Factor on the palette's jerk limit, in (0, 10]; None: ``accel_scale``. Above 1
        the flat output jerks harder than the palette's largest lean rate allows on the
        linearised model (its box filters narrow, so the ball's jerk rises faster than
        the flat output's); for the trade of time against jerk
        (``bench/bench_speed.py --baseline-jerk-scales``).
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
    position_filter : bool
        Track from the ball position :class:`gracenav.control.PositionEstimator`
        estimates, tuned to the simulated sensor's noise (as the hybrid controller's
        ``ExecutionOptions.position_filter``); False tracks the raw measurement.
    """

    safety_margin: float = 0.25
    smooth_margin: float = 0.2
    smoothing_spacing: float = 0.5
    speed_scale: float = 1.0
    accel_scale: float = 0.9
    jerk_scale: float | None = None
    lateral_fraction: float = 0.6
    replan_error: float = 0.25
    max_replans: int = 5
    hold_chunk: float = 0.125
    path_step: float = 0.005
    max_retimings: int = 12
    position_filter: bool = True

    def __post_init__(self) -> None:
        for name in ("smoothing_spacing", "hold_chunk", "path_step", "replan_error"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"DecoupledOptions.{name} must be positive, got {v!r}")
        for name in ("speed_scale", "accel_scale", "lateral_fraction"):
            v = getattr(self, name)
            if not (0 < v <= 1):
                raise ConfigError(f"DecoupledOptions.{name} must lie in (0, 1], got {v!r}")
        if self.jerk_scale is not None and not (
            math.isfinite(self.jerk_scale) and 0 < self.jerk_scale <= 10
        ):
            raise ConfigError(
                f"DecoupledOptions.jerk_scale must lie in (0, 10] or be None, got "
                f"{self.jerk_scale!r}"
            )
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
    Jerk: κ · the largest lean rate of the palette's primitives (jerk = κ φ̇). The
    acceleration is scaled by ``options.accel_scale``, the jerk by
    ``options.jerk_scale`` (default the same ``accel_scale``).
    """
    from gracenav.library import max_trim_speed
    from gracenav.primitives.shape_planner import flat_output_gain

    options = options if options is not None else DecoupledOptions()
    kappa = flat_output_gain(palette.params)
    speed = max_trim_speed(palette)
    if speed <= 0:
        raise ConfigError("the palette has no cruise trim: no speed limit for the baseline")
    lean_rate = max(float(np.max(np.abs(p.primitive.states[:, 6:8]))) for p in palette.policies)
    acc = kappa * palette.primitive_options.max_lean * options.accel_scale
    jerk_scale = options.jerk_scale if options.jerk_scale is not None else options.accel_scale
    return MotionLimits(
        max_speed=speed * options.speed_scale,
        max_acceleration=acc,
        max_jerk=kappa * lean_rate * jerk_scale,
    )
