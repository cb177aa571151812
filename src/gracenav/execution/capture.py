"""Capture at the robot's own state: catches and shifts placed on a library.

A push can leave the robot in a moving state outside every start domain S of the
library. The palette's catches and shifts (:mod:`gracenav.policies.catches`, which designs
and verifies them) are placed where the robot is instead: a catch is turned near the
robot's heading and moved so that it ends on a fine grid (spacing d /
``grid_divisions``, anchored where the library's lattice is); of the headings that
end it there, the one whose S best holds the state is used. Shifts between grid
points then bring the robot onto a lattice rest trim of the library: catch ⪰ shift
⪰ rest trim. A still catch hands over to either kind of shift; the others only to
plain ones.

:class:`Capture` plans, for one library, the catch, shift and rest trim that take a
state to the goal at least cost, checking each swept D' grown by the footprint
against the map as instantiation does; :func:`capture_for` keeps one per library.
The same shifts, run the other way round (from a rest trim's end to a grid point
next to a goal at rest off the lattice), give goals a verified end where no capture
regulator fits (:class:`ShiftTerminal`, :meth:`Capture.shift_terminals`).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.library import PolicyLibrary, swept_discs
from gracenav.policies import (
    CatchOptions,
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
    rotate_pairs_by,
)
from gracenav.policies.catches import PUSHED, SETTLED, STILL, lean_class_of
from gracenav.policies.domains import EllipsoidalDomain
from gracenav.policies.placement import instantiated_reference
from gracenav.sim import Reference

if TYPE_CHECKING:
    from gracenav.palette import Palette

__all__ = [
    "Capture",
    "CapturePlan",
    "PlacedPolicy",
    "ShiftTerminal",
    "Terminal",
    "TerminalPolicy",
    "capture_for",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

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
#: Grid points next to a goal a shift terminal may end on: within this many grid
#: spacings of the goal (the nearest first).
_TERMINAL_REACH = 1.0


#: Grid points (i, j) are looked up in bulk as one integer each (:func:`_cell_codes`);
#: indices within this many of 0 are coded exactly (a 2**29-point-wide map).
_CELL_OFFSET = 1 << 29


def _cell_codes(cells: NDArray[np.int64]) -> NDArray[np.int64]:
    """One integer per grid point (i, j) of ``cells``, shape (..., 2), equal only for
    equal points (for |i|, |j| < ``_CELL_OFFSET``)."""
    c = np.asarray(cells, dtype=np.int64) + _CELL_OFFSET
    return np.asarray(c[..., 0] * (2 * _CELL_OFFSET) + c[..., 1], dtype=np.int64)


def _has_cells(codes: NDArray[np.int64], cells: NDArray[np.int64]) -> BoolArray:
    """Whether each grid point of ``cells`` (shape (..., 2)) is among the sorted
    ``codes`` (:func:`_cell_codes`)."""
    want = _cell_codes(cells)
    if codes.size == 0:
        return np.zeros(want.shape, dtype=bool)
    at = np.minimum(np.searchsorted(codes, want), codes.size - 1)
    return np.asarray(codes[at] == want, dtype=bool)


def _remember(
    cache: dict[tuple[int, int, bool], list[_Way]], key: tuple[int, int, bool], ways: list[_Way]
) -> None:
    if len(cache) >= _HANDOVER_CACHE:  # a long run on a large map
        cache.clear()
    cache[key] = ways


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
        return instantiated_reference(self.primitive, None, self.start_xy, radius)

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


#: Each library's capture planner (:func:`capture_for`), kept as long as the library
#: lives. A planner holds its library weakly, so it does not keep its own key alive.
_PLANNERS: weakref.WeakKeyDictionary[PolicyLibrary, Capture] = weakref.WeakKeyDictionary()


def _holds_catch_goals(palette: Palette) -> NDArray[np.bool_]:
    """Per palette policy, whether its S holds the G of every catch and shift of the
    palette placed at its own start (concentric, exact ellipsoid containment)."""
    mats = [p.goal_domain.shape_matrix for p in (*palette.catches, *palette.shifts)]
    if not mats:
        return np.ones(len(palette.policies), dtype=bool)
    goals = np.unique(np.array(mats).reshape(len(mats), -1), axis=0).reshape(-1, 4, 4)
    out = np.zeros(len(palette.policies), dtype=bool)
    for i, pol in enumerate(palette.policies):
        start = pol.start_domain
        out[i] = all(
            start.contains_domain(EllipsoidalDomain(start.center, g), tol=1e-9) for g in goals
        )
    return out


def capture_for(library: PolicyLibrary) -> Capture:
    """The library's capture planner: built on first use, then reused.

    Parameters
    ----------
    library : PolicyLibrary

    Returns
    -------
    Capture
        The same planner for every call on ``library`` as long as the library lives
        (its remembered ways onto rest trims are shared by every controller on it).
    """
    got = _PLANNERS.get(library)
    if got is None:
        got = _PLANNERS[library] = Capture(library)
    return got


class Capture:
    """Plans captures (catch, shift, rest trim) on one library.

    Parameters
    ----------
    library : PolicyLibrary
        Its palette's catches and shifts are placed on its map, with its footprint;
        its rest trims are where captures end. The planner keeps what it needs of it
        and holds the library itself weakly (see :attr:`library`).
    """

    def __init__(self, library: PolicyLibrary) -> None:
        self._library = weakref.ref(library)
        self.world_map = library.world_map
        self.footprint_radius = library.footprint_radius
        palette = library.palette
        opts = palette.options.catch
        self.options = opts
        self.grid = palette.d / (opts.grid_divisions if opts is not None else 1)
        self.origin = np.asarray(library.origin, dtype=float)
        self.sweep_step = min(float(library.sweep_step), _SWEEP_STEP)
        members = []
        for pol in palette.catches:
            path, reach = self.swept(pol)
            members.append(
                _Member(
                    pol,
                    float(pol.primitive.start_velocity[0]),
                    float(pol.primitive.displacement[0]),
                    lean_class_of(pol),
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
            path, reach = self.swept(pol)
            for k in range(4):
                angle = 0.5 * math.pi * k
                c, s = math.cos(angle), math.sin(angle)
                shifts.append((pol, angle))
                paths.append(path @ np.array([[c, -s], [s, c]]).T)
                reaches.append(reach)
                still.append(lean_class_of(pol) == STILL)
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
        # The rest rows a catch or a shift may end on: their S holds every catch's and
        # shift's G (a fine copy's rest trim, of a smaller S, may not).
        holds = _holds_catch_goals(palette)
        self._rest_onto: dict[tuple[int, int], NDArray[np.int64]] = {}
        for key, rows in self._rest.items():
            ok = rows[holds[library.palette_index[rows]]]
            if ok.size:
                self._rest_onto[key] = ok
        # The same grid points as sorted codes, for lookups of many points at once.
        self._rest_codes = np.sort(
            _cell_codes(np.array(list(self._rest), dtype=np.int64).reshape(-1, 2))
        )
        self._onto_codes = np.sort(
            _cell_codes(np.array(list(self._rest_onto), dtype=np.int64).reshape(-1, 2))
        )
        self._direct_ways: dict[tuple[int, int, bool], list[_Way]] = {}
        self._chained: dict[tuple[int, int, bool], list[_Way]] = {}
        self._chained_every: dict[tuple[int, int, bool], list[_Way]] = {}
        self._arrival_ways: dict[tuple[int, int, bool], list[_Way]] = {}

    @property
    def library(self) -> PolicyLibrary:
        """The library it plans on.

        Raises
        ------
        ReferenceError
            If the library no longer exists (the planner holds it weakly).
        """
        library = self._library()
        if library is None:
            raise ReferenceError("the library of this capture planner no longer exists")
        return library

    @property
    def available(self) -> bool:
        """Whether the palette has catches to place."""
        return bool(self._members)

    @property
    def shifts_available(self) -> bool:
        """Whether the palette has plain shifts and a settled catch from rest, which
        shift terminals need (:meth:`shift_terminals`)."""
        return bool(np.any(~self._shift_still)) and self._settled_hold() is not None

    @property
    def shift_end_reach(self) -> float:
        """Clearance (m) beyond the footprint a plain shift's swept D' needs at its end,
        where a shift terminal holds the robot."""
        plain = ~self._shift_still
        return float(np.max(self._shift_reach[plain, -1])) if np.any(plain) else math.inf

    def swept(self, policy: MotionPolicy) -> tuple[FloatArray, FloatArray]:
        """Discs whose union holds ``policy``'s swept D' (policy frame, from its start;
        :func:`gracenav.library.swept_discs` at the captures' sample spacing)."""
        return swept_discs(policy, self.sweep_step)

    def clear(self, points: FloatArray, reach: FloatArray) -> BoolArray:
        """Whether each disc (centres ``points``, shape (..., 2); radii ``reach``) grown
        by the footprint lies in free space, shape ``points.shape[:-1]``."""
        world = self.world_map
        flat = points.reshape(-1, 2)
        ok = world.is_free(flat) & (
            world.clearance(flat)
            >= self.footprint_radius + np.broadcast_to(reach, points.shape[:-1]).reshape(-1)
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
        for row in self._rest_onto.get(cell, ()):
            out.append((0.0, (), int(row)))
        q = self.origin + np.asarray(cell, dtype=float) * self.grid
        ends = self._shift_cells + np.asarray(cell, dtype=np.int64)
        ks = np.flatnonzero(
            (still | ~self._shift_still) & _has_cells(self._onto_codes, ends.reshape(-1, 2))
        )
        if ks.size:
            clear = np.all(self.clear(q + self._shift_path[ks], self._shift_reach[ks]), axis=1)
            for k in ks[clear]:
                rows = self._rest_onto[(int(ends[k, 0]), int(ends[k, 1]))]
                out.extend((float(self._shift_time[k]), (int(k),), int(row)) for row in rows)
        _remember(self._direct_ways, key, out)
        return out

    def _handovers(self, cell: tuple[int, int], still: bool) -> list[_Way]:
        """(shifts' duration, shift indices, rest row) of the ways from grid point
        ``cell`` onto a rest trim: those of :meth:`_direct`; from a point where there
        are none (a catch ending too near a wall for a shift toward a rest trim, or in a
        passage without one), two shifts (:meth:`_chains`)."""
        out = self._direct(cell, still)
        if out:
            return out
        return self._chains(cell, still)

    def _chains(self, cell: tuple[int, int], still: bool, every: bool = False) -> list[_Way]:
        """Two-shift ways from grid point ``cell`` onto a rest trim: a first shift with a
        clear swept D' (a still one too after a ``still`` catch), then a plain one, whose
        S (``shift_scale`` G) holds the first one's G. The first shifts are tried from
        the one ending with the most clearance, until ``_CHAIN_FIRSTS`` of them have a
        way on or ``_CHAIN_TRIES`` have been tried (``every``: all ``_CHAIN_TRIES``,
        for a state whose nearer ways lead only to rest trims that do not reach the
        goal)."""
        key = (cell[0], cell[1], still)
        cache = self._chained_every if every else self._chained
        got = cache.get(key)
        if got is not None:
            return got
        q = self.origin + np.asarray(cell, dtype=float) * self.grid
        ks = np.flatnonzero(~self._shift_still | still)
        ks = ks[np.all(self.clear(q + self._shift_path[ks], self._shift_reach[ks]), axis=1)]
        ends = self._shift_cells[ks] + np.asarray(cell, dtype=np.int64)
        room = self.world_map.clearance(self.origin + ends * self.grid)
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
            if firsts >= _CHAIN_FIRSTS and not every:
                break
        chained = sorted(best.values())
        _remember(cache, key, chained)
        return chained

    # -- shifts onto a goal ------------------------------------------------------------
    def _arrivals(self, cell: tuple[int, int]) -> list[_Way]:
        """(shift duration, (shift index,), rest row) of every way onto grid point
        ``cell`` from the end of a library rest trim by one plain shift (its S holds the
        rest trim's G) with a clear swept D'."""
        key = (cell[0], cell[1], False)
        got = self._arrival_ways.get(key)
        if got is not None:
            return got
        out: list[_Way] = []
        plain = np.flatnonzero(~self._shift_still)
        starts = np.asarray(cell, dtype=np.int64) - self._shift_cells[plain]
        sel = np.flatnonzero(_has_cells(self._rest_codes, starts.reshape(-1, 2)))
        if sel.size:
            q = self.origin + starts[sel] * self.grid
            ks = plain[sel]
            clear = np.all(
                self.clear(q[:, None, :] + self._shift_path[ks], self._shift_reach[ks]), axis=1
            )
            for n in sel[clear]:
                rows = self._rest[(int(starts[n, 0]), int(starts[n, 1]))]
                k = int(plain[n])
                out.extend((float(self._shift_time[k]), (k,), int(row)) for row in rows)
        out.sort()
        _remember(self._arrival_ways, key, out)
        return out

    def _arrival_chains(self, cell: tuple[int, int]) -> list[_Way]:
        """Two-shift ways onto grid point ``cell`` from the end of a library rest trim:
        a plain shift onto a grid point from which a last plain shift with a clear
        swept D' reaches ``cell`` (its S holds the first one's G). The grid points are
        tried from the one with the most clearance, at most ``_CHAIN_TRIES`` of them."""
        key = (cell[0], cell[1], True)
        got = self._arrival_ways.get(key)
        if got is not None:
            return got
        plain = np.flatnonzero(~self._shift_still)
        starts = np.asarray(cell, dtype=np.int64) - self._shift_cells[plain]
        q = self.origin + starts * self.grid
        clear = np.all(
            self.clear(q[:, None, :] + self._shift_path[plain], self._shift_reach[plain]), axis=1
        )
        ks, starts, q = plain[clear], starts[clear], q[clear]
        room = self.world_map.clearance(q)
        best: dict[int, _Way] = {}
        for n in np.argsort(-room, kind="stable")[:_CHAIN_TRIES]:
            k = int(ks[n])
            for t1, ks1, row in self._arrivals((int(starts[n, 0]), int(starts[n, 1]))):
                way = (t1 + float(self._shift_time[k]), (*ks1, k), row)
                if row not in best or way[0] < best[row][0]:
                    best[row] = way
        out = sorted(best.values())
        _remember(self._arrival_ways, key, out)
        return out

    def _settled_hold(self) -> MotionPolicy | None:
        """The palette's settled catch from rest (a rest hold whose S is the palette's
        G), or None."""
        for m in self._members:
            if m.lean_class == SETTLED and m.speed == 0.0 and m.stop == 0.0:
                return m.policy
        return None

    def shift_terminals(self, goal: ArrayLike, *, every: bool = False) -> tuple[ShiftTerminal, ...]:
        """Shift terminals for a goal at rest (x, y, 0, 0), best first (empty if none
        fits); ``every``: the ways of one and of two shifts alike.

        The grid points within a grid spacing of the goal whose G (the palette's, at
        rest) contains it are tried, nearest first, until one has ways: plain shifts
        from the end of a library rest trim (one, else two, as captures hand over in
        the other direction) whose swept D' grown by the footprint is clear, then the
        palette's settled catch from rest held at the point (its D' clear too). Each
        way's containments are checked exactly: the rest trim's G in the first shift's
        S, each shift's G in the next one's S, the last one's G in the hold's S, and the
        goal in the hold's G. Ordered by the shifts' duration, then the rest trim's
        distance from the goal and duration."""
        g = np.asarray(goal, dtype=float).reshape(4)
        hold = self._settled_hold()
        opts = self.options
        if hold is None or opts is None or not self._shifts:
            return ()
        library = self.library
        base = np.round((g[:2] - self.origin) / self.grid).astype(np.int64)
        cells = base + _NEIGHBOURS
        xy = self.origin + cells * self.grid
        dist = np.hypot(*(xy - g[:2]).T)
        hold_path, hold_reach = self.swept(hold)
        at_goal = self._goal_regulator(g)
        for n in np.argsort(dist, kind="stable"):
            if dist[n] > _TERMINAL_REACH * self.grid + 1e-12:
                break
            cell = (int(cells[n, 0]), int(cells[n, 1]))
            end = PlacedPolicy(hold, 0.0, xy[n].copy())
            if not end.goal_domain.contains(g):
                continue
            if not np.all(self.clear(xy[n] + hold_path, hold_reach)):
                continue
            holds = [*at_goal, (end, (hold_path, hold_reach))]
            ways = (
                self._arrivals(cell) + self._arrival_chains(cell)
                if every
                else self._arrivals(cell) or self._arrival_chains(cell)
            )
            out = []
            for t, ks, row in ways:
                term = self._terminal_of(ks, row, holds, opts)
                if term is not None:
                    out.append((t, float(np.hypot(*(library.start_xy[row] - g[:2]))), term))
            if out:
                out.sort(
                    key=lambda c: (c[0], c[1], library.durations[c[2].approach], c[2].approach)
                )
                return tuple(c[2] for c in out)
        return ()

    def _goal_regulator(
        self, g: FloatArray
    ) -> list[tuple[PlacedPolicy, tuple[FloatArray, FloatArray]]]:
        """The smallest capture regulator of the palette placed at the goal ``g`` whose
        swept D' grown by the footprint is clear, with its swept discs (empty if none
        is): the hold of a shift terminal that brings the robot onto the goal itself
        rather than onto the grid point next to it, the reference stepping by at most
        the grid's half diagonal when it starts."""
        library = self.library
        regs = sorted(
            (p for p in library.palette.policies if p.capture),
            key=lambda p: p.start_radii.position,
        )
        for reg in regs:
            path, reach = self.swept(reg)
            if np.all(self.clear(g[:2] + path, reach)):
                return [(PlacedPolicy(reg, 0.0, g[:2].copy()), (path, reach))]
        return []

    def _terminal_of(
        self,
        ks: tuple[int, ...],
        row: int,
        holds: list[tuple[PlacedPolicy, tuple[FloatArray, FloatArray]]],
        opts: CatchOptions,
    ) -> ShiftTerminal | None:
        """The shift terminal of shifts ``ks`` from rest trim ``row``'s point to a
        hold, if every containment holds exactly. ``holds``: (hold, its swept discs),
        the regulator at the goal first (:meth:`_goal_regulator`), then the settled
        hold at the grid point the shifts end on; the first whose S holds the last
        shift's G is taken."""
        library = self.library
        at = np.round((library.start_xy[row] - self.origin) / self.grid).astype(np.int64)
        before = library.policy(int(row)).goal_domain
        shifts = []
        points = []
        reach = []
        for k in ks:
            pol, angle = self._shifts[k]
            placed = PlacedPolicy(pol, angle, self.origin + at * self.grid)
            if not placed.start_domain.contains_domain(before):
                return None
            shifts.append(placed)
            points.append(placed.start_xy + self._shift_path[k])
            reach.append(self._shift_reach[k])
            before = placed.goal_domain
            at = at + self._shift_cells[k]
        found = next((h for h in holds if h[0].start_domain.contains_domain(before)), None)
        if found is None:
            return None
        hold, hold_sweep = found
        points.append(hold.start_xy + hold_sweep[0])
        reach.append(hold_sweep[1])
        return ShiftTerminal(
            tuple(shifts),
            hold,
            int(row),
            np.ascontiguousarray(np.concatenate(points)),
            np.concatenate(reach),
            (float(opts.settled_lean[0]), float(opts.settled_lean[1])),
        )

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
            if not np.all(self.clear(start + m.path @ rot.T, m.reach)):
                continue
            still = m.lean_class == STILL
            ways = self._handovers(cell, still)
            if settle is not None and ways:
                settle(np.array(sorted({w[2] for w in ways}), dtype=np.int64))
            if cost_to_go is not None and not any(
                math.isfinite(float(cost_to_go[w[2]])) for w in ways
            ):
                # The nearer ways end only on rest trims that do not reach the goal (near
                # walls, where the stopping allowance leaves a rest trim no way out):
                # every two-shift way is read.
                more = self._chains(cell, still, every=True)
                if settle is not None and more:
                    settle(np.array(sorted({w[2] for w in more}), dtype=np.int64))
                ways = ways + more
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
        direct = None
        if STILL in classes and (cost_to_go is not None or chosen is None):
            direct = self._from_grid(st, cost_to_go, settle)
        if direct is not None and (best is None or direct[0] < best[0]):
            total, cell, ks, row = direct
            placed = self._placed_shifts(cell, ks)
            return CapturePlan(placed[0], tuple(placed[1:]), row, total)
        if chosen is None or best is None:
            return None
        m, heading, start, cell, ks, row = chosen
        catch = PlacedPolicy(m.policy, heading, np.asarray(start, dtype=float))
        return CapturePlan(catch, tuple(self._placed_shifts(cell, ks)), row, best[0])

    def _holding(
        self, ways: list[_Way], q: FloatArray, st: FloatArray, holds: dict[int, bool]
    ) -> list[_Way]:
        """The ways of at least one shift whose first shift, placed at grid point ``q``,
        holds ``st`` in its S (``holds`` remembers the verdict per shift)."""
        for _, ks, _ in ways:
            if ks and ks[0] not in holds:
                pol, angle = self._shifts[ks[0]]
                holds[ks[0]] = bool(PlacedPolicy(pol, angle, q).start_domain.contains(st))
        return [w for w in ways if w[1] and holds[w[1][0]]]

    def _placed_shifts(self, cell: tuple[int, int], ks: tuple[int, ...]) -> list[PlacedPolicy]:
        """The shifts ``ks`` placed one after the other from grid point ``cell``."""
        shifts = []
        at = np.asarray(cell, dtype=np.int64)
        for k in ks:
            pol, angle = self._shifts[k]
            shifts.append(PlacedPolicy(pol, angle, self.origin + at * self.grid))
            at = at + self._shift_cells[k]
        return shifts

    def _from_grid(
        self,
        st: FloatArray,
        cost_to_go: FloatArray | None,
        settle: Callable[[NDArray[np.int64]], None] | None,
    ) -> tuple[float, tuple[int, int], tuple[int, ...], int] | None:
        """The cheapest way onto a rest trim that starts with a shift whose S, placed
        at one of the grid points nearest the state, already holds it (a state at rest
        with the plan's lean, as a task's start: no catch is needed to reach the grid):
        (shifts' duration plus the rest trim's cost-to-go, grid point, shift indices,
        rest row), or None. Each shift's S holds the G before it and the rest trim's S
        the last G, as in every capture (the ways of :meth:`_handovers`); where none of
        those reaches the goal from a grid point, every two-shift way from it is read,
        as at a catch's end."""
        base = np.round((st[:2] - self.origin) / self.grid).astype(np.int64)
        best: tuple[float, tuple[int, int], tuple[int, ...], int] | None = None
        for offset in _NEIGHBOURS:
            cell = (int(base[0] + offset[0]), int(base[1] + offset[1]))
            q = self.origin + np.asarray(cell, dtype=float) * self.grid
            holds: dict[int, bool] = {}
            ways = self._holding(self._handovers(cell, True), q, st, holds)
            if settle is not None and ways:
                settle(np.array(sorted({w[2] for w in ways}), dtype=np.int64))
            if cost_to_go is not None and not any(
                math.isfinite(float(cost_to_go[w[2]])) for w in ways
            ):
                # As for a catch's end: every two-shift way is read.
                more = self._holding(self._chains(cell, True, every=True), q, st, holds)
                if settle is not None and more:
                    settle(np.array(sorted({w[2] for w in more}), dtype=np.int64))
                ways = ways + more
            for shift_t, ks, row in ways:
                togo = 0.0 if cost_to_go is None else float(cost_to_go[row])
                if not math.isfinite(togo):
                    continue
                total = shift_t + togo
                if best is None or total < best[0]:
                    best = (total, cell, ks, row)
        return best

    def covers(self, states: ArrayLike) -> BoolArray:
        """Whether a capture plan (with the plan lean: settled and still catches too)
        exists for each state (n, 4)."""
        pts = np.asarray(states, dtype=float).reshape(-1, 4)
        return np.array(
            [self.plan(s, lean_deviation=(0.0, 0.0)) is not None for s in pts], dtype=bool
        )


@dataclass(frozen=True)
class TerminalPolicy(PlacedPolicy):
    """A capture regulator of the palette placed at a goal off the lattice: a
    :class:`~gracenav.execution.capture.PlacedPolicy` at heading 0 whose reference starts (and
    holds) at the goal.

    Attributes
    ----------
    approach : int
        The library rest trim the task reaches first; its G lies in this S.
    """

    approach: int

    @property
    def goal_xy(self) -> NDArray[np.float64]:
        """Where it holds the robot (m)."""
        return self.start_xy

    def outer_domain(self, t: float) -> EllipsoidalDomain:
        """D'(t) in the world frame."""
        return self._world(self.policy.outer_domain(t))

    @property
    def name(self) -> str:
        """E.g. ``regulate[ep=0.55m]@(1.23, 2.5)``."""
        x, y = self.goal_xy
        return f"{self.policy.name}@({x:g}, {y:g})"


@dataclass(frozen=True, eq=False)
class ShiftTerminal:
    """A goal at rest off the lattice reached by shifts (where no capture regulator
    fits, or from the approach trim of one that does, instead of the regulator's step of
    the reference: :class:`~gracenav.execution.goals.Goals`): from the end of a library
    rest trim (``approach``), plain shifts of the palette (:meth:`Capture.shift_terminals`)
    to a grid point next to the goal whose G holds it, then a hold until the robot is at
    the goal: the smallest capture regulator whose D' fits, placed at the goal, or
    where none fits or its S does not hold the last shift's G, the palette's settled
    catch from rest held at that grid point. Catch ⪰ shift ⪰ rest trim, run the other
    way: the rest trim's G lies in the first shift's S, each shift's G in the next
    one's S, the last one's G in the hold's S (all exact ellipsoid containments), and
    every swept D' grown by the footprint is clear of the map's obstacles.

    Attributes
    ----------
    shifts : tuple of PlacedPolicy
        In the order they run (one or two).
    hold : PlacedPolicy
        The rest hold at the end point (:attr:`goal_xy`); run again as long as the robot
        is in its S and not yet at the goal.
    approach : int
        The library rest trim the task reaches first.
    sweep_points : ndarray, shape (K, 2)
        Samples of the shifts' and the hold's reference (m, world frame) ...
    sweep_reach : ndarray, shape (K,)
        ... and the radius of D' there plus half the gap to a neighbouring sample (m):
        the discs whose union holds every swept D' (checked against moving obstacles).
    lean_band : (float, float)
        Lean (rad) and lean rate (rad/s) within which the shifts and the hold are
        verified (the settled band): a stage starts only inside it.
    """

    shifts: tuple[PlacedPolicy, ...]
    hold: PlacedPolicy
    approach: int
    sweep_points: FloatArray
    sweep_reach: FloatArray
    lean_band: tuple[float, float]

    @property
    def stages(self) -> tuple[PlacedPolicy, ...]:
        """The shifts, then the hold."""
        return (*self.shifts, self.hold)

    @property
    def start_domain(self) -> EllipsoidalDomain:
        """S of the first shift (world frame): it holds the approach trim's G."""
        return self.shifts[0].start_domain

    @property
    def goal_domain(self) -> EllipsoidalDomain:
        """G of the hold (world frame, the last shift's G too): it holds the goal."""
        return self.hold.goal_domain

    @property
    def goal_xy(self) -> FloatArray:
        """The point it holds the robot at (m): the goal, or a grid point within a grid
        spacing of it."""
        return self.hold.start_xy

    @property
    def duration(self) -> float:
        """Duration of the shifts and one hold (s)."""
        return float(sum(p.duration for p in self.stages))

    @property
    def name(self) -> str:
        """E.g. ``shift_3_4@0°(1, 2) + catch_0[settled,S=1G]@0°(1.09, 2.12)``."""
        return " + ".join(p.name for p in self.stages)

    def accepts_lean(self, lean: float, rate: float) -> bool:
        """Whether a stage may start at this lean and lean rate deviation (norms, rad
        and rad/s) from upright: within the band it was verified from."""
        return abs(lean) <= self.lean_band[0] and abs(rate) <= self.lean_band[1]


#: What ends a task toward a goal at rest off the lattice.
Terminal = TerminalPolicy | ShiftTerminal
