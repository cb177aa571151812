"""The decoupled baseline ("plan, then track"): the approach the paper argues against.

A collision-free geometric path is planned first, then timed, then tracked; the
planner knows nothing of the robot's dynamics beyond speed, acceleration and jerk
limits, and nothing is verified. The pipeline (``docs/design/baseline.md``, *Decoupled
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
   (κ the flat-output gain), jerk ≤ κ · the palette's largest lean rate (each times
   its scale in :class:`DecoupledOptions`). A forward and
   a backward pass on the arc length with the friction-circle bound
   √(a_t² + (v² k)²) ≤ a_max and v ≤ √(lateral_fraction · a_max / |k|), then the
   speed profile is smoothed in time by three box filters of width
   T = 2 a_max / j_max (acceleration continuous, jerk ≤ j_max, snap bounded; the
   distance travelled is unchanged); where smoothing pushed the acceleration over the
   limit the speed cap is lowered and the passes repeat.
4. **Tracking.** The timed path is the desired flat output of the shape trajectory
   planner (:func:`gracenav.primitives.shape_planner.plan_shape_trajectory`, as for the
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

Modules by role: :mod:`~gracenav.baseline.options` (options and motion limits),
:mod:`~gracenav.baseline.path` (steps 1–2), :mod:`~gracenav.baseline.timing` (step 3),
:mod:`~gracenav.baseline.plan` (one plan: steps 1–3), :mod:`~gracenav.baseline.tracking`
(steps 4–6) and :mod:`~gracenav.scenarios.decoupled` (a scenario's runs).
"""

from __future__ import annotations

from gracenav.baseline.options import DecoupledOptions, MotionLimits, motion_limits
from gracenav.baseline.path import grid_path, shortcut_path, smooth_path
from gracenav.baseline.plan import DecoupledPlan, plan_decoupled
from gracenav.baseline.timing import TimedPath, time_parameterize
from gracenav.baseline.tracking import BASELINE_POLICY, track_decoupled

__all__ = [
    "BASELINE_POLICY",
    "DecoupledOptions",
    "DecoupledPlan",
    "MotionLimits",
    "TimedPath",
    "grid_path",
    "motion_limits",
    "plan_decoupled",
    "shortcut_path",
    "smooth_path",
    "time_parameterize",
    "track_decoupled",
]
