"""Catches and shifts: the palette's policies for capture at the robot's own state.

Sequential composition promises a verified policy for every state a push can leave
(paper Sec. IV-C), but policies instantiated on a lattice, at four orientations and a
few speeds, leave most moving states outside every start domain S. A *catch* is
placed where the robot is instead: a braking maneuver from a speed of
:attr:`~gracenav.policies.CatchOptions.speeds` (0 is a rest hold) along +x to rest,
then a rest tail, turned near the robot's heading and moved so that it ends on a fine
grid (spacing d / ``grid_divisions``, anchored where the library's lattice is). Its
start domain S is small (the palette's shape at 1–1.5 G) and only has to hold the
speed difference to the nearest catch and a grid cell of placement; its outer
domain D' is a tube of fixed extents around the braking path, much narrower than a
capture regulator's disc. Near a wall what counts is how far ahead the braking
goes; the candidate that goes least far is usually the shortest-reach braking
(:class:`~gracenav.primitives.shape_planner.ShortestBrakeReference`), which first drives the
ball forward to lean the body back and then brakes at the torque share. A *shift*
(a rest-to-rest maneuver of up to ``shift_radius`` between grid points, its S ⊇ G)
then brings the robot onto a lattice rest trim of the library, whose S ⊇ G:
catch ⪰ shift ⪰ rest trim.

Catches are verified like every palette policy (:func:`gracenav.policies.verify_policy`:
boundary states of S, D' at every tick, G at the end, lean and torque limits, no
saturation) at ``headings`` placements over [0°, 180°), in two lean classes:

* ``pushed``: from the plan lean and from the lean and lean rate a push leaves 0,
  0.1, 0.2 and 0.3 s after it (the capture regulators' push table), with the wider
  D' this needs; usable whatever the measured lean. Their S holds the position
  state of the flat output (ball plus L times the lean), which a push does not
  throw ahead the way it throws the ball (:attr:`MotionPolicy.flat_start`);
* ``settled``: from the plan lean and the corners of a small band around it
  (:attr:`~gracenav.policies.CatchOptions.settled_lean`), with a narrow D'; usable
  only when the measured lean is within that band;
* ``still``: from a smaller S and G (half the palette's G) and the corners of a tight
  band (:attr:`~gracenav.policies.CatchOptions.still_lean`), with a D' half the
  settled one: the error from S, not the lean band, then sets D'. Their paths may
  lean and pull harder (``still_max_lean``, ``still_torque_shares``), as the feedback
  has little to correct. They serve states at the plan lean (starts, and the
  position states coverage counts).

Shifts are verified at the 0° and 90° placements from the plan lean and the settled
band; each is verified a second time from a smaller S (a still catch's G fits in it)
and the still band, with a narrower D' (a *still shift*). A still catch hands over to
either kind; the others only to the first.

This module designs and verifies them (the palette builds them: :mod:`gracenav.palette`);
:mod:`gracenav.execution.capture` places them at the robot's state on a library.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE, ControllerGains
from gracenav.policies import (
    CatchOptions,
    DomainRadii,
    DomainShape,
    MotionPolicy,
    PrimitiveKind,
    PushLeanTable,
    SampledPrimitive,
    VerificationOptions,
    VerificationReport,
    combined_report,
    verify_placements,
    verify_policy,
)

if TYPE_CHECKING:
    from gracenav.params import BallbotParams
    from gracenav.primitives.references import PositionReference

__all__ = [
    "CATCH_NAME",
    "PUSHED",
    "SETTLED",
    "SHIFT_NAME",
    "STILL",
    "ball_jerk",
    "band_leans",
    "catch_label",
    "catch_policies",
    "catch_primitives",
    "lean_class_of",
    "reverify",
    "settled_leans",
    "shift_cells",
    "shift_policies",
    "shift_primitive",
    "verify_headings",
    "verify_still_start",
]

FloatArray = NDArray[np.float64]

CATCH_NAME = "catch"
SHIFT_NAME = "shift"
PUSHED = "pushed"
SETTLED = "settled"
STILL = "still"

#: Planned durations are whole multiples of this (s): 8 control ticks.
_DURATION_STEP = 1.0 / 128.0
#: Limits of the shortest-reach braking's linear program, as shares of the class's
#: (:class:`~gracenav.primitives.shape_planner.ShortestBrakeReference`).
_BRAKE_DERATE = 0.97
#: Its duration is at least this times (1 + speed in m/s) (s): its reach then no longer
#: shrinks with more time (within 0.5 mm at 0.35-0.6 m/s).
_BRAKE_SETTLE = 1.0


def catch_label(speed: float, lean_class: str, scale: float) -> str:
    """Name of a catch, e.g. ``catch_0.5[pushed,S=1.5G]``."""
    return f"{CATCH_NAME}_{speed:g}[{lean_class},S={scale:g}G]"


def lean_class_of(policy: MotionPolicy) -> str:
    """The lean class of a catch or shift of the palette.

    Parameters
    ----------
    policy : MotionPolicy
        A catch (:func:`catch_policies`) or shift (:func:`shift_policies`).

    Returns
    -------
    str
        :data:`PUSHED`, :data:`SETTLED` or :data:`STILL` for a catch; :data:`SETTLED`
        or :data:`STILL` (a still shift) for a shift.
    """
    if f"[{STILL}" in policy.label:
        return STILL
    if f"[{SETTLED}," in policy.label or policy.primitive.name.startswith(SHIFT_NAME):
        return SETTLED
    return PUSHED


# --------------------------------------------------------------------------------------
# Primitives
# --------------------------------------------------------------------------------------


def _rest_primitive(name: str, duration: float) -> SampledPrimitive:
    dt = 1.0 / CONTROL_RATE
    n = round(duration / dt)
    zero = np.zeros(2)
    return SampledPrimitive(
        name=name,
        kind=PrimitiveKind.MANEUVER,
        duration=n * dt,
        dt=dt,
        displacement=zero.copy(),
        start_velocity=zero.copy(),
        end_velocity=zero.copy(),
        states=np.zeros((n + 1, 8)),
        accelerations=np.zeros((n + 1, 4)),
        inputs=np.zeros((n + 1, 2)),
        position=np.zeros((n + 1, 6)),
    )


def _plan_to_rest(
    reference_of: Callable[[float], PositionReference | None],
    velocity: FloatArray,
    options: CatchOptions,
    torque_limit: float,
    gains: ControllerGains,
    name: str,
    *,
    min_duration: float | None = None,
) -> SampledPrimitive | None:
    """The shortest duration T (on a 1/16 s then 1/128 s grid, from ``min_duration``,
    default ``options.min_duration``) whose reference ``reference_of(T)`` (from (0,
    ``velocity``) to rest) the shape planner makes feasible within ``options.max_lean``
    and ``torque_limit``, sampled with the rest tail."""
    from gracenav.policies.braking import sampled_with_rest_tail
    from gracenav.primitives.shape_planner import plan_shape_trajectory

    params = gains.params
    t_min = options.min_duration if min_duration is None else min_duration

    def feasible(t: float) -> object | None:
        ref = reference_of(t)
        if ref is None:  # no reference meets the limits at this duration
            return None
        # Too short a T diverges; the result is then rejected, not a user's concern.
        with np.errstate(over="ignore", invalid="ignore"):
            res = plan_shape_trajectory(ref, params, model="3d")
        return res if res.within(options.max_lean, torque_limit) else None

    coarse = 1.0 / 16.0
    t = math.ceil(t_min / _DURATION_STEP - 1e-9) * _DURATION_STEP
    while t <= options.max_duration + 1e-9:
        if feasible(t) is not None:
            break
        t += coarse
    else:
        return None
    lo, hi = max(t_min, t - coarse), t  # feasible at hi
    while hi - lo > _DURATION_STEP + 1e-12:
        mid = math.ceil((lo + hi) / 2 / _DURATION_STEP - 1e-9) * _DURATION_STEP
        if mid >= hi:
            break
        if feasible(mid) is not None:
            hi = mid
        else:
            lo = mid
    res = feasible(hi)
    ref = reference_of(hi)
    assert res is not None and ref is not None
    return sampled_with_rest_tail(
        res,  # type: ignore[arg-type]
        ref.duration,
        options.tail,
        name=name,
        start_velocity=velocity,
    )


def _reach_ahead(prim: SampledPrimitive) -> float:
    """How far ahead of its start (m, along its initial velocity) a catch's path goes."""
    return float(np.max(prim.position[:, 0]))


def catch_primitives(
    speed: float, options: CatchOptions, gains: ControllerGains, *, lean_class: str = PUSHED
) -> list[SampledPrimitive]:
    """The candidate catches from ``speed`` (m/s) along +x to rest, each followed by the
    rest tail, ordered by how far ahead their path reaches (ties: shorter first).

    The candidates are the C⁴ nonic smooth step (the nonic from (0, v) to (v T/2, 0)),
    and for each torque share of the class the shortest-reach braking
    (:class:`~gracenav.primitives.shape_planner.ShortestBrakeReference`, its linear program's
    limits 97 % of the class's, at least 1 + v s long) and one smooth trapezoidal
    deceleration (:class:`~gracenav.primitives.shape_planner.BrakeReference`) per ramp of
    ``options.ramps``. Each is of the shortest T feasible on the 3D model with the
    class's lean (``max_lean``, ``settled_max_lean`` or ``still_max_lean``) and torque
    (the share of the limit; the whole limit for the nonic). At speed 0, the rest
    hold of the tail's duration. Empty if nothing is feasible within ``max_duration``.
    """
    from gracenav.primitives.shape_planner import (
        BrakeReference,
        NonicReference,
        ShortestBrakeReference,
    )

    name = f"{CATCH_NAME}_{speed:g}_{lean_class}"
    if speed == 0.0:
        return [_rest_primitive(name, options.tail)]
    v = np.array([speed, 0.0])
    lean, shares = {
        PUSHED: (options.max_lean, options.pushed_torque_shares),
        SETTLED: (options.settled_max_lean, options.settled_torque_shares),
        STILL: (options.still_max_lean, options.still_torque_shares),
    }[lean_class]
    opts = replace(options, max_lean=lean)
    limit = gains.params.torque_limit
    zero = np.zeros(2)
    found = [
        _plan_to_rest(
            lambda t: NonicReference.between(t, zero, v, np.array([speed * t / 2.0, 0.0]), zero),
            v,
            opts,
            limit,
            gains,
            name,
        )
    ]
    for share in shares:
        # The linear program's limits leave 3 % for the 3D model's terms (about 1 %).
        found.append(
            _plan_to_rest(
                functools.partial(
                    ShortestBrakeReference.plan,
                    velocity=v,
                    params=gains.params,
                    max_lean=_BRAKE_DERATE * lean,
                    max_torque=_BRAKE_DERATE * share * limit,
                ),
                v,
                opts,
                share * limit,
                gains,
                f"{name}_shortest_torque{share:g}",
                min_duration=max(options.min_duration, _BRAKE_SETTLE + speed * _BRAKE_SETTLE),
            )
        )
        for ramp in options.ramps:
            found.append(
                _plan_to_rest(
                    functools.partial(BrakeReference, velocity=v, ramp=ramp),
                    v,
                    opts,
                    share * limit,
                    gains,
                    f"{name}_ramp{ramp:g}_torque{share:g}",
                    min_duration=max(options.min_duration, 2.0 * ramp),
                )
            )
    got = [p for p in found if p is not None]
    return sorted(got, key=lambda p: (round(_reach_ahead(p), 9), p.duration))


def shift_primitive(
    offset: ArrayLike, options: CatchOptions, gains: ControllerGains
) -> SampledPrimitive | None:
    """The rest-to-rest shift by ``offset`` (m) of the shortest feasible duration (at
    least 1 s, and long enough for ``options.shift_max_ball_jerk``), then the rest
    tail."""
    from gracenav.primitives.shape_planner import NonicReference

    off = np.asarray(offset, dtype=float)
    zero = np.zeros(2)

    def nonic(t: float) -> NonicReference:
        return NonicReference.between(t, zero, zero, off, zero)

    t_min = max(1.0, options.min_duration)
    if options.shift_max_ball_jerk is not None:
        t_min = max(t_min, _jerk_duration(nonic, options, gains))
    return _plan_to_rest(
        nonic,
        zero,
        options,
        gains.params.torque_limit,
        gains,
        f"{SHIFT_NAME}_{off[0]:.4g}_{off[1]:.4g}",
        min_duration=t_min,
    )


#: Samples per reference of the ball jerk check (:func:`_jerk_duration`).
_JERK_SAMPLES = 257


def ball_jerk(reference: PositionReference, params: BallbotParams) -> float:
    """Largest ball jerk (m/s³) of a flat-output reference on the linearised model,
    x⃛ = y⃛ − (L/κ) y⁽⁵⁾ on each axis (the ball moves against the lean), on
    :data:`_JERK_SAMPLES` samples."""
    from gracenav.primitives.references import flat_output_gain, flat_output_lengths

    t = np.linspace(0.0, reference.duration, _JERK_SAMPLES)
    lag = flat_output_lengths(params) / flat_output_gain(params)
    jerk = reference.value(t, 3) - lag * reference.value(t, 5)
    return float(np.max(np.hypot(jerk[:, 0], jerk[:, 1])))


def _jerk_duration(
    reference_of: Callable[[float], PositionReference],
    options: CatchOptions,
    gains: ControllerGains,
) -> float:
    """The shortest duration on the planning grid whose reference keeps the ball jerk
    within ``options.shift_max_ball_jerk``: bisection between 1/128 s and a duration
    that does (the nonic's jerk falls with its duration as T⁻³ and T⁻⁵)."""
    bound = options.shift_max_ball_jerk
    assert bound is not None
    params = gains.params
    hi = 1.0
    while ball_jerk(reference_of(hi), params) > bound:
        hi *= 2.0
        if hi > options.max_duration:
            return hi  # beyond every feasible duration: the shift cannot be planned
    lo = 0.0
    while hi - lo > _DURATION_STEP + 1e-12:
        mid = math.ceil((lo + hi) / 2 / _DURATION_STEP - 1e-9) * _DURATION_STEP
        if mid >= hi:
            break
        if ball_jerk(reference_of(mid), params) > bound:
            lo = mid
        else:
            hi = mid
    return hi


def shift_cells(options: CatchOptions, d: float) -> list[tuple[int, int]]:
    """Grid offsets (i, j) of the shifts to build: i >= 1, j >= 0 (one quadrant; the
    others by rotation), within ``shift_radius``."""
    grid = d / options.grid_divisions
    n = int(options.shift_radius / grid)
    return [
        (i, j)
        for i in range(1, n + 1)
        for j in range(0, n + 1)
        if math.hypot(i, j) * grid <= options.shift_radius + 1e-12
    ]


# --------------------------------------------------------------------------------------
# Verification
# --------------------------------------------------------------------------------------


def settled_leans(options: CatchOptions) -> PushLeanTable:
    """The corners of the settled band (:func:`band_leans`)."""
    return band_leans(*options.settled_lean)


def band_leans(lean: float, rate: float) -> PushLeanTable:
    """The four corners (±``lean`` rad, ±``rate`` rad/s) of a band around the plan
    lean, along the motion, as a table for :func:`gracenav.policies.verify_policy`
    (the same at every speed)."""
    return PushLeanTable(
        times=np.arange(4, dtype=float),
        speed=np.full((1, 4), 1e-9),
        lean=np.array([[lean, lean, -lean, -lean]]),
        lean_rate=np.array([[rate, -rate, rate, -rate]]),
    )


def verify_still_start(
    policy: MotionPolicy,
    options: VerificationOptions,
    *,
    params: BallbotParams | None = None,
    placements: tuple[int, ...] = (0, 1),
) -> MotionPolicy:
    """``policy`` with its :attr:`~gracenav.policies.MotionPolicy.still_report` when it
    starts at rest and is neither a rest trim nor a capture policy: verified at both
    placements from its S with the plan lean and from the corners of the still band
    (:attr:`CatchOptions.still_lean`, :func:`band_leans`), on the plant of ``params``
    (default the controller's nominal one). Unchanged otherwise, and when ``options``
    has no catches (no still band).

    A hold (a capture's last shift, a capture regulator) ends with the lean within that
    band long before its own end; a policy verified so may start from it then, by the
    same rule as every switch (its S holds the state). ``placements`` as in
    :func:`~gracenav.policies.verify_placements`."""
    cat = options.catch
    prim = policy.primitive
    if (
        cat is None
        or policy.capture
        or prim.kind is PrimitiveKind.REST
        or bool(np.any(prim.start_velocity != 0.0))
    ):
        return policy
    report = verify_placements(
        policy,
        options,
        params=params,
        push_leans=band_leans(*cat.still_lean),
        placements=placements,
    )
    return replace(policy, still_report=report)


def verify_headings(
    policy: MotionPolicy,
    options: VerificationOptions,
    headings: int,
    *,
    push_leans: PushLeanTable | None,
    boundary_points: int,
) -> VerificationReport:
    """Verify ``policy`` placed at ``headings`` evenly spaced headings in [0°, 180°)."""
    return combined_report(
        *(
            verify_policy(
                replace(policy, primitive=policy.primitive.rotated_by(math.pi * k / headings)),
                options,
                push_leans=push_leans,
                boundary_points=boundary_points,
            )
            for k in range(headings)
        )
    )


def _fixed_outer_policy(
    prim: SampledPrimitive,
    gains: ControllerGains,
    goal: DomainRadii,
    scale: float,
    outer: tuple[float, float],
    correlation: float,
    *,
    label: str = "",
    outer_cross: float | None = None,
) -> MotionPolicy:
    """A policy of S = ``scale`` G whose D' does not shrink (:attr:`MotionPolicy.capture`):
    position and velocity extents at least ``outer`` (m, m/s) and 1.1 and 3 times S's."""
    start = DomainRadii(goal.position * scale, goal.velocity * scale)
    return MotionPolicy(
        prim,
        gains,
        start,
        goal,
        (max(1.1, outer[0] / start.position), max(3.0, outer[1] / start.velocity)),
        correlation,
        label=label,
        capture=True,
        outer_cross=outer_cross,
    )


def catch_policies(
    speed: float,
    gains: ControllerGains,
    options: VerificationOptions,
    shape: DomainShape,
    push_leans: PushLeanTable,
    *,
    classes: tuple[str, ...] = (PUSHED, SETTLED),
) -> tuple[MotionPolicy, ...]:
    """The catches from ``speed``: for each lean class of ``classes``, the first of its
    sizes (``options.catch.scales``, largest first) and candidate paths
    (:func:`catch_primitives`, shortest reach first, at most ``max_candidates`` per
    size) that verifies, preceded by the candidates that failed (reports attached).
    A still catch has S = G = ``still_scale`` times the palette's G. Empty if the
    braking cannot be planned."""
    opts = options.catch
    assert opts is not None
    goal = shape.radii(options.goal_position_extent)
    small = DomainRadii(goal.position * opts.still_scale, goal.velocity * opts.still_scale)
    still_outer = (opts.still_outer[0], opts.still_outer[0], opts.still_outer[1])
    out: list[MotionPolicy] = []
    for cls, (along, across, fv), leans, scales, base, unit in (
        (PUSHED, opts.pushed_outer, push_leans, opts.scales, goal, 1.0),
        (SETTLED, opts.settled_outer, settled_leans(opts), opts.settled_scales, goal, 1.0),
        (STILL, still_outer, band_leans(*opts.still_lean), (1.0,), small, opts.still_scale),
    ):
        if cls not in classes:
            continue
        prims = catch_primitives(speed, opts, gains, lean_class=cls)[: opts.max_candidates]
        for scale, prim in itertools.product(sorted(scales, reverse=True), prims):
            pol = _fixed_outer_policy(
                prim,
                gains,
                base,
                scale,
                (along, fv),
                shape.correlation,
                label=catch_label(speed, cls, scale * unit),
                outer_cross=across if speed > 0 and cls != STILL else None,
            )
            pol = replace(pol, flat_start=cls == PUSHED)
            report = verify_headings(
                pol, options, opts.headings, push_leans=leans, boundary_points=opts.boundary_points
            )
            out.append(replace(pol, report=report))
            if report.passed:
                break
    return tuple(out)


def shift_policies(
    cell: tuple[int, int],
    d: float,
    gains: ControllerGains,
    options: VerificationOptions,
    shape: DomainShape,
) -> tuple[MotionPolicy, ...]:
    """The shift by ``cell`` grid steps, verified at the 0° and 90° placements from the
    plan lean and the settled band, then as a still shift (S = ``still_shift_scale``
    G, the still band, D' ``still_shift_outer``); empty if it cannot be planned."""
    opts = options.catch
    assert opts is not None
    grid = d / opts.grid_divisions
    prim = shift_primitive(np.asarray(cell, dtype=float) * grid, opts, gains)
    if prim is None:
        return ()
    name = f"{SHIFT_NAME}_{cell[0]}_{cell[1]}"
    prim = replace(prim, name=name)
    goal = shape.radii(options.goal_position_extent)
    out = []
    for pol, leans in (
        (
            _fixed_outer_policy(
                prim, gains, goal, opts.shift_scale, opts.shift_outer, shape.correlation
            ),
            settled_leans(opts),
        ),
        (
            _fixed_outer_policy(
                prim,
                gains,
                goal,
                opts.still_shift_scale,
                opts.still_shift_outer,
                shape.correlation,
                label=f"{name}[{STILL}]",
            ),
            band_leans(*opts.still_lean),
        ),
    ):
        report = verify_placements(
            pol, options, push_leans=leans, boundary_points=opts.boundary_points
        )
        out.append(replace(pol, report=report))
    return tuple(out)


def reverify(
    policy: MotionPolicy,
    options: VerificationOptions,
    push_leans: PushLeanTable,
    *,
    params: BallbotParams | None = None,
) -> VerificationReport:
    """Verify a catch or shift of the palette as it was built (placements, lean
    variants of its class, boundary points), on ``params`` (default: nominal)."""
    opts = options.catch
    assert opts is not None
    leans = {
        PUSHED: push_leans,
        SETTLED: settled_leans(opts),
        STILL: band_leans(*opts.still_lean),
    }[lean_class_of(policy)]
    if policy.primitive.name.startswith(SHIFT_NAME):
        return verify_placements(
            policy,
            options,
            params=params,
            push_leans=leans,
            boundary_points=opts.boundary_points,
        )
    return combined_report(
        *(
            verify_policy(
                replace(policy, primitive=policy.primitive.rotated_by(math.pi * k / opts.headings)),
                options,
                params=params,
                push_leans=leans,
                boundary_points=opts.boundary_points,
            )
            for k in range(opts.headings)
        )
    )
