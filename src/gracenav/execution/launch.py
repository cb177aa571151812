"""Starts at rest through one maneuver designed and verified at the start (a gracenav
extension, on by default: :attr:`~gracenav.execution.ExecutionOptions.online_starts`).

A task that starts at rest off the lattice reaches it through a capture (a shift onto a
rest trim, then a maneuver from rest) or a capture regulator. One maneuver from the start
itself onto the start state of a library policy ahead that starts at cruise (a cruise
trim, or a maneuver from one) does both at once
(``bench/bench_starts.py``: 1.875–2.75 s against 3.67–4.20 s). The palette cannot hold
it (the start is anywhere), so it is made when the task starts as the palette's
maneuvers and policies are made, in the one frame it runs in (the palette's are planned
and verified at a second placement too, a quarter turn, since the library places them
at every quarter turn): the nonic from rest at the start to that policy's start state
(:mod:`gracenav.execution.online`); its start domain sized by bisection, the largest
that verifies on the 3D model from points on the surface of S and passes the size test
that the policy's S holds its G (exact ellipsoid containment, the prepares relation) and
its swept D' grown by the footprint is clear of the map
(:func:`gracenav.policies.size_policy`), then verified from the still band
(:func:`gracenav.policies.catches.verify_still_start`). A maneuver is a candidate only
where S holds the start and its duration plus the policy's cost-to-go is below what the
start costs otherwise (:func:`launch_candidates`, the few whose ways run soonest). The
hybrid controller then prices every candidate by what its way runs, less what an end
designed online saves on it (the tree's cost-to-go sees neither), and takes the
cheapest whose check from the still band holds (:func:`confirm_launch`). It runs as a
capture whose last policy is followed by that policy (:class:`CapturePlan`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gracenav.execution.capture import CapturePlan, PlacedPolicy
from gracenav.execution.online import (
    LONGEST,
    design,
    shortest,
    size_where_it_runs,
    speed_limit,
)
from gracenav.policies import MotionPolicy, PrimitiveKind
from gracenav.policies.catches import verify_still_start

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary

__all__ = ["LaunchOptions", "confirm_launch", "launch_candidates"]

FloatArray = NDArray[np.float64]

#: Plans remembered per library (by start, lean, budget, cost-to-go and options).
_KEEP = 32
_MADE: weakref.WeakKeyDictionary[PolicyLibrary, dict[bytes, tuple[CapturePlan, ...]]] = (
    weakref.WeakKeyDictionary()
)
_CONFIRMED: weakref.WeakKeyDictionary[PolicyLibrary, dict[bytes, CapturePlan | None]] = (
    weakref.WeakKeyDictionary()
)


@dataclass(frozen=True)
class LaunchOptions:
    """Which library cruise trims a start may be launched onto.

    Parameters
    ----------
    ahead : (float, float)
        Range (m) of the policy's start point ahead of the start, along its direction
        of travel. Up to 3.5 m: a launch that joins the lattice farther along the way
        cuts the corner its first maneuvers would turn (``docs/design/speed.md``,
        *Launches that join the lattice farther along*).
    across : float
        Largest distance (m) of the policy's start point across its direction of
        travel.
    candidates : int
        Maneuvers whose S is verified at most, cheapest first by what the way runs from
        the policy launched onto (or its cost-to-go) plus the shortest duration their
        kinematics allow (each a 3D plan and the sizing of S, its verifications; one
        whose size test fails even at S = G runs none and does not count; the still
        band's verification only for the one that would be chosen). All of them are
        candidates: the way that runs soonest is not always the cheapest (its end may
        save less).
    maneuvers : bool
        Launch onto any library policy that starts at a cruise state (a trim, or a
        maneuver from one: a turn may reach the goal where the trim runs into a wall),
        not only onto cruise trims.
    fine : bool
        Launch onto fine copies too (their smaller domains, where nothing else fits
        near the start: the launch's G must then fit their smaller S); False keeps
        to the others. Measured under sensor noise with the position filter in
        ``docs/design/speed.md`` (*Launches onto fine copies*).
    longest : float or None
        Longest launch (s) designed; None keeps to the palette's longest maneuver
        (``PrimitiveSetOptions.max_duration``). A nonic from rest to a cruise state
        reaches farther only by lasting longer (``docs/design/speed.md``, *Online
        maneuvers longer than the palette's*).
    """

    ahead: tuple[float, float] = (0.3, 3.5)
    across: float = 1.2
    candidates: int = 4
    maneuvers: bool = True
    fine: bool = True
    longest: float | None = LONGEST


def launch_candidates(
    library: PolicyLibrary,
    state: FloatArray,
    lean: tuple[float, float],
    cost_to_go: FloatArray,
    budget: float,
    options: LaunchOptions | None = None,
    *,
    run_to_go: FloatArray | None = None,
) -> tuple[CapturePlan, ...]:
    """The maneuvers from the start ``state`` (x, y, ẋ, ẏ, the ball's) onto the library
    policies ahead that start at a cruise state (``options.maneuvers``; else onto cruise
    trims; fine copies too unless ``options.fine`` is False), cheapest first by their
    duration plus the tree's cost-to-go (``cost_to_go``, by library row) of the policy
    they launch onto, each priced below ``budget`` (s): at most ``options.candidates``
    sized, each with an S verified on the 3D model that holds the start; none where the
    measured lean and lean rate ``lean`` (norms, rad and rad/s) are outside the still
    band a launch is verified from (``CatchOptions.still_lean``). Not yet verified from
    the still band: :func:`confirm_launch` does that for the one a caller would take
    (the costliest check). A caller that prices the ways on more than the tree's
    cost-to-go (an end designed online saves more on one way than on another) compares
    them all. Given ``run_to_go`` (by library row, what the way from each runs:
    :func:`gracenav.execution.arrival.run_to_go`), the policies are sized in the order
    of their shortest maneuver plus that instead: the tree prices a fine copy at twice
    its duration and every hold in full, so its cheapest few are not always the ways
    that run soonest (``docs/design/speed.md``, *Launches sized by what their ways
    run*). The budget and the plans' costs stay the tree's price.

    The last few lists of each library are remembered (by start, lean, budget,
    cost-to-go and options): a task that is checked first and then run designs its
    start once.
    """
    opts = options if options is not None else LaunchOptions()
    key = hashlib.sha1(
        b"".join(
            np.ascontiguousarray(a, dtype=float).tobytes()
            for a in (state, lean, (budget,), cost_to_go)
        )
        + (b"" if run_to_go is None else np.ascontiguousarray(run_to_go, dtype=float).tobytes())
        + repr(opts).encode()
    ).digest()
    known = _MADE.setdefault(library, {})
    if key not in known:
        if len(known) >= _KEEP:
            del known[next(iter(known))]
        rank = cost_to_go if run_to_go is None else np.asarray(run_to_go, dtype=float)
        known[key] = _launch_candidates(library, state, lean, cost_to_go, rank, budget, opts)
    return known[key]


def confirm_launch(library: PolicyLibrary, plan: CapturePlan) -> CapturePlan | None:
    """``plan`` (one of :func:`launch_candidates`) with its maneuver verified from the
    still band too (:func:`gracenav.policies.catches.verify_still_start`), or None where
    that fails. Remembered per library, like the candidates."""
    key = hashlib.sha1(
        np.ascontiguousarray(plan.catch.start_xy, dtype=float).tobytes()
        + repr((plan.rest_row, plan.cost, plan.catch.policy.duration)).encode()
    ).digest()
    known = _CONFIRMED.setdefault(library, {})
    if key not in known:
        if len(known) >= _KEEP:
            del known[next(iter(known))]
        policy = verify_still_start(plan.catch.policy, library.palette.options, placements=(0,))
        known[key] = (
            dataclasses.replace(plan, catch=PlacedPolicy(policy, 0.0, plan.catch.start_xy.copy()))
            if policy.starts_from_still_band
            else None
        )
    return known[key]


def _launch_candidates(
    library: PolicyLibrary,
    state: FloatArray,
    lean: tuple[float, float],
    cost_to_go: FloatArray,
    rank: FloatArray,
    budget: float,
    opts: LaunchOptions,
) -> tuple[CapturePlan, ...]:
    palette = library.palette
    fastest = speed_limit(library)
    catch = palette.options.catch
    p = np.asarray(state, dtype=float).reshape(4)
    if catch is None or lean[0] > catch.still_lean[0] or lean[1] > catch.still_lean[1]:
        return ()
    start, zero = p[:2], np.zeros(2)
    if opts.maneuvers:
        # Every policy that starts at a cruise state: the trims and the maneuvers
        # from them (a turn may reach the goal where the trim runs into a wall).
        speed0 = np.hypot(library.start_state[:, 2], library.start_state[:, 3])
        rows = np.flatnonzero((speed0 > 1e-6) & np.isfinite(cost_to_go))
        rows = rows[~library.types.is_capture[library.type_index[rows]]]
    else:
        rows = library.trim_indices(PrimitiveKind.CRUISE)
        rows = rows[np.isfinite(cost_to_go[rows])]
    if not opts.fine:
        rows = rows[~library.is_fine(rows)]
    v = library.start_state[rows, 2:4]
    speed = np.hypot(v[:, 0], v[:, 1])
    u = v / speed[:, None]
    w = library.start_xy[rows] - start
    ahead = np.sum(w * u, axis=1)
    across = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    near = (ahead >= opts.ahead[0]) & (ahead <= opts.ahead[1]) & (np.abs(across) <= opts.across)
    # Each policy priced at its cost-to-go plus the shortest maneuver kinematics allow
    # (a lower bound on the designed one's), up to the budget; sized cheapest first by
    # ``rank`` (the cost-to-go, or what the way runs) plus that shortest maneuver.
    picks: list[tuple[float, int, float]] = []
    for row in rows[near].tolist():
        end, velocity = library.start_xy[row], library.start_state[row, 2:4]
        least_time = shortest(start, end, zero, velocity, palette, opts.longest, fastest)
        if least_time + float(cost_to_go[row]) < budget:
            picks.append((least_time + float(rank[row]), int(row), least_time))
    picks.sort()

    sized: list[tuple[float, int, MotionPolicy]] = []
    verified = 0
    for _bound, row, least_time in picks:
        if verified >= opts.candidates:
            break
        end, velocity = library.start_xy[row], library.start_state[row, 2:4]
        maneuver = design(
            start,
            end,
            zero,
            velocity,
            palette,
            least_time,
            name="launch",
            longest=opts.longest,
            max_speed=fastest,
        )
        if maneuver is None:
            continue
        cost = maneuver.duration + float(cost_to_go[row])
        if cost >= budget:
            continue
        policy = size_where_it_runs(library, maneuver, start, library.policy(row).start_domain)
        if policy.report is None:
            continue  # not even S = G fits: no verification ran
        verified += 1
        if not policy.report.passed:
            continue
        if not PlacedPolicy(policy, 0.0, start).start_domain.contains(p):
            continue
        sized.append((cost, row, policy))
    sized.sort(key=lambda c: (c[0], c[1]))
    return tuple(
        CapturePlan(
            catch=PlacedPolicy(policy, 0.0, start.copy()), shifts=(), rest_row=row, cost=cost
        )
        for cost, row, policy in sized
    )
