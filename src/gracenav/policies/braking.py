"""Braking maneuvers: capture policies that stop a moving robot along its own path.

A capture regulator (:class:`gracenav.policies.RegulatorOptions`) catches a robot
moving in any direction, but its outer domain is a disc around its rest point that
must hold the whole approach: near walls only small regulators fit, and they only
catch slow robots. A braking maneuver starts at a velocity v0 (a speed of
:attr:`BrakingOptions.speeds` along one of the lattice directions
:attr:`BrakingOptions.directions`, at each of the four orientations of instantiation)
and decelerates along v0 to rest on a lattice point, then holds there; its outer
domain is a tube around that path. Near a wall, a robot moving along the wall is
caught by a braking maneuver where no regulator fits.

The desired flat output is the nonic from (0, v0) to (D, 0) with zero acceleration,
jerk and snap at both ends (a C⁴ smooth-step deceleration, monotone, which ends at
v0 T/2): D is the shortest multiple of the lattice step along the direction whose
duration T = 2 D/|v0| (rounded up to 1/128 s, the speed adjusted to match) the shape
trajectory planner makes feasible on the 3D model with the palette maneuvers' lean
limit. A rest tail lets the tracking error settle into G.

Each maneuver is verified as a capture policy (:attr:`MotionPolicy.capture`): start
domain S = s G of the palette's shape at each size of :attr:`BrakingOptions.scales`,
outer domain D'(t) of fixed extents around the moving reference (position extent the
larger of 1.1 e_p(S) and :attr:`BrakingOptions.outer_position_floor`, velocity extent
the larger of 3 e_v(S) and :attr:`BrakingOptions.outer_velocity_floor`: measured, the
error a push leaves needs about 0.3 m and 0.8 m/s), from boundary states with the
plan lean and with the lean a push leaves, at both placements. A size that fails is
left out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gracenav.control import CONTROL_RATE, ControllerGains
from gracenav.policies.options import (
    BrakingOptions,
    PushLeanTable,
    RegulatorOptions,
    VerificationOptions,
    push_lean_table,
)
from gracenav.policies.policy import MotionPolicy
from gracenav.policies.primitive import PrimitiveKind, SampledPrimitive
from gracenav.policies.regulators import variant_label
from gracenav.policies.shape import DomainShape
from gracenav.policies.verification import verify_placements

if TYPE_CHECKING:
    from gracenav.primitives.shape_planner import ShapePlannerResult

__all__ = ["braking_name", "braking_policies", "braking_primitive", "sampled_with_rest_tail"]

FloatArray = NDArray[np.float64]

#: Durations of braking maneuvers are whole multiples of this (s): 8 control ticks,
#: so that the palette stores them coarsely like every primitive.
_DURATION_STEP = 1.0 / 128.0


def braking_name(speed: float, direction: tuple[int, int]) -> str:
    """Name of the braking maneuver from ``speed`` (m/s) along lattice ``direction``."""
    return f"brake_{speed:g}_{direction[0]}_{direction[1]}"


def braking_primitive(
    speed: float,
    direction: tuple[int, int],
    step: float,
    options: BrakingOptions,
    gains: ControllerGains,
) -> SampledPrimitive | None:
    """Plan the braking maneuver from ``speed`` (m/s) along ``direction`` to rest at a
    multiple of ``step`` (m) times the direction's lattice vector, plus the rest tail.

    Returns None if no stopping distance within ``options.max_duration`` is feasible.
    """
    from gracenav.primitives.shape_planner import NonicReference, plan_shape_trajectory

    params = gains.params
    lattice = step * np.hypot(*direction)
    unit = np.asarray(direction, dtype=float) / np.hypot(*direction)
    for k in range(1, 64):
        dist = k * lattice
        duration = math.ceil(2.0 * dist / speed / _DURATION_STEP - 1e-9) * _DURATION_STEP
        if duration < options.min_duration:
            continue
        if duration > options.max_duration:
            return None
        v0 = unit * (2.0 * dist / duration)
        ref = NonicReference.between(duration, np.zeros(2), v0, unit * dist, np.zeros(2))
        res = plan_shape_trajectory(ref, params, model="3d")
        if not res.within(options.max_lean, params.torque_limit):
            continue
        return sampled_with_rest_tail(
            res, duration, options.tail, name=braking_name(speed, direction), start_velocity=v0
        )
    return None


def sampled_with_rest_tail(
    result: ShapePlannerResult,
    duration: float,
    tail: float,
    *,
    name: str,
    start_velocity: FloatArray,
) -> SampledPrimitive:
    """The planned trajectory ``result`` (lasting ``duration`` s, ending at rest) sampled
    at the control ticks, followed by ``tail`` seconds of rest at its end point: a
    maneuver whose rest tail lets the tracking error settle into G."""
    dt = 1.0 / CONTROL_RATE
    n = round(duration / dt)
    m = round(tail / dt)
    s = result.trajectory.sample(np.arange(n + 1) * dt)
    rest = s.states[-1].copy()
    rest[2:4] = 0.0
    rest[4:] = 0.0
    states = np.concatenate([s.states, np.repeat(rest[None], m, axis=0)])
    pos = np.concatenate([s.position, np.repeat(s.position[-1:], m, axis=0)])
    pos[n + 1 :, 2:] = 0.0
    return SampledPrimitive(
        name=name,
        kind=PrimitiveKind.MANEUVER,
        duration=(n + m) * dt,
        dt=dt,
        displacement=pos[-1, :2].copy(),
        start_velocity=np.asarray(start_velocity, dtype=float),
        end_velocity=np.zeros(2),
        states=np.ascontiguousarray(states),
        accelerations=np.ascontiguousarray(np.concatenate([s.accelerations, np.zeros((m, 4))])),
        inputs=np.ascontiguousarray(np.concatenate([s.inputs, np.zeros((m, 2))])),
        position=np.ascontiguousarray(pos),
    )


def braking_policies(
    primitive: SampledPrimitive,
    gains: ControllerGains,
    options: VerificationOptions,
    shape: DomainShape,
    *,
    push_leans: PushLeanTable | None = None,
    progress: Callable[[], None] | None = None,
) -> tuple[MotionPolicy, ...]:
    """The braking maneuver's capture policy of the largest size of the braking options'
    ``scales`` that verifies at both placements, preceded by the larger sizes that
    failed (reports attached). Smaller sizes are not tried once one passes: with the
    outer domain's floors they share its D' and lie inside its S."""
    brk = options.braking
    reg = options.regulator
    if brk is None:
        return ()
    if push_leans is None:
        pushes = reg or RegulatorOptions()  # the regulators' push table
        push_leans = push_lean_table(gains, pushes.push_impulses, pushes.push_times)
    goal = shape.radii(options.goal_position_extent)
    out = []
    for scale in sorted(brk.scales, reverse=True):
        start = goal.scaled(scale)
        cp = max(brk.outer_position_factor, brk.outer_position_floor / start.position)
        cv = max(brk.outer_velocity_factor, brk.outer_velocity_floor / start.velocity)
        pol = MotionPolicy(
            primitive,
            gains,
            start,
            goal,
            (cp, cv),
            shape.correlation,
            label=variant_label(primitive.name, scale),
            capture=True,
        )
        report = verify_placements(
            pol, options, push_leans=push_leans, boundary_points=brk.boundary_points
        )
        out.append(replace(pol, report=report))
        if progress is not None:
            progress()
        if report.passed:
            break
    return tuple(out)
