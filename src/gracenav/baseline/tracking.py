"""Tracking of the decoupled baseline (steps 4–6 of :mod:`gracenav.baseline`).

The timed path becomes a feasible reference through the shape trajectory planner and
is tracked by the palette's controllers; a tracking error beyond the threshold
replans from the measured state, and the simulator's fall limit ends the run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.baseline.options import DecoupledOptions, MotionLimits
from gracenav.baseline.plan import DecoupledPlan, plan_decoupled
from gracenav.baseline.timing import TimedPath
from gracenav.errors import PlanningError
from gracenav.params import BallbotParams
from gracenav.planning.repair import ReplanEvent

if TYPE_CHECKING:
    from gracenav.control import ControllerGains, PositionEstimator
    from gracenav.execution import Episode
    from gracenav.sim import Disturbance, Reference
    from gracenav.sim.plant import PlantKind
    from gracenav.world import WorldMap

__all__ = ["BASELINE_POLICY", "DecoupledController", "track_decoupled"]

FloatArray = NDArray[np.float64]

BASELINE_POLICY = -3
"""Value of :attr:`Episode.policy` while the baseline tracks its own reference: not a
library row (≥ 0), not balancing mode (−1, which :attr:`Episode.balancing_time` counts)
and not the terminal regulator (−2)."""

_BASIS_BUDGET_BYTES = 2.0e8
"""Memory budget (bytes) of the shape planner's basis tables for one baseline path: the
knot spacing stays 1/8 s (as the palette's maneuvers) up to ≈ 20 s paths, and widens
beyond."""


def _reference(timed: TimedPath, gains: ControllerGains) -> tuple[Reference, FloatArray, float]:
    """Feasible reference of the 3D model whose flat output tracks ``timed``: states,
    feed-forward torques, ball (x, y, ẋ, ẏ, ẍ, ÿ) (N, 6) and the planner's peak lean."""
    from gracenav.primitives import shape_planner
    from gracenav.sim import Reference

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
    plant: PlantKind = "model3d",
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
    from gracenav.execution import Episode, ExecutionLog, TaskStatus, drive
    from gracenav.sim import SimulationOptions

    sim = simulation if simulation is not None else SimulationOptions()
    plant_params = plant_params if plant_params is not None else gains.params
    controller = DecoupledController(
        world_map,
        goal,
        footprint_radius=footprint_radius,
        gains=gains,
        limits=limits,
        max_time=max_time,
        goal_tolerance=goal_tolerance,
        options=options,
    )
    robot = sim.plant(plant, plant_params)
    robot.reset(np.asarray(x0, dtype=float))
    estimator = None
    if controller.options.position_filter:
        from gracenav.control import PositionEstimator

        estimator = PositionEstimator(
            controller.r, controller.dt, sim.position_noise_std, sim.velocity_noise_std
        )
    controller.reset(robot.measure(), fall_lean=sim.fall_lean, estimator=estimator)
    trace = drive(
        controller,
        robot,
        dt=controller.dt,
        max_ticks=controller.max_ticks + 1,
        disturbances=disturbances,
    )
    status = controller.status
    log = ExecutionLog(
        events=(),
        status=status,
        goals_reached=((trace.time[-1], 0),) if status is TaskStatus.GOAL_REACHED else (),
        tree_seconds=tuple(pl.seconds for pl in controller.plans),
        replans=tuple(controller.log),
    )
    return Episode.from_trace(trace, log), controller.plans


class DecoupledController:
    """The baseline as a per-tick controller: track the timed path's reference, replan
    from the measured state when the tracking error exceeds the threshold (or after a
    hold), hold the goal (or where the robot is) otherwise.

    Parameters are those of :func:`track_decoupled`. :meth:`reset` plans the first path,
    :meth:`step` returns one command a tick (``policy`` :data:`BASELINE_POLICY`).
    """

    def __init__(
        self,
        world_map: WorldMap,
        goal: ArrayLike,
        *,
        footprint_radius: float,
        gains: ControllerGains,
        limits: MotionLimits,
        max_time: float = 120.0,
        goal_tolerance: float = 0.05,
        options: DecoupledOptions | None = None,
    ) -> None:
        from gracenav.control import TrackingLaw
        from gracenav.sim import CONTROL_RATE

        self.world_map = world_map
        self.goal_xy = np.asarray(goal, dtype=float)[:2]
        self.footprint_radius = footprint_radius
        self.gains = gains
        self.limits = limits
        self.options = options if options is not None else DecoupledOptions()
        self.goal_tolerance = goal_tolerance
        self.dt = 1.0 / CONTROL_RATE
        self.r = float(gains.params.ball_radius)
        self.law = TrackingLaw(gains)
        self.max_ticks = max(1, math.ceil(max_time / self.dt - 1e-9))
        self.plans: list[DecoupledPlan] = []
        self.log: list[ReplanEvent] = []

    def reset(
        self,
        x0: ArrayLike,
        *,
        fall_lean: float = math.inf,
        estimator: PositionEstimator | None = None,
    ) -> None:
        """Start from the measured state ``x0`` (8,): plan the first path. With an
        ``estimator``, every measured state is filtered by it first (as the hybrid
        controller does with ``ExecutionOptions.position_filter``).

        Raises
        ------
        PlanningError
            If the first plan fails.
        """
        from gracenav.execution import TaskStatus
        from gracenav.sim import position_state

        self.estimator = estimator
        x = np.asarray(x0, dtype=float).copy()
        self.x = estimator.reset(x) if estimator is not None else x
        self.p = position_state(self.x, self.r)
        at_goal = bool(np.linalg.norm(self.p[:2] - self.goal_xy) <= self.goal_tolerance)
        self.plans = []
        self.log = []
        if not at_goal:  # else the goal is only held
            self.plans.append(self._plan())
        self.tracking = not at_goal
        self.hold_xy = self.goal_xy
        self.replans = 0
        self.ticks = 0
        self.status = TaskStatus.RUNNING
        self.segment: Any = None
        self.fall_lean = fall_lean
        self.held = False
        self.final: Any = None
        self.err2 = 1.0 / self.options.replan_error**2

    def _plan(self) -> DecoupledPlan:
        """A plan from the measured position and velocity to the goal."""
        return plan_decoupled(
            self.world_map,
            self.p[:2],
            self.goal_xy,
            footprint_radius=self.footprint_radius,
            limits=self.limits,
            start_velocity=self.p[2:],
            options=self.options,
            dt=self.dt,
        )

    def _replan(self) -> bool:
        self.replans += 1
        if np.linalg.norm(self.p[:2] - self.goal_xy) <= self.goal_tolerance:
            return False  # too short a path to plan: hold the goal
        try:
            self.plans.append(self._plan())
        except PlanningError:
            return False
        t = self.ticks * self.dt
        self.log.append(ReplanEvent(t, "tracking_error", self.plans[-1].seconds, 0, 0))
        return True

    def _begin(self) -> None:
        from gracenav.execution.supervisor import Segment
        from gracenav.sim import Reference

        if self.tracking:
            ref, ref_pos, _ = _reference(self.plans[-1].timed, self.gains)
            monitor = self.replans < self.options.max_replans
        else:
            ref = Reference.hold(self.hold_xy, self.options.hold_chunk, params=self.gains.params)
            ref_pos = np.zeros((ref.num_ticks + 1, 6))
            ref_pos[:, :2] = self.hold_xy
            monitor = False
        n = min(ref.num_ticks, self.max_ticks - self.ticks)
        centers = shapes = None
        if monitor:
            shapes = np.zeros((n + 1, 4, 4))
            shapes[:, 0, 0] = shapes[:, 1, 1] = self.err2
            centers = np.ascontiguousarray(ref_pos[: n + 1, :4])
        self.segment = Segment(
            BASELINE_POLICY,
            ref.states[: n + 1],
            ref.inputs[: n + 1],
            ref_pos[: n + 1],
            centers,
            shapes,
            n,
        )

    def step(self, t: float, x: ArrayLike, *, held: bool = False) -> Any:
        """The command (:class:`gracenav.execution.Command`) for one tick."""
        from gracenav.execution import Command, TaskStatus
        from gracenav.execution.supervisor import fallen
        from gracenav.sim import position_state

        xs = np.asarray(x, dtype=float)
        if self.final is not None:
            return self.final
        if self.estimator is not None:
            xs = self.estimator.update(xs)
        self.x, self.held = xs, held
        while self.status is TaskStatus.RUNNING:
            if self.segment is None:
                if self.ticks >= self.max_ticks:
                    self.status = TaskStatus.TIMEOUT
                    break
                self._begin()
                continue
            seg = self.segment
            k = seg.k
            if fallen(xs, self.fall_lean):
                self.status = TaskStatus.FELL
                break
            tau, val = seg.command(self.law, xs)
            exited = val > 1.0
            if exited or k == seg.n:
                self.segment = None
                self.p = position_state(xs, self.r)
                self._end(exited)
                continue
            seg.k += 1
            self.ticks += 1
            return Command(tau, False, TaskStatus.RUNNING, seg.policy, seg.ref_pos[k])
        self.final = Command(np.zeros(2), True, self.status, BASELINE_POLICY, np.zeros(6))
        return self.final

    def _end(self, exited: bool) -> None:
        from gracenav.execution import TaskStatus

        p, opt = self.p, self.options
        if self.tracking:
            if exited:
                if self.held:  # held and moved: wait, replan after
                    self.tracking = False
                    self.hold_xy = p[:2].copy()
                elif not self._replan():  # no path from here: keep station until one exists
                    self.tracking = False
                    near = np.linalg.norm(p[:2] - self.goal_xy) <= self.goal_tolerance
                    self.hold_xy = self.goal_xy if near else p[:2].copy()
                return
            self.tracking = False
        if (
            np.linalg.norm(p[:2] - self.goal_xy) <= self.goal_tolerance
            and np.linalg.norm(p[2:]) <= self.goal_tolerance
        ):
            self.status = TaskStatus.GOAL_REACHED
            return
        far = np.linalg.norm(p[:2] - self.goal_xy) > opt.replan_error
        if (
            not self.tracking
            and far
            and self.replans < opt.max_replans
            and not self.held
            and self._replan()
        ):
            self.tracking = True
            self.hold_xy = self.goal_xy
