"""Maneuvers designed when a task starts (gracenav extensions): one from a start at rest
onto the lattice (:mod:`gracenav.execution.launch`) and one from the lattice to rest at
the goal (:mod:`gracenav.execution.arrival`).

Each is made as the palette's maneuvers are made (:mod:`gracenav.primitives.design`): the
nonic between two position states, the shortest on the palette's duration grid that
keeps within its speed, does not run backwards along the way it moves, keeps the ball's
jerk within the palette's bound when its maneuvers are limited references, and that the
shape trajectory planner makes feasible on the 3D model within the palette's lean and
torque limits; planned in the one frame it runs in.
"""

from __future__ import annotations

import hashlib
import math
import os
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from numpy.typing import NDArray

from gracenav.execution.capture import PlacedPolicy, capture_for
from gracenav.library.push_fans import FAN_FLOOR
from gracenav.policies import MotionPolicy, domain_shape, size_policy
from gracenav.policies.catches import ball_jerk
from gracenav.policies.primitive import SampledPrimitive
from gracenav.primitives.design import passes_screen
from gracenav.primitives.motion import Maneuver, PrimitiveReport, PrimitiveSetOptions
from gracenav.primitives.references import NonicReference
from gracenav.primitives.shape_planner import plan_shape_trajectory

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary
    from gracenav.palette import Palette
    from gracenav.params import BallbotParams
    from gracenav.policies.domains import EllipsoidalDomain

__all__ = ["LONGEST", "admissible", "design", "shortest", "size_where_it_runs", "speed_limit"]

FloatArray = NDArray[np.float64]
_T = TypeVar("_T")

#: Shortest duration (s) designed: the shape trajectory planner's basis needs a few
#: knots (at 0.25 s and below its linear system is singular or its ends are not trims).
_SHORTEST = 0.5

#: Longest maneuver (s) designed online by default
#: (:attr:`~gracenav.execution.launch.LaunchOptions.longest`,
#: :attr:`~gracenav.execution.arrival.ArrivalOptions.longest`): longer than the
#: palette's 4.5 s, since a nonic between rest and cruise reaches farther only by lasting
#: longer (2.05 m in 4.5 s, 2.95 m in 6.5 s within the palette's 0.8 m/s).
LONGEST = 6.5

#: Speed (m/s) below which an end is at rest (a stop's end velocity is about 1e-13 m/s).
_MOVING = 1e-6

# What was designed and sized, remembered: a task is checked before it is run, and the
# start's candidates and the end's are designed and sized again for the same
# displacements (256 designs of 54 different ones in a pair of the random pairs
# campaign). Both are pure functions of their inputs, so a remembered result is the
# result. Designs by palette (id, dropped with it), sizings by library (its map), the
# last few: about 0.24 MB a design, 0.8 MB a verified sizing (those whose S = G does not
# fit, no verification run, cost a few ms and are not kept). The shortest durations
# kinematics allow too, by palette: a start's candidates ask for one per policy ahead,
# and policies that start at one cruise state ask the same (471 asks of 107 different
# ones in a pair), each a scan of the duration grid (about 2 ms); ~150 bytes each.
_DESIGNS_KEPT = 96
_SIZINGS_KEPT = 32
_SHORTEST_KEPT = 4096
_designs: dict[int, OrderedDict[bytes, Maneuver | None]] = {}
_shortest: dict[int, OrderedDict[bytes, float]] = {}
_sizings: weakref.WeakKeyDictionary[
    PolicyLibrary, OrderedDict[bytes, tuple[Maneuver, MotionPolicy]]
] = weakref.WeakKeyDictionary()
_remembered = threading.Lock()


def _forget_the_lock() -> None:
    """In a forked child: a new lock (another thread may have held the parent's)."""
    global _remembered
    _remembered = threading.Lock()


os.register_at_fork(after_in_child=_forget_the_lock)


def _key(*parts: object) -> bytes:
    """A digest of arrays (their float64 bytes) and other values (their repr)."""
    h = hashlib.sha1()
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(np.ascontiguousarray(part, dtype=float).tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"|")
    return h.digest()


def _recall(table: OrderedDict[bytes, _T], key: bytes) -> tuple[_T] | None:
    """The value remembered for ``key`` (boxed: it may be None), or None."""
    with _remembered:
        if key in table:
            table.move_to_end(key)
            return (table[key],)
    return None


def _keep(table: OrderedDict[bytes, _T], key: bytes, value: _T, most: int) -> None:
    with _remembered:
        table[key] = value
        while len(table) > most:
            table.popitem(last=False)


def _remembered_or_made(
    table: OrderedDict[bytes, _T], key: bytes, most: int, make: Callable[[], _T]
) -> _T:
    """What ``table`` remembers for ``key``, else ``make()``, kept (the last ``most``)."""
    found = _recall(table, key)
    if found is not None:
        return found[0]
    made = make()
    _keep(table, key, made, most)
    return made


def _table_of(
    tables: dict[int, OrderedDict[bytes, _T]], palette: Palette
) -> OrderedDict[bytes, _T]:
    """``palette``'s table in ``tables`` (made on first use, dropped with the palette)."""
    with _remembered:
        table = tables.get(id(palette))
        if table is None:
            table = tables[id(palette)] = OrderedDict()
            weakref.finalize(palette, tables.pop, id(palette), None)
    return table


def speed_limit(library: PolicyLibrary) -> float:
    """Largest flat-output speed (m/s) of a maneuver designed online on ``library``: the
    palette's, but at most :data:`~gracenav.library.push_fans.FAN_FLOOR` where the
    library keeps room for a design push. Above that speed the library keeps its own
    policies' room for the catches of the design push (their push fans); a maneuver
    designed online gets no such check, so it keeps below it (a palette whose
    references keep within 0.8 m/s, the default and the smooth one, is not changed)."""
    speed = float(library.palette.primitive_options.max_speed)
    return min(speed, FAN_FLOOR) if library.design_push > 0.0 else speed


def admissible(
    disp: FloatArray,
    v0: FloatArray,
    v1: FloatArray,
    options: PrimitiveSetOptions,
    shortest: float,
    params: BallbotParams,
    longest: float | None = None,
    max_speed: float | None = None,
) -> Iterator[tuple[float, NonicReference]]:
    """The nonics from the origin at velocity ``v0`` to displacement ``disp`` at velocity
    ``v1`` on the duration grid from ``shortest`` (s, at least :data:`_SHORTEST`) to
    ``longest`` (s; None: ``options.max_duration``, the palette's longest maneuver),
    shortest first, that keep within ``options``' speed (or ``max_speed``, m/s, where
    lower), do not run backwards
    (beyond ``options.max_backward_speed``) against the moving end's direction of travel (the
    end's, when both move; the displacement's, from rest to rest) and, when the palette's
    maneuvers are limited references, keep the ball's jerk (of ``params``' linearised
    model, :func:`gracenav.policies.catches.ball_jerk`) within ``options.max_ball_jerk``,
    as those do."""
    jerk_bound = options.max_ball_jerk if options.reference == "limited" else math.inf
    along = v1 if float(np.hypot(*v1)) > _MOVING else v0 if float(np.hypot(*v0)) > _MOVING else disp
    u = along / float(np.hypot(*along))
    step = options.duration_step
    first = max(1, math.ceil(max(shortest, _SHORTEST) / step - 1e-9))
    last = options.max_duration if longest is None else longest
    fastest = options.max_speed if max_speed is None else min(options.max_speed, max_speed)
    for m in range(first, math.floor(last / step + 1e-9) + 1):
        duration = m * step
        ref = NonicReference.between(duration, np.zeros(2), v0, disp, v1)
        t = np.linspace(0.0, duration, max(2, int(duration * 128) + 1))
        vel = ref.value(t, 1)
        if np.max(np.hypot(vel[:, 0], vel[:, 1])) > fastest * (1 + 1e-9):
            continue
        if np.min(vel @ u) < -options.max_backward_speed:
            continue
        if jerk_bound < math.inf and ball_jerk(ref, params) > jerk_bound:
            continue
        yield duration, ref


def shortest(
    start: FloatArray,
    end: FloatArray,
    v0: FloatArray,
    v1: FloatArray,
    palette: Palette,
    longest: float | None = None,
    max_speed: float | None = None,
) -> float:
    """The shortest duration :func:`admissible` gives from ``start`` at ``v0`` to ``end``
    at ``v1`` (inf if none up to ``longest``, s, by default the palette's longest
    maneuver; within ``max_speed`` where given): a lower bound on :func:`design`'s, from
    kinematics alone."""
    disp = np.asarray(end, dtype=float) - start
    u0, u1 = np.asarray(v0, dtype=float), np.asarray(v1, dtype=float)
    opts, params = palette.primitive_options, palette.params

    def scan() -> float:
        first = admissible(disp, u0, u1, opts, 0.0, params, longest, max_speed)
        return next((duration for duration, _ in first), math.inf)

    key = _key(disp, u0, u1, longest, max_speed)
    return _remembered_or_made(_table_of(_shortest, palette), key, _SHORTEST_KEPT, scan)


def design(
    start: FloatArray,
    end: FloatArray,
    v0: FloatArray,
    v1: FloatArray,
    palette: Palette,
    shortest: float,
    *,
    name: str,
    longest: float | None = None,
    max_speed: float | None = None,
) -> Maneuver | None:
    """The shortest nonic on the palette's duration grid, from ``shortest`` (s) on, from
    ``start`` at ``v0`` to ``end`` at ``v1`` that is feasible on the 3D model (None if
    none is up to ``longest``, s, by default the palette's longest maneuver; within
    ``max_speed`` where given)."""
    disp = np.asarray(end, dtype=float) - start
    v0, v1 = (np.asarray(v, dtype=float) for v in (v0, v1))
    key = _key(disp, v0, v1, float(shortest), name, longest, max_speed)
    return _remembered_or_made(
        _table_of(_designs, palette),
        key,
        _DESIGNS_KEPT,
        lambda: _design(disp, v0, v1, palette, shortest, name, longest, max_speed),
    )


def _design(
    disp: FloatArray,
    v0: FloatArray,
    v1: FloatArray,
    palette: Palette,
    shortest: float,
    name: str,
    longest: float | None,
    max_speed: float | None,
) -> Maneuver | None:
    options = palette.primitive_options
    params = palette.params
    for duration, ref in admissible(disp, v0, v1, options, shortest, params, longest, max_speed):
        if not passes_screen(ref, params, options):
            continue  # the palette's screen: the 3D model only where it may pass
        res = plan_shape_trajectory(ref, params, model="3d", options=options.planner)
        if not res.within(options.max_lean, params.torque_limit):
            continue
        report = PrimitiveReport.from_result(res)
        return Maneuver(
            name=name,
            duration=duration,
            displacement=disp,
            start_velocity=v0,
            end_velocity=v1,
            params=params,
            start_trim="cruise" if float(np.hypot(*v0)) > _MOVING else "rest",
            end_trim="cruise" if float(np.hypot(*v1)) > _MOVING else "rest",
            plans=(res.trajectory, res.trajectory),
            reports=(report, report),
        )
    return None


def size_where_it_runs(
    library: PolicyLibrary,
    maneuver: Maneuver,
    start: FloatArray,
    then: EllipsoidalDomain,
) -> MotionPolicy:
    """The policy of ``maneuver`` placed at ``start`` (heading 0), its S sized by
    :func:`gracenav.policies.size_policy` as the palette's, verified on the 3D model in
    the one frame it runs in (the palette's policies also at a quarter turn, since the
    library places them at every quarter turn), with the size test that ``then`` (the S
    of what follows, world frame) holds its G (exact containment) and its swept D' grown
    by the footprint is clear of the map: near a wall a smaller S rather than none (the
    size test's bisection run first, and the size it ends on verified:
    ``largest_fit_first``). Its report is None where not even S = G passes the size test
    (no verification ran). Verified sizings are remembered per library."""
    at = np.asarray(start, dtype=float)
    with _remembered:
        table = _sizings.setdefault(library, OrderedDict())
    # The maneuver by identity (design returns the one it remembers), kept with the
    # result so that its id is not reused while remembered.
    key = _key(id(maneuver), at, then.center, then.shape_matrix)
    found = _recall(table, key)
    if found is not None and found[0][0] is maneuver:
        return found[0][1]
    sized = _size_where_it_runs(library, maneuver, at, then)
    if sized.report is not None:
        _keep(table, key, (maneuver, sized), _SIZINGS_KEPT)
    return sized


def _size_where_it_runs(
    library: PolicyLibrary, maneuver: Maneuver, at: FloatArray, then: EllipsoidalDomain
) -> MotionPolicy:
    palette = library.palette
    gains, vopts = palette.gains, palette.options
    capture = capture_for(library)

    def fits(pol: MotionPolicy) -> bool:
        if not then.contains_domain(PlacedPolicy(pol, 0.0, at).goal_domain):
            return False
        path, reach = capture.swept(pol)
        return bool(np.all(capture.clear(at + path, reach)))

    return size_policy(
        SampledPrimitive.from_primitive(maneuver),
        gains,
        vopts,
        shape=domain_shape(gains, horizon=vopts.shape_horizon),
        fits=fits,
        placements=(0,),
        largest_fit_first=True,
    )
