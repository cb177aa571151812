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
from gracenav.replanning import ReplanEvent

if TYPE_CHECKING:
    from gracenav.control import ControllerGains
    from gracenav.execution import Episode
    from gracenav.simulate import Disturbance, Reference
    from gracenav.world import WorldMap

__all__ = ["BASELINE_POLICY", "track_decoupled"]

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

    def plan_from_here() -> DecoupledPlan:
        """A plan from the measured position and velocity ``p`` to the goal."""
        return plan_decoupled(
            world_map,
            p[:2],
            goal_xy,
            footprint_radius=footprint_radius,
            limits=limits,
            start_velocity=p[2:],
            options=options,
            dt=dt,
        )

    plans: list[DecoupledPlan] = []
    if not at_goal:  # else the goal is only held
        plans.append(plan_from_here())
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
            plans.append(plan_from_here())
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
