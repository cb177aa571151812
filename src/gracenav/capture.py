"""Capture at the robot's own state: catches and shifts.

Sequential composition promises a verified policy for every state a push can leave
(paper Sec. IV-C), but policies instantiated on a lattice, at four orientations and a
few speeds, leave most moving states outside every start domain S. A *catch* is
placed where the robot is instead: a braking maneuver from a speed of
:attr:`~gracenav.policies.CatchOptions.speeds` (0 is a rest hold) along +x to rest,
then a rest tail, turned near the robot's heading and moved so that it ends on a fine
grid (spacing d / ``grid_divisions``, anchored where the library's lattice is); of
the headings that end it there, the one whose S best holds the state is used. Its
start domain S is small (the palette's shape at 1–1.5 G) and only has to hold the
speed difference to the nearest catch and a grid cell of placement; its outer
domain D' is a tube of fixed extents around the braking path, much narrower than a
capture regulator's disc. Near a wall what counts is how far ahead the braking
goes; the candidate that goes least far is usually the shortest-reach braking
(:class:`~gracenav.shape_planner.ShortestBrakeReference`), which first drives the
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
:class:`Capture` plans, for one library, the catch, shift and rest trim that take a
state to the goal at least cost, checking each swept D' grown by the footprint
against the map as instantiation does.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE, ControllerGains
from gracenav.domains import EllipsoidalDomain
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
    rotate_pairs_by,
    verify_policy,
)
from gracenav.simulate import Reference

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary
    from gracenav.params import BallbotParams
    from gracenav.shape_planner import PositionReference

__all__ = [
    "CATCH_NAME",
    "PUSHED",
    "SETTLED",
    "SHIFT_NAME",
    "STILL",
    "Capture",
    "CapturePlan",
    "PlacedPolicy",
    "band_leans",
    "capture_for",
    "catch_label",
    "catch_policies",
    "catch_primitives",
    "reverify",
    "settled_leans",
    "shift_cells",
    "shift_policies",
    "shift_primitive",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

CATCH_NAME = "catch"
SHIFT_NAME = "shift"
PUSHED = "pushed"
SETTLED = "settled"
STILL = "still"

#: Planned durations are whole multiples of this (s): 8 control ticks.
_DURATION_STEP = 1.0 / 128.0
#: Limits of the shortest-reach braking's linear program, as shares of the class's
#: (:class:`~gracenav.shape_planner.ShortestBrakeReference`).
_BRAKE_DERATE = 0.97
#: Its duration is at least this times (1 + speed in m/s) (s): its reach then no longer
#: shrinks with more time (within 0.5 mm at 0.35-0.6 m/s).
_BRAKE_SETTLE = 1.0
#: A catch is tried for states whose speed is within this of its own (m/s).
_SPEED_WINDOW = 0.16
#: A catch is placed to end on one of the 3 x 3 grid points nearest its natural stop,
#: at the best of this many headings within this many radians of the direction from
#: the state to that point (see Capture._candidates).
_NEIGHBOURS = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], dtype=np.int64)
_HEADINGS = 61
_HEADING_SPAN = 0.3
#: Largest arc (m) between the samples of a catch's or shift's swept D' checked for
#: clearance. Catches act near walls, where the library's coarser step (the map's
#: resolution, half of it added to every disc) would cost the clearance they need.
_SWEEP_STEP = 0.004
#: Grid points whose ways onto a rest trim are remembered (then forgotten at once).
_HANDOVER_CACHE = 100_000
#: Two-shift ways from a grid point: first shifts tried, and those with a way on
#: after which the search stops (see Capture._handovers).
_CHAIN_TRIES = 48
_CHAIN_FIRSTS = 4
#: A way from a grid point onto a rest trim: (shifts' duration, shift indices, rest row).
_Way = tuple[float, tuple[int, ...], int]


def _remember(
    cache: dict[tuple[int, int, bool], list[_Way]], key: tuple[int, int, bool], ways: list[_Way]
) -> None:
    if len(cache) >= _HANDOVER_CACHE:  # a long run on a large map
        cache.clear()
    cache[key] = ways


def catch_label(speed: float, lean_class: str, scale: float) -> str:
    """Name of a catch, e.g. ``catch_0.5[pushed,S=1.5G]``."""
    return f"{CATCH_NAME}_{speed:g}[{lean_class},S={scale:g}G]"


def _lean_class(policy: MotionPolicy) -> str:
    """PUSHED, SETTLED or STILL for a catch; SETTLED or STILL for a shift."""
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
    from gracenav.braking import sampled_with_rest_tail
    from gracenav.shape_planner import plan_shape_trajectory

    params = gains.params
    t_min = options.min_duration if min_duration is None else min_duration

    def feasible(t: float) -> object | None:
        ref = reference_of(t)
        if ref is None:  # no reference meets the limits at this duration
            return None
        # Too short a T diverges; the result is then rejected, not a user's concern.
        with np.errstate(over="ignore", invalid="ignore"):
            res = plan_shape_trajectory(ref, params, model="3d")
        ok = res.converged and res.peak_lean <= options.max_lean and res.peak_torque <= torque_limit
        return res if ok else None

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
    (:class:`~gracenav.shape_planner.ShortestBrakeReference`, its linear program's
    limits 97 % of the class's, at least 1 + v s long) and one smooth trapezoidal
    deceleration (:class:`~gracenav.shape_planner.BrakeReference`) per ramp of
    ``options.ramps``. Each is of the shortest T feasible on the 3D model with the
    class's lean (``max_lean``, ``settled_max_lean`` or ``still_max_lean``) and torque
    (the share of the limit; the whole limit for the nonic). At speed 0, the rest
    hold of the tail's duration. Empty if nothing is feasible within ``max_duration``.
    """
    from gracenav.shape_planner import BrakeReference, NonicReference, ShortestBrakeReference

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
    least 1 s), then the rest tail."""
    from gracenav.shape_planner import NonicReference

    off = np.asarray(offset, dtype=float)
    zero = np.zeros(2)
    return _plan_to_rest(
        lambda t: NonicReference.between(t, zero, zero, off, zero),
        zero,
        options,
        gains.params.torque_limit,
        gains,
        f"{SHIFT_NAME}_{off[0]:.4g}_{off[1]:.4g}",
        min_duration=max(1.0, options.min_duration),
    )


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
    from gracenav.policies import verify_placements

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
    from gracenav.policies import verify_placements

    opts = options.catch
    assert opts is not None
    leans = {
        PUSHED: push_leans,
        SETTLED: settled_leans(opts),
        STILL: band_leans(*opts.still_lean),
    }[_lean_class(policy)]
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


# --------------------------------------------------------------------------------------
# Placement
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlacedPolicy:
    """A palette policy placed at any heading and point (not on the lattice).

    Attributes
    ----------
    policy : MotionPolicy
        The palette's catch or shift, in its own frame.
    angle : float
        Heading (rad): the policy is rotated by it about its start.
    start_xy : ndarray, shape (2,)
        Where the reference starts (m).
    """

    policy: MotionPolicy
    angle: float
    start_xy: FloatArray

    @cached_property
    def primitive(self) -> SampledPrimitive:
        """The primitive rotated to ``angle`` (its own start at the origin)."""
        return self.policy.primitive.rotated_by(self.angle)

    @property
    def name(self) -> str:
        """E.g. ``catch_0.5[pushed,S=1.5G]@37°(1.2, 0.8)``."""
        x, y = self.start_xy
        return f"{self.policy.name}@{math.degrees(self.angle):.0f}°({x:.3g}, {y:.3g})"

    @property
    def duration(self) -> float:
        """t_f (s)."""
        return self.policy.duration

    @property
    def end_xy(self) -> FloatArray:
        """Where the reference ends (m)."""
        out: FloatArray = self.start_xy + self.primitive.displacement
        return out

    def _world(self, local: EllipsoidalDomain) -> EllipsoidalDomain:
        c = rotate_pairs_by(local.center, self.angle)
        c[:2] += self.start_xy
        # S and G (the palette's shape) are invariant under rotations of the plane.
        return EllipsoidalDomain(c, local.shape_matrix)

    @property
    def start_domain(self) -> EllipsoidalDomain:
        """S in the world frame."""
        return self._world(self.policy.start_domain)

    @property
    def goal_domain(self) -> EllipsoidalDomain:
        """G in the world frame."""
        return self._world(self.policy.goal_domain)

    def reference(self, radius: float) -> tuple[Reference, FloatArray]:
        """World-frame reference (states, feed-forward torques) and reference x, y, ẋ,
        ẏ, ẍ, ÿ at the ticks (T + 1, 6), for a ball of ``radius`` (m)."""
        prim = self.primitive
        states = prim.states.copy()
        states[:, 0:2] += self.start_xy / radius
        position = prim.position.copy()
        position[:, 0:2] += self.start_xy
        return Reference(states, prim.inputs, prim.dt), position

    def outer_monitor(self) -> tuple[FloatArray, FloatArray]:
        """D'(t) at every tick in the world frame: centres (T+1, 4), shapes (T+1, 4, 4)."""
        # D' across the motion (``outer_cross``) turns with the placement.
        rotated = replace(self.policy, primitive=self.primitive)
        centres, shapes = rotated.outer_monitor()
        centres = centres.copy()
        centres[:, :2] += self.start_xy
        return np.ascontiguousarray(centres), shapes


@dataclass(frozen=True)
class CapturePlan:
    """A verified way from a state back onto the library.

    Attributes
    ----------
    catch : PlacedPolicy
        Placed at the state: its S contains it.
    shifts : tuple of PlacedPolicy
        From the catch's end onto ``rest_row``'s point, in the order they run (none if
        the catch ends there, at most two); each one's S ⊇ the G before it.
    rest_row : int
        The library's rest trim the robot is left on (its S ⊇ the last G).
    cost : float
        Duration of the catch and the shifts plus the rest trim's cost-to-go (s); 0 for
        the cost-to-go when planned without a tree.
    """

    catch: PlacedPolicy
    shifts: tuple[PlacedPolicy, ...]
    rest_row: int
    cost: float

    @property
    def policies(self) -> tuple[PlacedPolicy, ...]:
        """The placed policies in the order they run."""
        return (self.catch, *self.shifts)


@dataclass(frozen=True)
class _Member:
    policy: MotionPolicy
    speed: float
    stop: float
    lean_class: str
    shape: FloatArray  # S's shape matrix, (4, 4)
    path: FloatArray  # reference samples along +x relative to the start, (K, 2)
    reach: FloatArray  # D' radius plus half the gap to the next sample, (K,)


def _sweep_of(policy: MotionPolicy, step: float) -> tuple[FloatArray, FloatArray]:
    """Reference samples (K, 2) at most ``step`` of arc apart and the XY radius of D'
    there plus half the arc to a neighbouring sample (K,): the discs whose union
    holds the swept D' (as instantiation checks it)."""
    from gracenav.library import _sweep_samples

    pos, cum, sel = _sweep_samples(policy, step)
    outer, _ = policy.outer_extents(sel * policy.primitive.dt)
    along = float(np.max(outer))
    if policy.outer_cross is not None and np.any(policy.primitive.start_velocity):
        # An ellipse (along a, across b <= a) lies in the discs of radius b centred on
        # its major axis within a - b of its centre: the reference's straight path
        # extended by a - b at both ends, with radius b.
        ext = along - policy.outer_cross
        u = policy.primitive.start_velocity / np.hypot(*policy.primitive.start_velocity)
        k = np.arange(1, int(np.ceil(ext / step)) + 1)
        grow = np.minimum(k * step, ext)
        pts = np.concatenate(
            [(-grow[::-1])[:, None] * u, pos[sel], pos[sel][-1] + grow[:, None] * u]
        )
        cum_all = np.concatenate([-grow[::-1], cum[sel], cum[sel][-1] + grow])
        outer = np.full(pts.shape[0], policy.outer_cross)
    else:
        pts, cum_all = pos[sel], cum[sel]
    reach = np.asarray(outer, dtype=float).copy()
    if pts.shape[0] > 1:
        half = 0.5 * np.diff(cum_all)
        seg = np.maximum(outer[:-1], outer[1:]) + half
        reach[:-1] = np.maximum(reach[:-1], seg)
        reach[1:] = np.maximum(reach[1:], seg)
    return np.ascontiguousarray(pts), reach


def capture_for(library: PolicyLibrary) -> Capture:
    """The library's :class:`Capture` (built once and kept with the library)."""
    got = library._cache.get("capture")
    if got is None:
        got = library._cache["capture"] = Capture(library)
    assert isinstance(got, Capture)
    return got


class Capture:
    """Plans captures (catch, shift, rest trim) on one library.

    Parameters
    ----------
    library : PolicyLibrary
        Its palette's catches and shifts are placed on its map, with its footprint;
        its rest trims are where captures end.
    """

    def __init__(self, library: PolicyLibrary) -> None:
        self.library = library
        palette = library.palette
        opts = palette.options.catch
        self.options = opts
        self.grid = palette.d / (opts.grid_divisions if opts is not None else 1)
        self.origin = np.asarray(library.origin, dtype=float)
        step = min(float(library.sweep_step), _SWEEP_STEP)
        members = []
        for pol in palette.catches:
            path, reach = _sweep_of(pol, step)
            members.append(
                _Member(
                    pol,
                    float(pol.primitive.start_velocity[0]),
                    float(pol.primitive.displacement[0]),
                    _lean_class(pol),
                    pol.start_domain.shape_matrix,
                    path,
                    reach,
                )
            )
        self._members = members
        # Shifts at the four quarter turns, their swept D' samples padded to one length.
        shifts: list[tuple[MotionPolicy, float]] = []
        paths: list[FloatArray] = []
        reaches: list[FloatArray] = []
        still: list[bool] = []
        for pol in palette.shifts:
            path, reach = _sweep_of(pol, step)
            for k in range(4):
                angle = 0.5 * math.pi * k
                c, s = math.cos(angle), math.sin(angle)
                shifts.append((pol, angle))
                paths.append(path @ np.array([[c, -s], [s, c]]).T)
                reaches.append(reach)
                still.append(_lean_class(pol) == STILL)
        self._shifts = shifts
        # A still shift's S holds a still catch's G only.
        self._shift_still = np.array(still, dtype=bool)
        width = max((a.shape[0] for a in paths), default=1)
        self._shift_path = np.zeros((len(paths), width, 2))
        self._shift_reach = np.zeros((len(paths), width))
        for k, (a, b) in enumerate(zip(paths, reaches, strict=True)):
            self._shift_path[k, : a.shape[0]] = a
            self._shift_path[k, a.shape[0] :] = a[-1]
            self._shift_reach[k, : b.size] = b
            self._shift_reach[k, b.size :] = b[-1]
        self._shift_cells = np.array(
            [np.round(a[-1] / self.grid) for a in paths], dtype=np.int64
        ).reshape(-1, 2)
        self._shift_time = np.array([p.duration for p, _ in shifts], dtype=float)
        rest = library.trim_indices(PrimitiveKind.REST)
        keys = np.round((library.start_xy[rest] - self.origin) / self.grid).astype(np.int64)
        # The rest rows at each grid point, ascending (one sort, not a scan per point).
        points, which = np.unique(keys.reshape(-1, 2), axis=0, return_inverse=True)
        which = which.reshape(-1)
        order = np.argsort(which, kind="stable")
        bounds = np.searchsorted(which[order], np.arange(points.shape[0] + 1))
        self._rest: dict[tuple[int, int], NDArray[np.int64]] = {
            (int(key[0]), int(key[1])): rest[order[a:b]]
            for key, a, b in zip(points, bounds[:-1], bounds[1:], strict=True)
        }
        self._direct_ways: dict[tuple[int, int, bool], list[_Way]] = {}
        self._chained: dict[tuple[int, int, bool], list[_Way]] = {}

    @property
    def available(self) -> bool:
        """Whether the palette has catches to place."""
        return bool(self._members)

    def _clear(self, points: FloatArray, reach: FloatArray) -> BoolArray:
        world = self.library.world_map
        flat = points.reshape(-1, 2)
        ok = world.is_free(flat) & (
            world.clearance(flat)
            >= self.library.footprint_radius + np.broadcast_to(reach, points.shape[:-1]).reshape(-1)
        )
        return np.asarray(ok.reshape(points.shape[:-1]), dtype=bool)

    def _direct(self, cell: tuple[int, int], still: bool) -> list[_Way]:
        """(shift duration, shift indices, rest row) of every way from grid point
        ``cell`` onto a rest trim with at most one shift: the rest trims at the point
        itself, then those a shift with a clear swept D' reaches (still shifts too after
        a ``still`` catch)."""
        key = (cell[0], cell[1], still)
        got = self._direct_ways.get(key)
        if got is not None:
            return got
        out: list[_Way] = []
        for row in self._rest.get(cell, ()):
            out.append((0.0, (), int(row)))
        q = self.origin + np.asarray(cell, dtype=float) * self.grid
        ends = self._shift_cells + np.asarray(cell, dtype=np.int64)
        found = [
            None if self._shift_still[k] and not still else self._rest.get((int(i), int(j)))
            for k, (i, j) in enumerate(ends)
        ]
        ks = np.array([k for k, rows in enumerate(found) if rows is not None], dtype=np.int64)
        if ks.size:
            clear = np.all(self._clear(q + self._shift_path[ks], self._shift_reach[ks]), axis=1)
            for k in ks[clear]:
                rows = found[int(k)]
                assert rows is not None
                out.extend((float(self._shift_time[k]), (int(k),), int(row)) for row in rows)
        _remember(self._direct_ways, key, out)
        return out

    def _handovers(self, cell: tuple[int, int], still: bool) -> list[_Way]:
        """(shifts' duration, shift indices, rest row) of the ways from grid point
        ``cell`` onto a rest trim: those of :meth:`_direct`; from a point where there
        are none (a catch ending too near a wall for a shift toward a rest trim, or in a
        passage without one), two shifts: a first one with a clear swept D' (a still
        one too after a ``still`` catch), then a plain one, whose S (``shift_scale``
        G) holds the first one's G. The first shifts are tried from the one ending
        with the most clearance, until ``_CHAIN_FIRSTS`` of them have a way on or
        ``_CHAIN_TRIES`` have been tried."""
        out = self._direct(cell, still)
        if out:
            return out
        key = (cell[0], cell[1], still)
        got = self._chained.get(key)
        if got is not None:
            return got
        q = self.origin + np.asarray(cell, dtype=float) * self.grid
        ks = np.flatnonzero(~self._shift_still | still)
        ks = ks[np.all(self._clear(q + self._shift_path[ks], self._shift_reach[ks]), axis=1)]
        ends = self._shift_cells[ks] + np.asarray(cell, dtype=np.int64)
        room = self.library.world_map.clearance(self.origin + ends * self.grid)
        best: dict[int, _Way] = {}
        firsts = 0
        for n in np.argsort(-room, kind="stable")[:_CHAIN_TRIES]:
            k = int(ks[n])
            onward = self._direct((int(ends[n, 0]), int(ends[n, 1])), False)
            for t2, ks2, row in onward:
                way = (float(self._shift_time[k]) + t2, (k, *ks2), row)
                if row not in best or way[0] < best[row][0]:
                    best[row] = way
            firsts += bool(onward)
            if firsts >= _CHAIN_FIRSTS:
                break
        chained = sorted(best.values())
        _remember(self._chained, key, chained)
        return chained

    def _candidates(
        self, state: FloatArray, classes: tuple[str, ...], flat: FloatArray | None = None
    ) -> list[tuple[int, float, _Member, float, FloatArray, tuple[int, int]]]:
        """(class rank, S value, member, heading, start, end cell) of every placement of
        a catch whose S contains ``state`` (``flat``, the flat output's position state,
        for a catch of :attr:`~gracenav.policies.MotionPolicy.flat_start`; default
        ``state``), the catch ending on a grid point near its natural stop.

        A catch ending at grid point q may start anywhere on the circle of radius its
        stop around q, at the heading that points it at q. Of the headings within
        ``_HEADING_SPAN`` of the direction from the state to q (``_HEADINGS`` of them,
        that direction among them) the one with the least S value is kept: S couples
        position and velocity errors (its thinnest axis mixes them), so a lateral offset
        of the start can cancel the state's lateral velocity, which pointing the catch
        straight at q cannot.
        """

        def motion(st: FloatArray) -> tuple[FloatArray, FloatArray, float, FloatArray]:
            v = st[2:4]
            speed = float(np.hypot(*v))
            return st[:2], v, speed, v / speed if speed > 1e-9 else np.array([1.0, 0.0])

        of_state = motion(state)
        of_flat = of_state if flat is None else motion(flat)
        offsets = np.linspace(-_HEADING_SPAN, _HEADING_SPAN, _HEADINGS)
        out = []
        for m in self._members:
            p, v, speed, u = of_flat if m.policy.flat_start else of_state
            if m.lean_class not in classes or abs(m.speed - speed) > _SPEED_WINDOW:
                continue
            base = np.round((p + m.stop * u - self.origin) / self.grid).astype(np.int64)
            cells = base + _NEIGHBOURS  # (9, 2)
            q = self.origin + cells * self.grid
            if m.stop > 1e-9:
                w = q - p
                keep = np.hypot(w[:, 0], w[:, 1]) >= 1e-9
                cells, q, w = cells[keep], q[keep], w[keep]
                towards = np.arctan2(w[:, 1], w[:, 0])
            else:  # a rest hold: it starts where it ends
                towards = np.full(q.shape[0], math.atan2(u[1], u[0]))
            heading = towards[:, None] + offsets[None, :]  # (cells, headings)
            c, s = np.cos(heading), np.sin(heading)
            start = q[:, None, :] - m.stop * np.stack([c, s], axis=-1)
            dp = p - start
            local = np.stack(
                [
                    c * dp[..., 0] + s * dp[..., 1],
                    c * dp[..., 1] - s * dp[..., 0],
                    c * v[0] + s * v[1] - m.speed,
                    c * v[1] - s * v[0],
                ],
                axis=-1,
            )
            value = np.einsum("...i,ij,...j->...", local, m.shape, local)
            k = np.argmin(value, axis=1)
            rows = np.arange(value.shape[0])
            rank = classes.index(m.lean_class)
            for i in np.flatnonzero(value[rows, k] <= 1.0):
                out.append(
                    (
                        rank,
                        float(value[i, k[i]]),
                        m,
                        float(heading[i, k[i]]),
                        start[i, k[i]].copy(),
                        (int(cells[i, 0]), int(cells[i, 1])),
                    )
                )
        out.sort(key=lambda c: (c[0], c[1]))
        return out

    def plan(
        self,
        state: ArrayLike,
        *,
        lean_deviation: tuple[float, float] | None = None,
        cost_to_go: FloatArray | None = None,
        settle: Callable[[NDArray[np.int64]], None] | None = None,
        flat_state: ArrayLike | None = None,
    ) -> CapturePlan | None:
        """The cheapest verified capture of ``state`` (x, y, ẋ, ẏ), or None.

        Parameters
        ----------
        state : array_like, shape (4,)
            The ball's position state.
        lean_deviation : (float, float), optional
            The measured lean (rad) and lean rate (rad/s) deviation from the plan's
            (the catch's plan lean is upright), largest over both axes; settled and
            still catches are considered only when it is within their band. None:
            only pushed ones.
        cost_to_go : ndarray, optional
            Cost-to-go of every library row toward the goal (inf where unreachable);
            None ranks rest trims equally (any verified capture will do).
        settle : callable, optional
            Called with the rest-trim rows a clear catch could end on before their
            ``cost_to_go`` is read (a :class:`~gracenav.planning.LazyPolicyTree` fills
            it on demand).
        flat_state : array_like, shape (4,), optional
            The flat output's position state
            (:func:`~gracenav.policies.flat_position_state`), which the pushed
            catches' S holds; default ``state`` (the lean at the plan's).
        """
        if not self._members:
            return None
        st = np.asarray(state, dtype=float).reshape(4)
        flat = None if flat_state is None else np.asarray(flat_state, dtype=float).reshape(4)
        classes: tuple[str, ...] = (PUSHED,)
        opts = self.options
        if lean_deviation is not None and opts is not None:
            dev = (abs(lean_deviation[0]), abs(lean_deviation[1]))
            if dev[0] <= opts.still_lean[0] and dev[1] <= opts.still_lean[1]:
                classes = (STILL, SETTLED, PUSHED)
            elif dev[0] <= opts.settled_lean[0] and dev[1] <= opts.settled_lean[1]:
                classes = (SETTLED, PUSHED)
        best: tuple[float, int, float] | None = None
        chosen = None
        for rank, value, m, heading, start, cell in self._candidates(st, classes, flat):
            c, s = math.cos(heading), math.sin(heading)
            rot = np.array([[c, -s], [s, c]])
            if not np.all(self._clear(start + m.path @ rot.T, m.reach)):
                continue
            ways = self._handovers(cell, m.lean_class == STILL)
            if settle is not None and ways:
                settle(np.array(sorted({w[2] for w in ways}), dtype=np.int64))
            for shift_t, ks, row in ways:
                togo = 0.0 if cost_to_go is None else float(cost_to_go[row])
                if not math.isfinite(togo):
                    continue
                total = m.policy.duration + shift_t + togo
                key = (total, rank, value)
                if best is None or key < best:
                    best, chosen = key, (m, heading, start, cell, ks, row)
            if cost_to_go is None and chosen is not None:
                break
        if chosen is None or best is None:
            return None
        m, heading, start, cell, ks, row = chosen
        catch = PlacedPolicy(m.policy, heading, np.asarray(start, dtype=float))
        shifts = []
        at = np.asarray(cell, dtype=np.int64)
        for k in ks:
            pol, angle = self._shifts[k]
            shifts.append(PlacedPolicy(pol, angle, self.origin + at * self.grid))
            at = at + self._shift_cells[k]
        return CapturePlan(catch, tuple(shifts), row, best[0])

    def covers(self, states: ArrayLike) -> BoolArray:
        """Whether a capture plan (with the plan lean: settled and still catches too)
        exists for each state (n, 4)."""
        pts = np.asarray(states, dtype=float).reshape(-1, 4)
        return np.array(
            [self.plan(s, lean_deviation=(0.0, 0.0)) is not None for s in pts], dtype=bool
        )
