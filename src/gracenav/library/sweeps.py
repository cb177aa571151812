"""Swept outer domains: a policy's D'(t) sampled along its reference, grown by the
footprint, the stopping allowance and the catches a design push calls for, checked
against a map's clearance (compiled)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from gracenav.errors import ConfigError
from gracenav.library.types import ORIENTATIONS, BoolArray, FloatArray, IntArray, _rotate
from gracenav.model.rotation import rotate_pairs
from gracenav.palette import Palette
from gracenav.policies import MotionPolicy
from gracenav.policies.catches import PUSHED, lean_class_of
from gracenav.primitives.references import flat_output_lengths
from gracenav.world import WorldMap

if TYPE_CHECKING:
    from gracenav.params import BallbotParams

__all__ = [
    "FAN_DIRECTIONS",
    "FAN_FLOOR",
    "FAN_GAP",
    "PushFan",
    "fastest_flat_speed",
    "flat_speed_change",
    "push_fan",
    "sweep_samples",
    "swept_discs",
]

# The compiled sweep check runs in parallel. numba's default layer here is GNU OpenMP,
# which aborts any process that forks after using it (worker pools fork: palette
# builds, campaigns, benchmarks), so a fork-safe layer is chosen unless the user
# chose one (environment variable NUMBA_THREADING_LAYER).
_numba_config: Any = numba.config

if _numba_config.THREADING_LAYER == "default" and "NUMBA_THREADING_LAYER" not in os.environ:
    _numba_config.THREADING_LAYER = "forksafe"

_GROUP = 8  # checked sweep samples per bounding disc of the hierarchical sweep check

#: Directions of the design push a push fan checks, evenly spaced over the full turn.
FAN_DIRECTIONS = 8

#: Largest displacement (m) of a push fan's catch discs from a checked state to the
#: states after it that are not checked (see :func:`_with_fan`): every disc is grown
#: by it.
FAN_GAP = 0.1

#: Control ticks between the states a push fan's walk along a reference looks at.
_FAN_STRIDE = 8

#: Flat-output reference speeds (m/s) at or below which a push fan is not checked.
#: The shipped palette's references reach 0.773 m/s (the ball 0.945 m/s), and with the
#: stopping allowance alone every one of 900 seeded pushes of up to 16 N s on the 5 m
#: room was caught there (bench/bench_pushes.py); a fan below it costs reachability
#: near walls that no measured push needed (the 5 m room's task from (1, 1) has no
#: way out with a fan from 0.5 m/s).
FAN_FLOOR = 0.8


@dataclass(frozen=True)
class _Sweep:
    """Checked samples of one palette policy's swept D' (policy frame, footprint excluded).

    A sample j at offset c_j needs clearance(q + c_j) >= footprint + reach_j.
    Groups of consecutive samples are bounded by discs (centre, reach).
    """

    offsets: FloatArray  # (K, 2)
    reach: FloatArray  # (K,)
    group_centre: FloatArray  # (Gp, 2)
    group_reach: FloatArray  # (Gp,)
    group_first: IntArray  # (Gp,) first sample
    group_size: IntArray  # (Gp,)
    total_reach: float  # bound around the start point
    # Groups of consecutive groups, bounded by discs too (a push fan's thousands of
    # samples per policy are checked group by group only near obstacles).
    super_centre: FloatArray  # (Sp, 2)
    super_reach: FloatArray  # (Sp,)
    super_first: IntArray  # (Sp,) first group
    super_size: IntArray  # (Sp,)


def sweep_samples(
    policy: MotionPolicy, step: float, lead: float = 0.0
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Samples of a policy's reference path for checking its swept outer domain D'.

    Parameters
    ----------
    policy : MotionPolicy
    step : float
        Largest arc (m) between selected samples (plus one control tick of motion).
    lead : float
        The path is led by this (s) times the reference velocity.

    Returns
    -------
    pos : ndarray, shape (T+1, 2)
        The (led) reference path relative to its start (m), at every tick.
    cum : ndarray, shape (T+1,)
        Its arc length at each tick (m).
    sel : ndarray of int
        The selected ticks, ascending: the first, the last, and ticks at most
        ``step`` of arc (plus one tick) apart.
    """
    prim = policy.primitive
    pos = prim.position[:, :2] - prim.position[0, :2] + lead * prim.position[:, 2:4]
    seg = np.hypot(*np.diff(pos, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n_ticks = pos.shape[0] - 1
    targets = np.arange(int(cum[-1] // step) + 2) * step
    picked = np.clip(np.searchsorted(cum, targets, side="right") - 1, 0, n_ticks)
    sel = np.unique(np.concatenate([[0], picked, [n_ticks]]))
    return pos, cum, sel


def swept_discs(policy: MotionPolicy, step: float) -> tuple[FloatArray, FloatArray]:
    """Discs whose union holds a policy's swept D' (policy frame, from its start).

    Reference samples (K, 2) at most ``step`` of arc apart and the XY radius of D'
    there plus half the arc to a neighbouring sample (K,), as instantiation checks a
    swept D'. A D' whose XY section is an ellipse (along a, across b <= a; a policy
    with ``outer_cross``) lies in the discs of radius b centred on its major axis
    within a - b of its centre: the straight path is extended by a - b at both ends.
    """
    pos, cum, sel = sweep_samples(policy, step)
    outer, _ = policy.outer_extents(sel * policy.primitive.dt)
    along = float(np.max(outer))
    if policy.outer_cross is not None and np.any(policy.primitive.start_velocity):
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


@dataclass(frozen=True)
class PushFan:
    """The catches a design push calls for along a reference (:func:`push_fan`).

    Attributes
    ----------
    impulse : float
        The design push (N s).
    speed_change : float
        The velocity it adds to the flat output (m/s) right after it
        (:func:`flat_speed_change`).
    above : float
        Flat-output reference speeds (m/s) at or below which no fan is checked
        (:data:`FAN_FLOOR`).
    flat_length : ndarray, shape (2,)
        L of the flat output x + L φ per axis (m): the pushed catches' S hold its state,
        so the fan starts them at the reference's flat output.
    speeds : ndarray, shape (C,)
        Speeds of the palette's pushed catches (m/s), ascending.
    tolerance : ndarray, shape (C,)
        The velocity radius of their start domains S (m/s).
    paths : tuple of ndarray, shape (K_c, 2)
        Disc centres of each speed's catches' swept D' (:func:`swept_discs`), the catch
        heading along +x from its start at the origin.
    reaches : tuple of ndarray, shape (K_c,)
        Their radii (m), grown by one cell of the catches' placement grid.
    radius : ndarray, shape (C,)
        The farthest disc centre of each speed's catches from their start (m).
    """

    impulse: float
    speed_change: float
    above: float
    flat_length: FloatArray
    speeds: FloatArray
    tolerance: FloatArray
    paths: tuple[FloatArray, ...]
    reaches: tuple[FloatArray, ...]
    radius: FloatArray

    def members(self, velocity: FloatArray) -> IntArray | None:
        """The catch speed (index into :attr:`speeds`, nearest speed) of the state
        pushed in each of :data:`FAN_DIRECTIONS` directions at flat-output
        ``velocity`` (..., 2), shape (..., FAN_DIRECTIONS); None when one of these
        states is faster or slower than every pushed catch's S holds."""
        a = 2.0 * np.pi * np.arange(FAN_DIRECTIONS) / FAN_DIRECTIONS
        push = self.speed_change * np.stack([np.cos(a), np.sin(a)], axis=-1)
        w = np.asarray(velocity, dtype=float)[..., None, :] + push
        speed = np.hypot(w[..., 0], w[..., 1])
        j = np.argmin(np.abs(self.speeds - speed[..., None]), axis=-1)
        if np.any(np.abs(self.speeds[j] - speed) > self.tolerance[j]):
            return None
        out: IntArray = j
        return out

    def turn(self, members: IntArray, dv: float) -> float:
        """Bound (m) on how far the discs of the catches ``members`` (a tick's, from
        :meth:`members`) move when the velocity changes by ``dv`` (m/s) with the same
        catches: a disc at r from the catch's start turns with the pushed velocity w,
        by at most dv / |w| rad, and |w| is at least the catch's speed less its S's
        velocity radius; never more than 2 r."""
        r = self.radius[members]
        slowest = np.maximum(self.speeds[members] - self.tolerance[members], 1e-9)
        return float(np.max(np.minimum(2.0 * r, r * dv / slowest)))

    def samples_along(
        self, positions: FloatArray, velocities: FloatArray, members: IntArray
    ) -> tuple[FloatArray, FloatArray]:
        """Discs (centres (K, 2), radii (K,)) of the catches of every state the design
        push leaves at flat-output ``positions`` (n, 2) moving at ``velocities`` (n, 2),
        pushed in each of :data:`FAN_DIRECTIONS` directions, whose catches ``members``
        (n, :data:`FAN_DIRECTIONS`) (:meth:`members`) are known: each catch's path
        turned to the pushed velocity's heading and moved to the state's position,
        state by state, direction by direction."""
        a = [2.0 * math.pi * k / FAN_DIRECTIONS for k in range(FAN_DIRECTIONS)]
        push = self.speed_change * np.array([[math.cos(v), math.sin(v)] for v in a])
        w = velocities[:, None, :] + push  # (n, K, 2)
        speed = np.hypot(w[..., 0], w[..., 1])
        h = np.where(speed > 1e-9, np.arctan2(w[..., 1], w[..., 0]), 0.0)
        c, s = np.cos(h).ravel(), np.sin(h).ravel()
        j = members.ravel()
        sizes = np.array([p.shape[0] for p in self.paths], dtype=np.int64)[j]
        start = np.cumsum(sizes) - sizes
        centres = np.empty((int(sizes.sum()), 2))
        radii = np.empty(int(sizes.sum()))
        origin = np.repeat(positions, FAN_DIRECTIONS, axis=0)
        for speed_index in np.unique(j):
            blocks = np.flatnonzero(j == speed_index)
            path = self.paths[speed_index]
            n = path.shape[0]
            # path @ [[c, s], [-s, c]] for every block of this speed at once
            px, py = path[:, 0], path[:, 1]
            cx = px[None, :] * c[blocks, None] - py[None, :] * s[blocks, None]
            cy = px[None, :] * s[blocks, None] + py[None, :] * c[blocks, None]
            rows = (start[blocks, None] + np.arange(n)[None, :]).ravel()
            centres[rows, 0] = (origin[blocks, 0, None] + cx).ravel()
            centres[rows, 1] = (origin[blocks, 1, None] + cy).ravel()
            radii[rows] = np.tile(self.reaches[speed_index], blocks.size)
        return centres, radii


def flat_speed_change(params: BallbotParams, impulse: float) -> float:
    """The flat output's velocity change (m/s) that a push of ``impulse`` (N s) on the
    body makes, along the push: the 3D model pushed at upright rest, read right after.

    By momentum alone the centre of mass gains J / M (M the body's and the ball's mass
    together: 0.296 m/s for 16 N s on the CMU ballbot); the flat output x + L φ, whose
    L weighs the lean rate the push starts, gains 3.7 % more (0.307 m/s). The change is
    linear in J and the same at any speed and, within 1 %, at the maneuvers' leans
    (``tests/test_push_fan.py``).
    """
    from gracenav.policies import flat_position_state
    from gracenav.sim import Model3DPlant, position_state

    plant = Model3DPlant(params)
    plant.reset(np.zeros(8))
    plant.push(np.array([float(impulse), 0.0]))
    x = plant.state()
    flat = flat_position_state(position_state(x, params.ball_radius), x[2:4], x[6:8], params)
    return float(flat[2])


def _flat_velocity(prim: Any, flat_length: FloatArray) -> FloatArray:
    """The flat output's velocity (T+1, 2) along a primitive's reference: the ball's
    plus L times the lean rate, per axis."""
    vel: FloatArray = prim.position[:, 2:4] + flat_length * prim.states[:, 6:8]
    return vel


def fastest_flat_speed(palette: Palette) -> float:
    """The largest speed (m/s) of the flat output along any of ``palette``'s policies'
    references (the speed :func:`_with_fan` compares with a fan's floor)."""
    length = flat_output_lengths(palette.params)
    top = 0.0
    for pol in palette.policies:
        vel = _flat_velocity(pol.primitive, length)
        top = max(top, float(np.max(np.hypot(vel[:, 0], vel[:, 1]), initial=0.0)))
    return top


def push_fan(palette: Palette, impulse: float, step: float) -> PushFan | None:
    """The push fan of a design push of ``impulse`` (N s) for ``palette``, its catches'
    discs at most ``step`` (m) apart; None for no push, and for a palette whose
    references' flat output never exceeds :data:`FAN_FLOOR` (the fan would check
    nothing: the shipped palette).

    The pushed catches' S hold the flat output's state, whose velocity the push
    changes by :func:`flat_speed_change`.

    Raises
    ------
    ConfigError
        If ``impulse`` > 0, some reference is faster than the floor and the palette has
        no pushed catches.
    """
    if impulse <= 0.0 or fastest_flat_speed(palette) <= FAN_FLOOR + 1e-9:
        return None
    pushed = [c for c in palette.catches if lean_class_of(c) == PUSHED]
    if not pushed:
        raise ConfigError(
            "a design push needs a palette with pushed catches; build it with "
            "`gracenav palette build` (catches on), or set design_push (planner.design_push) "
            "to 0"
        )
    opts = palette.options.catch
    slack = palette.d / (opts.grid_divisions if opts is not None else 1)
    by_speed: dict[float, list[MotionPolicy]] = {}
    for c in pushed:
        by_speed.setdefault(round(float(c.primitive.start_velocity[0]), 9), []).append(c)
    speeds = sorted(by_speed)
    paths, reaches, tolerance = [], [], []
    for v in speeds:
        discs = [swept_discs(c, step) for c in by_speed[v]]
        paths.append(np.concatenate([d[0] for d in discs]))
        reaches.append(np.concatenate([d[1] for d in discs]) + slack)
        # The narrowest S of this speed: the one the fan's state must lie in.
        tolerance.append(min(c.start_radii.velocity for c in by_speed[v]))
    return PushFan(
        impulse=float(impulse),
        speed_change=flat_speed_change(palette.params, float(impulse)),
        above=FAN_FLOOR,
        flat_length=flat_output_lengths(palette.params),
        speeds=np.array(speeds),
        tolerance=np.array(tolerance),
        paths=tuple(paths),
        reaches=tuple(reaches),
        radius=np.array([float(np.max(np.hypot(*p.T))) for p in paths]),
    )


def _sweep(
    policy: MotionPolicy,
    step: float,
    samples: tuple[FloatArray, FloatArray, IntArray] | None = None,
    speed_clearance: float = 0.0,
    fan: PushFan | None = None,
) -> _Sweep:
    """Select samples of the reference path (led by half the stopping allowance times
    the velocity) at most ``step`` of arc (plus one tick) apart and the conservative
    reach of D' around each, plus half the allowance ``speed_clearance`` (s) times the
    reference speed (see :func:`build_library`). ``samples``: :func:`sweep_samples`
    of the policy's primitive with that lead, if already computed. With ``fan``, the
    discs of the catches of the design push (:meth:`PushFan.samples_along`) where the flat
    output is faster than ``fan.above`` are checked too (:func:`_with_fan`); a policy
    with a pushed state that no catch holds gets an infinite reach (it is placed
    nowhere)."""
    prim = policy.primitive
    half = 0.5 * speed_clearance
    pos, cum, sel = samples if samples is not None else sweep_samples(policy, step, half)
    outer, _ = policy.outer_extents(sel * prim.dt)
    speed = np.hypot(prim.position[:, 2], prim.position[:, 3])
    reach = outer + half * speed[sel]
    if sel.size > 1:
        # The fastest tick from one sample to the next, both included.
        seg_speed = np.maximum(np.maximum.reduceat(speed, sel)[:-1], speed[sel[1:]])
        seg_reach = np.maximum(outer[:-1], outer[1:]) + half * seg_speed + 0.5 * np.diff(cum[sel])
        reach[:-1] = np.maximum(reach[:-1], seg_reach)
        reach[1:] = np.maximum(reach[1:], seg_reach)
    offsets = pos[sel]
    if fan is not None:
        offsets, reach = _with_fan(prim, sel, offsets, reach, fan)
    centres, greach, first, size = _bounding_discs(offsets, reach)
    total = float(np.max(np.hypot(*offsets.T) + reach))
    scentres, sreach, sfirst, ssize = _bounding_discs(centres, greach)
    return _Sweep(
        offsets, reach, centres, greach, first, size, total, scentres, sreach, sfirst, ssize
    )


def _bounding_discs(
    centres: FloatArray, reach: FloatArray
) -> tuple[FloatArray, FloatArray, IntArray, IntArray]:
    """Discs bounding each run of :data:`_GROUP` consecutive discs (``centres``,
    ``reach``): (centres, reach, first disc, discs). A bounding disc's centre is the
    middle of its discs' centres' box, its reach the farthest any of them reaches from
    there, so a point whose clearance exceeds it (clearance is 1-Lipschitz) clears
    every disc it bounds."""
    first = np.arange(0, centres.shape[0], _GROUP, dtype=np.int64)
    size = np.minimum(_GROUP, centres.shape[0] - first)
    mid = 0.5 * (
        np.minimum.reduceat(centres, first, axis=0) + np.maximum.reduceat(centres, first, axis=0)
    )
    own = np.repeat(np.arange(first.size), size)
    bound = np.maximum.reduceat(np.hypot(*(centres - mid[own]).T) + reach, first)
    return mid, bound, first, size


def _with_fan(
    prim: Any, sel: IntArray, offsets: FloatArray, reach: FloatArray, fan: PushFan
) -> tuple[FloatArray, FloatArray]:
    """``offsets`` and ``reach`` with the push fan's discs appended (see :func:`_sweep`),
    at the reference's flat output, which the pushed catches' S hold.

    The walk along the reference's fast ticks (every :data:`_FAN_STRIDE` ticks) checks
    a state, then the next one whose catches differ or whose discs may have moved more
    than :data:`FAN_GAP` from the checked one's (the flat output's displacement plus
    :meth:`PushFan.turn`); every disc is grown by :data:`FAN_GAP` and by the most the
    discs move within a stride, so the states between checked ones are covered too.
    """
    ref = prim.position[:, :2] - prim.position[0, :2] + fan.flat_length * prim.states[:, 2:4]
    vel = _flat_velocity(prim, fan.flat_length)
    fast = np.flatnonzero(np.hypot(vel[:, 0], vel[:, 1]) > fan.above + 1e-9)
    if fast.size == 0:
        return offsets, reach
    ticks = fast[::_FAN_STRIDE]
    members = fan.members(vel[ticks])
    if members is None:
        return offsets, np.full(reach.shape, np.inf)
    # Within a stride (and across a gap in the fast ticks, which only shortens it) the
    # discs move by at most the flat output's path plus the turn of its velocity.
    span = min(_FAN_STRIDE, int(fast[-1] - fast[0]) + 1)
    step_move = float(
        np.max(np.hypot(*np.diff(ref[fast[0] : fast[-1] + 1], axis=0).T), initial=0.0)
    )
    step_dv = float(np.max(np.hypot(*np.diff(vel[fast[0] : fast[-1] + 1], axis=0).T), initial=0.0))
    grow = FAN_GAP + span * step_move + fan.turn(np.unique(members), span * step_dv)
    picked = _pick_fan_states(
        np.ascontiguousarray(ref[ticks]),
        np.ascontiguousarray(vel[ticks]),
        np.ascontiguousarray(members, dtype=np.int64),
        fan.radius,
        np.maximum(fan.speeds - fan.tolerance, 1e-9),
        FAN_GAP,
    )
    centres, radii = fan.samples_along(ref[ticks[picked]], vel[ticks[picked]], members[picked])
    return np.concatenate([offsets, centres]), np.concatenate([reach, radii + grow])


@njit(cache=True)
def _pick_fan_states(
    ref: FloatArray,
    vel: FloatArray,
    members: IntArray,
    radius: FloatArray,
    slowest: FloatArray,
    gap: float,
) -> IntArray:
    """The walk of :func:`_with_fan`: indices of the states (rows of ``ref``, ``vel``,
    ``members``) checked, the first and then each whose catches differ from the last
    checked one's or whose discs may have moved more than ``gap`` from them (the flat
    output's displacement plus :meth:`PushFan.turn`, with the catches' ``radius`` and
    ``slowest`` speeds)."""
    n, k = members.shape
    picked = np.empty(n, dtype=np.int64)
    picked[0] = 0
    count = 1
    for i in range(1, n):
        p = picked[count - 1]
        moved = np.hypot(ref[i, 0] - ref[p, 0], ref[i, 1] - ref[p, 1])
        dv = np.hypot(vel[i, 0] - vel[p, 0], vel[i, 1] - vel[p, 1])
        differ = False
        turn = 0.0
        for m in range(k):
            if members[i, m] != members[p, m]:
                differ = True
            r = radius[members[p, m]]
            turn = max(turn, min(2.0 * r, r * dv / slowest[members[p, m]]))
        if differ or moved + turn > gap:
            picked[count] = i
            count += 1
    return picked[:count]


def _check_sweeps(
    world_map: WorldMap,
    points: FloatArray,
    pair_type: IntArray,
    pair_point: IntArray,
    tables: dict[str, NDArray[Any]],
    footprint: float,
) -> BoolArray:
    """Validity of undecided (type, point) pairs: the discs bounding groups of groups
    first, then the group discs where one is not clear, then the samples where a group
    disc is not clear; a type's group that failed last is checked first at the next
    pair (neighbouring points tend to fail at the same place; the verdicts do not
    depend on the order). Compiled; the clearance is computed as
    :meth:`gracenav.world.WorldMap.clearance` computes it, operation for operation."""
    valid = np.ones(pair_type.size, dtype=bool)
    if pair_type.size == 0:
        return valid
    grid, floor = _map_grid(world_map)
    hint = np.full(tables["type_super_first"].size, -1, dtype=np.int64)
    supers = tuple(
        tables[k]
        for k in (
            "type_super_first",
            "type_super_count",
            "super_centre",
            "super_reach",
            "super_group_first",
            "super_size",
        )
    )
    groups = tuple(
        tables[k]
        for k in (
            "group_centre",
            "group_reach",
            "group_sample_first",
            "group_size",
            "sample_offset",
            "sample_reach",
        )
    )
    _check_sweeps_kernel(
        valid,
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(pair_type, dtype=np.int64),
        np.ascontiguousarray(pair_point, dtype=np.int64),
        supers,
        groups,
        hint,
        float(footprint),
        grid,
        floor,
    )
    return valid


def _map_grid(world_map: WorldMap) -> tuple[tuple[Any, ...], FloatArray]:
    """The map as the compiled check reads it: the grid (nearest occupied cells,
    occupancy, origin, resolution and bounds: the arguments of :func:`_clearance_at`
    after the point) and its :func:`_clearance_floor`, computed once per map and kept
    with its clearance data (8 bytes a cell, counted in the memory budget's
    ``MAP_CELL_BYTES``)."""
    _, nearest = world_map._clearance_data()
    (x0, y0), (x1, y1) = world_map.bounds
    grid = (
        nearest,
        np.ascontiguousarray(world_map.occupied, dtype=np.bool_),
        float(world_map.origin[0]),
        float(world_map.origin[1]),
        float(world_map.resolution),
        float(x0),
        float(y0),
        float(x1),
        float(y1),
    )
    floor = world_map._cache.get("clearance_floor")
    if floor is None:
        floor = world_map._cache["clearance_floor"] = _clearance_floor(*grid)
        floor.setflags(write=False)
    return grid, floor


@njit(cache=True, nogil=True)
def _clearance_at(
    px: float,
    py: float,
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> float:
    """:meth:`gracenav.world.WorldMap.clearance` of one point, the same operations in
    the same order (so the same value). ``_check_sweeps`` passes the arguments after
    the point as one tuple, the grid."""
    ny, nx = occupied.shape
    fx = np.floor((px - ox) / res)
    fy = np.floor((py - oy) / res)
    if not (fx >= 0 and fx < nx and fy >= 0 and fy < ny):
        return 0.0
    iy = int(fy)
    ix = int(fx)
    if occupied[iy, ix]:
        return 0.0
    ky = int(np.floor((py - oy) / res - 0.5)) + 1
    kx = int(np.floor((px - ox) / res - 0.5)) + 1
    best = _nearest_squares(nearest, ky, kx, ox, oy, res, px, px, py, py)
    edge = min(min(px - xmin, xmax - px), min(py - ymin, ymax - py))
    return max(min(best, edge), 0.0)


@njit(cache=True, nogil=True)
def _nearest_squares(
    nearest: Any,
    ky: int,
    kx: int,
    ox: float,
    oy: float,
    res: float,
    x0: float,
    x1: float,
    y0: float,
    y1: float,
) -> float:
    """Distance from the rectangle [x0, x1] × [y0, y1] (a point when x0 = x1, y0 = y1)
    to the nearest of the occupied squares nearest to the four cell centres around
    index (ky, kx) of ``nearest`` (with a point, the operations of
    :meth:`gracenav.world.WorldMap.clearance`)."""
    best = np.inf
    for k in range(4):
        dyk = k >> 1
        dxk = k & 1
        jy = nearest[0, ky + dyk, kx + dxk] - 1
        jx = nearest[1, ky + dyk, kx + dxk] - 1
        bx0 = ox + jx * res
        by0 = oy + jy * res
        dx = max(max(bx0 - x1, x0 - (bx0 + res)), 0.0)
        dy = max(max(by0 - y1, y0 - (by0 + res)), 0.0)
        best = min(best, np.hypot(dx, dy))
    return best


#: What :func:`_clearance_floor` takes off its bounds (m): far more than the rounding of
#: the clearance's own arithmetic (about 1e-15 m), so a bound never exceeds a value.
_FLOOR_SLACK = 1e-9


@njit(cache=True)
def _clearance_floor(
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> FloatArray:
    """A lower bound on :func:`_clearance_at` over each cell of the half-cell-shifted
    grid whose four surrounding cell centres (and so whose four nearest occupied cells)
    it shares, shape (ny + 1, nx + 1), indexed as :func:`_clearance_at` indexes
    ``nearest`` (row ``floor((y - oy) / res - 0.5) + 1``): the distance from that
    rectangle to the nearest of the four occupied cells' squares or to the map edge,
    less :data:`_FLOOR_SLACK`; 0 where the rectangle reaches outside the grid."""
    ny, nx = occupied.shape
    out = np.empty((ny + 1, nx + 1))
    for ky in range(ny + 1):
        ry0 = oy + (ky - 0.5) * res
        ry1 = oy + (ky + 0.5) * res
        for kx in range(nx + 1):
            rx0 = ox + (kx - 0.5) * res
            rx1 = ox + (kx + 0.5) * res
            if ky == 0 or kx == 0 or ky == ny or kx == nx:
                out[ky, kx] = 0.0  # part of the rectangle lies off the grid: clearance 0
                continue
            best = _nearest_squares(nearest, ky, kx, ox, oy, res, rx0, rx1, ry0, ry1)
            edge = min(min(rx0 - xmin, xmax - rx1), min(ry0 - ymin, ymax - ry1))
            out[ky, kx] = max(min(best, edge), 0.0) - _FLOOR_SLACK
    return out


@njit(cache=True, nogil=True)
def _disc_clear(px: float, py: float, need: float, floor: Any, grid: Any) -> bool:
    """Whether :func:`_clearance_at` at (px, py) is at least ``need``: decided by the
    point's cell of :func:`_clearance_floor` when that bound reaches ``need`` (the same
    verdict, without the four nearest cells), else by the clearance itself."""
    oy = grid[3]
    ox = grid[2]
    res = grid[4]
    ky = np.floor((py - oy) / res - 0.5) + 1
    kx = np.floor((px - ox) / res - 0.5) + 1
    if ky >= 0 and ky < floor.shape[0] and kx >= 0 and kx < floor.shape[1]:
        if floor[int(ky), int(kx)] >= need:
            return True
    return _clearance_at(px, py, *grid) >= need


@njit(cache=True, nogil=True)
def _group_clear(
    g: int, qx: float, qy: float, footprint: float, groups: Any, grid: Any, floor: Any
) -> bool:
    """Whether group ``g`` of the swept samples is clear at (qx, qy): its disc, or else
    every sample (``groups``: the group and sample tables, ``grid``: the map's, as
    :func:`_check_sweeps` packs them; ``floor``: :func:`_clearance_floor`)."""
    centre, reach, sample_first, size, sample_offset, sample_reach = groups
    if _disc_clear(qx + centre[g, 0], qy + centre[g, 1], footprint + reach[g], floor, grid):
        return True
    for k in range(sample_first[g], sample_first[g] + size[g]):
        if not _disc_clear(
            qx + sample_offset[k, 0],
            qy + sample_offset[k, 1],
            footprint + sample_reach[k],
            floor,
            grid,
        ):
            return False
    return True


@njit(cache=True, nogil=True, parallel=True)
def _check_sweeps_kernel(
    valid: Any,
    points: Any,
    pair_type: Any,
    pair_point: Any,
    supers: Any,
    groups: Any,
    hint: Any,
    footprint: float,
    grid: Any,
    floor: Any,
) -> None:
    """Mark the pairs whose swept D' is not clear: a pair is valid iff in every group
    of groups either its bounding disc or, in every group, the group's disc or every
    sample is clear (see :func:`build_library`). ``hint[t]``: the group at which type
    t failed last (-1: none), checked first, behind its group of groups' disc as in the
    full check; threads write it without order, which changes only how soon a failing
    pair is found, never the verdict. ``floor``: :func:`_clearance_floor`, which decides
    a disc at one look-up when the map leaves it room to spare."""
    type_first, type_count, centre, reach, group_first, size = supers
    for a in prange(pair_type.size):  # independent pairs: the hints are only hints
        t = pair_type[a]
        qx = points[pair_point[a], 0]
        qy = points[pair_point[a], 1]
        h = hint[t]
        bad = False
        if h >= 0:
            # The hinted group as the loop below would reach it: within its group of
            # groups (runs of _GROUP from the type's first group), only when that
            # group's disc is not clear, so the verdict never depends on the hint.
            s0 = type_first[t]
            sh = s0 + (h - group_first[s0]) // _GROUP
            near = not _disc_clear(
                qx + centre[sh, 0], qy + centre[sh, 1], footprint + reach[sh], floor, grid
            )
            bad = near and not _group_clear(h, qx, qy, footprint, groups, grid, floor)
        for sg in range(type_first[t], type_first[t] + type_count[t]):
            if bad:
                break
            if _disc_clear(
                qx + centre[sg, 0], qy + centre[sg, 1], footprint + reach[sg], floor, grid
            ):
                continue
            for g in range(group_first[sg], group_first[sg] + size[sg]):
                if g != h and not _group_clear(g, qx, qy, footprint, groups, grid, floor):
                    bad = True
                    hint[t] = g
                    break
        valid[a] = not bad


def _sweep_tables(sweeps: list[_Sweep]) -> dict[str, NDArray[Any]]:
    """Concatenate the sweeps of every type (rotated) into flat tables."""
    gc, gr, gsf, gsz, total = [], [], [], [], []
    sc, sr, sgf, ssz, tsf, tsc = [], [], [], [], [], []
    n_samples = n_groups = n_supers = 0
    # The samples (most of the tables: millions with a design push) are written in
    # place, rotated, rather than rotated into copies and concatenated.
    size = ORIENTATIONS * sum(sw.offsets.shape[0] for sw in sweeps)
    sample_offset = np.empty((size, 2))
    sample_reach = np.empty(size)
    for sw in sweeps:
        for k in range(ORIENTATIONS):
            sc.append(_rotate(sw.super_centre, k))
            sr.append(sw.super_reach)
            sgf.append(sw.super_first + n_groups)
            ssz.append(sw.super_size)
            tsf.append(n_supers)
            tsc.append(sw.super_first.size)
            n_supers += sw.super_first.size
            rows = slice(n_samples, n_samples + sw.offsets.shape[0])
            rotate_pairs(sw.offsets, k, out=sample_offset[rows])
            sample_reach[rows] = sw.reach
            gc.append(_rotate(sw.group_centre, k))
            gr.append(sw.group_reach)
            gsf.append(sw.group_first + n_samples)
            gsz.append(sw.group_size)
            total.append(sw.total_reach)
            n_samples += sw.offsets.shape[0]
            n_groups += sw.group_first.size
    return {
        "sample_offset": sample_offset,
        "sample_reach": sample_reach,
        # What the start point's own clearance must exceed (the first sample leads it by
        # half the allowance times the start velocity; clearance is 1-Lipschitz).
        "sample_first_reach": np.array(
            [sw.reach[0] - math.hypot(*sw.offsets[0]) for sw in sweeps for _ in range(4)]
        ),
        "group_centre": np.concatenate(gc),
        "group_reach": np.concatenate(gr),
        "group_sample_first": np.concatenate(gsf).astype(np.int64),
        "group_size": np.concatenate(gsz).astype(np.int64),
        "super_centre": np.concatenate(sc),
        "super_reach": np.concatenate(sr),
        "super_group_first": np.concatenate(sgf).astype(np.int64),
        "super_size": np.concatenate(ssz).astype(np.int64),
        "type_super_first": np.array(tsf, dtype=np.int64),
        "type_super_count": np.array(tsc, dtype=np.int64),
        "type_total_reach": np.array(total),
    }
