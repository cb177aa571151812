"""Ends at rest through one maneuver designed and verified when the task starts (a
gracenav extension: :attr:`~gracenav.execution.ExecutionOptions.online_ends`).

The lattice ends a task at rest through a maneuver onto a rest trim (a stop), often
followed by rest-to-rest steps onto the goal's own point, each from rest and to rest
(e.g. ``cruise_x_to_rest_1_0``, 1.875 s, then ``rest_to_rest_2_1``, 4.0 s, for a goal
1 m beside the stop). One maneuver from the end of a moving policy on the way straight
to rest at the goal does all of it at once. The palette cannot hold it (it joins two
places of the map, not two trims of the lattice), so it is made when the task starts,
as the starts designed online are (:mod:`gracenav.execution.launch`): the nonic from the
policy's end state to rest at the goal (:mod:`gracenav.execution.online`), its start
domain sized by bisection, the largest that verifies on the 3D model from points on the
surface of S, in the one frame it runs in, and passes the size test that the goal's
rest trim's S holds its G and its swept D' grown by the footprint is clear of the map
(:func:`gracenav.policies.size_policy`); it is used only when its S then holds the
policy's G (exact ellipsoid containment: the prepares relation), so the switch onto it
is a graceful switch like any other.

The candidates are the moving policies on the tree's way from the start's first
library policy, each priced against what the way runs after it (the rest trims that
:attr:`~gracenav.execution.ExecutionOptions.skip_holds` skips left out). The one
that saves the most is kept. The tree is not changed: a robot pushed off the way
follows the tree to the goal's rest trim as before, and takes the maneuver whenever it
ends that policy in its G.
"""

from __future__ import annotations

import hashlib
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gracenav.errors import PlanningError
from gracenav.execution.capture import CapturePlan, PlacedPolicy
from gracenav.execution.online import (
    LONGEST,
    design,
    shortest,
    size_where_it_runs,
    speed_limit,
)
from gracenav.execution.types import TERMINAL
from gracenav.policies import MotionPolicy, PrimitiveKind

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary

__all__ = ["ArrivalOptions", "ArrivalPlan", "arrival_plan", "run_to_go", "way_time"]

FloatArray = NDArray[np.float64]

#: Distance (m) below which a policy ends at the goal already.
_NEAR = 1e-3

#: Plans remembered per library (by way, options and whether holds are skipped).
_KEEP = 32
_MADE: weakref.WeakKeyDictionary[PolicyLibrary, dict[bytes, ArrivalPlan | None]] = (
    weakref.WeakKeyDictionary()
)


@dataclass(frozen=True)
class ArrivalOptions:
    """Which policies of the way an end maneuver may start from.

    Parameters
    ----------
    reach : float
        Largest distance (m) from the policy's end point to the goal.
    candidates : int
        Maneuvers whose S is verified at most, the largest saving first by the
        shortest duration their kinematics allow (each a 3D plan and the sizing of S;
        one whose size test fails even at S = G runs no verification and does not
        count).
    min_saving : float
        Smallest saving (s) for which a maneuver is designed.
    longest : float or None
        Longest maneuver (s) designed; None keeps to the palette's longest maneuver
        (``PrimitiveSetOptions.max_duration``). A nonic from a cruise state to rest
        reaches farther back only by lasting longer (``docs/design/speed.md``, *Online
        maneuvers longer than the palette's*).
    """

    reach: float = 3.0
    candidates: int = 4
    min_saving: float = 0.125
    longest: float | None = LONGEST


@dataclass(frozen=True)
class ArrivalPlan:
    """A verified end maneuver on a task's way.

    Attributes
    ----------
    after : int
        The library row it starts from: it runs when that policy ends with the state in
        its G (which its S holds).
    plan : CapturePlan
        The maneuver placed at that policy's end point, followed by the goal's rest
        trim (``plan.rest_row``), or by the terminal regulator at a goal off the lattice
        (``plan.rest_row`` is then :data:`~gracenav.execution.TERMINAL`); ``plan.cost``
        is its duration.
    saving : float
        How much shorter (s) it is than the way after ``after``, as it runs.
    """

    after: int
    plan: CapturePlan
    saving: float


def arrival_plan(
    library: PolicyLibrary,
    way: Sequence[int],
    *,
    hold: PlacedPolicy | None = None,
    lead: float = 0.0,
    skip_holds: bool = True,
    options: ArrivalOptions | None = None,
) -> ArrivalPlan | None:
    """The end maneuver that saves the most on ``way``, or None.

    ``way`` is the library rows a task runs, in order (a tree's
    :meth:`~gracenav.planning.PolicyTree.path_from`). Its last is the goal's rest trim,
    whose start is the goal; or, for a goal off the lattice, the rest trim its terminal
    takes over from: the maneuver then ends at the start of ``hold``, the capture
    regulator placed at the goal (the terminal itself, or the hold after a terminal's
    shifts), and is followed by it (its S must hold the maneuver's G). ``lead`` is
    what the way runs between its last rest trim and ``hold`` (s): the terminal's shifts,
    which the maneuver saves too. ``skip_holds`` prices the way as it runs with
    :attr:`~gracenav.execution.ExecutionOptions.skip_holds` (rest trims on the way
    skipped). The last few plans of each library are remembered (a task that is checked
    first and then run designs its end once).
    """
    opts = options if options is not None else ArrivalOptions()
    rows = np.asarray(way, dtype=np.int64)
    at = b"" if hold is None else np.asarray(hold.start_xy, dtype=float).tobytes()
    key = hashlib.sha1(
        rows.tobytes() + at + repr((hold is None or hold.name, lead, skip_holds, opts)).encode()
    ).digest()
    known = _MADE.setdefault(library, {})
    if key not in known:
        if len(known) >= _KEEP:
            del known[next(iter(known))]
        known[key] = _arrival_plan(library, rows, hold, lead, skip_holds, opts)
    return known[key]


def way_time(library: PolicyLibrary, way: Sequence[int], *, skip_holds: bool = True) -> float:
    """How long (s) the library rows ``way`` run, up to, not including, the last: each
    its own duration (the trees price a fine copy at twice its own), and with
    ``skip_holds`` none for the rest trims on the way (the policy after a rest trim
    starts as soon as its S holds the state); a capture regulator in full."""
    return float(np.sum(_run_times(library, np.asarray(way, dtype=np.int64), skip_holds)))


def run_to_go(
    library: PolicyLibrary,
    next_policy: NDArray[np.int64],
    cost_to_go: FloatArray,
    *,
    skip_holds: bool = True,
) -> FloatArray:
    """:func:`way_time` of every library row's way along a tree (``next_policy`` and
    ``cost_to_go`` of a :class:`~gracenav.planning.PolicyTree`, or of the rows a
    :class:`~gracenav.planning.LazyPolicyTree` has closed), shape (N,): what the way
    runs from each row to the goal, inf where ``cost_to_go`` is (not reached, or not
    closed yet). The trees' cost-to-go prices a fine copy at twice its duration and
    every hold in full; this is what the way runs.

    Summed by pointer jumping (each row adds the sum of the row it points to, which
    then points twice as far), so a way of n rows takes log2(n) passes over the rows;
    the sums agree with :func:`way_time` to rounding.
    """
    n = len(library)
    run_by_type = _run_by_palette_policy(library, skip_holds)
    rows = np.flatnonzero(np.isfinite(cost_to_go))
    total = np.full(n, np.inf)
    if rows.size == 0:
        return total
    # On the reached rows only: each row's run, and the row after it (the goal, whose
    # own run is not counted, points nowhere).
    slot = np.full(n, -1, dtype=np.int64)
    slot[rows] = np.arange(rows.size)
    after = np.asarray(next_policy, dtype=np.int64)[rows]
    nxt = np.where(after >= 0, slot[np.maximum(after, 0)], -1)
    acc = np.where(nxt >= 0, run_by_type[library.palette_index[rows]], 0.0)
    for _ in range(64):  # 2**64 rows: far beyond any way
        jump = nxt >= 0
        if not jump.any():
            break
        acc = np.where(jump, acc + acc[np.maximum(nxt, 0)], acc)
        nxt = np.where(jump, nxt[np.maximum(nxt, 0)], -1)
    else:  # pragma: no cover - a tree's ways end at its goal
        raise PlanningError("corrupt policy tree (a way that does not end)")
    total[rows] = acc
    return total


def _run_by_palette_policy(library: PolicyLibrary, skip_holds: bool) -> FloatArray:
    """What each palette policy runs (s): its duration, or with ``skip_holds`` none for
    a rest trim (the policy after it starts as soon as its S holds the state); a
    capture regulator in full."""

    def hold(pol: MotionPolicy) -> bool:
        return pol.primitive.kind is PrimitiveKind.REST and not pol.capture

    return np.array(
        [0.0 if skip_holds and hold(pol) else pol.duration for pol in library.palette.policies],
        dtype=float,
    )


def _run_times(library: PolicyLibrary, way: NDArray[np.int64], skip_holds: bool) -> FloatArray:
    """What each library row of ``way`` runs, up to, not including, the last."""
    out: FloatArray = _run_by_palette_policy(library, skip_holds)[library.palette_index[way[:-1]]]
    return out


def _arrival_plan(
    library: PolicyLibrary,
    way: NDArray[np.int64],
    hold: PlacedPolicy | None,
    lead: float,
    skip_holds: bool,
    opts: ArrivalOptions,
) -> ArrivalPlan | None:
    if way.size < 2:
        return None
    palette = library.palette
    fastest = speed_limit(library)
    last = int(way[-1])
    if library.policy(last).policy.primitive.kind is not PrimitiveKind.REST:
        return None
    # What follows the maneuver, at the goal: the goal's rest trim, or the regulator.
    if hold is None:
        goal, then_start, then = library.start_xy[last], library.policy(last).start_domain, last
    else:
        goal, then_start, then = hold.start_xy, hold.start_domain, TERMINAL
    zero = np.zeros(2)
    # What the way runs after each of its policies, up to the goal's rest trim (and
    # from there to the hold: a terminal's shifts).
    runs = _run_times(library, way, skip_holds)
    after = np.concatenate([np.cumsum(runs[::-1])[::-1][1:], [0.0]]) + lead
    picks: list[tuple[float, int, float, float]] = []
    for k, row in enumerate(way[:-1].tolist()):
        end = library.end_state[row]
        if library.policy(row).policy.primitive.kind is PrimitiveKind.REST:
            continue  # from the end of the stop before it instead
        if not _NEAR <= float(np.hypot(*(goal - end[:2]))) <= opts.reach:
            continue
        least_time = shortest(end[:2], goal, end[2:], zero, palette, opts.longest, fastest)
        if after[k] - least_time >= opts.min_saving:
            picks.append((least_time - after[k], row, least_time, after[k]))
    picks.sort()

    best: ArrivalPlan | None = None
    verified = 0
    for bound, row, least_time, rest_of_way in picks:
        saved = best.saving if best is not None else opts.min_saving - 1e-9
        if -bound <= saved or verified >= opts.candidates:
            break
        end = library.end_state[row]
        maneuver = design(
            end[:2],
            goal,
            end[2:],
            zero,
            palette,
            least_time,
            name="arrival",
            longest=opts.longest,
            max_speed=fastest,
        )
        if maneuver is None or rest_of_way - maneuver.duration <= saved:
            continue
        start = end[:2].copy()
        policy = size_where_it_runs(library, maneuver, start, then_start)
        if policy.report is None:
            continue  # not even S = G fits: no verification ran
        verified += 1
        if not policy.report.passed:
            continue
        placed = PlacedPolicy(policy, 0.0, start)
        if not placed.start_domain.contains_domain(library.policy(row).goal_domain):
            continue  # the policy it follows does not prepare it
        plan = CapturePlan(catch=placed, shifts=(), rest_row=then, cost=maneuver.duration)
        best = ArrivalPlan(after=row, plan=plan, saving=rest_of_way - maneuver.duration)
    return best
