"""The push fan: the catches a design push calls for where a reference moves fast.

Wherever the flat output of a policy's reference is faster than :data:`FAN_FLOOR`, each
state a push of the design impulse leaves (in :data:`FAN_DIRECTIONS` directions) must
have room for the pushed catch that holds it. :class:`PushFan` gives those catches'
discs, which :func:`gracenav.library.sweeps.sweep` adds to a policy's sweep samples
(:meth:`PushFan.with_discs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from gracenav.errors import ConfigError
from gracenav.library.sweeps import swept_discs
from gracenav.library.types import FloatArray, IntArray
from gracenav.palette import Palette
from gracenav.policies import MotionPolicy
from gracenav.policies.catches import PUSHED, lean_class_of
from gracenav.primitives.references import flat_output_lengths

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
]

#: Directions of the design push a push fan checks, evenly spaced over the full turn.
FAN_DIRECTIONS = 8

#: Largest displacement (m) of a push fan's catch discs from a checked state to the
#: states after it that are not checked (see :meth:`PushFan.with_discs`): every disc is grown
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

    def with_discs(
        self, prim: Any, offsets: FloatArray, reach: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """``offsets`` and ``reach`` with the push fan's discs appended (see
        :func:`gracenav.library.sweeps.sweep`, which passes a policy's primitive ``prim``),
        at the reference's flat output, which the pushed catches' S hold.

        The walk along the reference's fast ticks (every :data:`_FAN_STRIDE` ticks) checks
        a state, then the next one whose catches differ or whose discs may have moved more
        than :data:`FAN_GAP` from the checked one's (the flat output's displacement plus
        :meth:`PushFan.turn`); every disc is grown by :data:`FAN_GAP` and by the most the
        discs move within a stride, so the states between checked ones are covered too.
        """
        ref = prim.position[:, :2] - prim.position[0, :2] + self.flat_length * prim.states[:, 2:4]
        vel = _flat_velocity(prim, self.flat_length)
        fast = np.flatnonzero(np.hypot(vel[:, 0], vel[:, 1]) > self.above + 1e-9)
        if fast.size == 0:
            return offsets, reach
        ticks = fast[::_FAN_STRIDE]
        members = self.members(vel[ticks])
        if members is None:
            return offsets, np.full(reach.shape, np.inf)
        # Within a stride (and across a gap in the fast ticks, which only shortens it) the
        # discs move by at most the flat output's path plus the turn of its velocity.
        span = min(_FAN_STRIDE, int(fast[-1] - fast[0]) + 1)
        step_move = float(
            np.max(np.hypot(*np.diff(ref[fast[0] : fast[-1] + 1], axis=0).T), initial=0.0)
        )
        step_dv = float(
            np.max(np.hypot(*np.diff(vel[fast[0] : fast[-1] + 1], axis=0).T), initial=0.0)
        )
        grow = FAN_GAP + span * step_move + self.turn(np.unique(members), span * step_dv)
        picked = _pick_fan_states(
            np.ascontiguousarray(ref[ticks]),
            np.ascontiguousarray(vel[ticks]),
            np.ascontiguousarray(members, dtype=np.int64),
            self.radius,
            np.maximum(self.speeds - self.tolerance, 1e-9),
            FAN_GAP,
        )
        centres, radii = self.samples_along(ref[ticks[picked]], vel[ticks[picked]], members[picked])
        return np.concatenate([offsets, centres]), np.concatenate([reach, radii + grow])


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
    references (the speed :meth:`PushFan.with_discs` compares with a fan's floor)."""
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


@njit(cache=True)
def _pick_fan_states(
    ref: FloatArray,
    vel: FloatArray,
    members: IntArray,
    radius: FloatArray,
    slowest: FloatArray,
    gap: float,
) -> IntArray:
    """The walk of :meth:`PushFan.with_discs`: indices of the states (rows of ``ref``, ``vel``,
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
