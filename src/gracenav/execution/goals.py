"""Goals of a task on a library: the trim policy a task ends on, and for a goal at rest
off the lattice the terminal placed there: a capture regulator whose S holds the G of a
rest trim of the library, or where none fits, shifts from a rest trim's end onto a grid
point whose G holds the goal (:class:`~gracenav.execution.capture.ShiftTerminal`)."""

from __future__ import annotations

import math
import weakref

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError, PlanningError
from gracenav.execution.capture import Terminal, TerminalPolicy, capture_for
from gracenav.library import PolicyLibrary, quarter_turn
from gracenav.policies import PrimitiveKind

__all__ = ["Goals"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Distance (m, m/s) within which a goal counts as the end state of a lattice trim.
ON_LATTICE = 1e-9

#: Terminals by goal (:meth:`HybridController.terminal_policies`) of each library, and
#: every terminal of a goal (:meth:`Goals.alternatives`, under the goal with a trailing
#: ``inf``): they depend on the library and the goal only, so every controller on the
#: same library (a scenario's runs, a campaign's trials) shares them, as long as it lives.
_TERMINALS: weakref.WeakKeyDictionary[
    PolicyLibrary, dict[tuple[float, ...], tuple[Terminal, ...]]
] = weakref.WeakKeyDictionary()


class Goals:
    """The goals of tasks on ``library``: which trim a task ends on, and the terminal
    regulators of goals off the lattice (cached per library and goal).

    Parameters
    ----------
    library : PolicyLibrary
    """

    def __init__(self, library: PolicyLibrary) -> None:
        self.library = library
        self.palette = library.palette
        self._terminals = _TERMINALS.setdefault(library, {})

    def goal_policy(self, goal: ArrayLike) -> int:
        """The closest trim policy (Euclidean, to its G's centre; the shortest of equally
        close ones) whose G contains ``goal``; for a goal at rest that no trim's G
        contains, the rest trim the task ends on before the terminal at the goal takes
        over (:meth:`terminal_policies`).

        Raises
        ------
        PlanningError
            If the goal is outside the map, in an obstacle (grown by the footprint), or
            no trim policy's goal domain contains it and no terminal fits there (outside
            coverage; the message says what clearance a terminal needs).
        """
        g = np.asarray(goal, dtype=float)
        if g.shape != (4,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"a goal is a position state (x, y, xdot, ydot), got {goal!r}")
        wm = self.library.world_map
        (x0, y0), (x1, y1) = wm.bounds
        if not (x0 <= g[0] <= x1 and y0 <= g[1] <= y1):
            raise PlanningError(
                f"goal ({g[0]:g}, {g[1]:g}) is outside the map [{x0:g}, {x1:g}] × [{y0:g}, {y1:g}]"
            )
        if float(wm.clearance(g[None, :2])[0]) < self.library.footprint_radius:
            raise PlanningError(
                f"goal ({g[0]:g}, {g[1]:g}) is inside an obstacle or closer to one than the "
                f"robot's footprint radius {self.library.footprint_radius:g} m"
            )
        candidate = self._containing_trim(g)
        at_rest = bool(np.all(g[2:] == 0.0))
        exact = candidate >= 0 and bool(
            np.linalg.norm(self.library.end_state[candidate] - g) <= ON_LATTICE
        )
        if candidate >= 0 and (exact or not at_rest):
            return candidate
        # A goal at rest off the lattice: a terminal brings the robot onto it; without
        # a regulator, the trim whose G contains it (within G's extent of the goal);
        # without either, shifts (terminal_policies).
        terminals = self.terminal_policies(g) if at_rest else ()
        if terminals:
            return terminals[0].approach
        if candidate >= 0:
            return candidate
        where = ", ".join(f"{v:g}" for v in g)
        if at_rest:
            raise PlanningError(f"goal ({where}) is outside coverage: {self._why_not(g)}")
        raise PlanningError(
            f"goal ({where}) is outside coverage: a moving goal must be a cruise trim of the "
            "library (on the instantiation lattice, at a trim velocity, away from obstacles)"
        )

    def _containing_trim(self, g: FloatArray) -> int:
        """The trim :meth:`goal_policy` ends on when its G contains ``g`` (−1: none)."""
        trims = self.library.trim_indices()
        ends = self.library.end_state[trims]
        # Nearest first; among equally near trims (a rest trim and the longer capture
        # trim end at the same state) the shortest, so a task does not end on a hold
        # longer than it needs.
        order = np.lexsort((self.library.durations[trims], np.linalg.norm(ends - g, axis=1)))
        near = trims[order][:64]
        inside = np.flatnonzero(self.goal_domains_contain(near, g))
        return int(near[inside[0]]) if inside.size else -1

    def _why_not(self, g: FloatArray) -> str:
        """Why no terminal fits at the goal at rest ``g``, and what to do."""
        lib = self.library
        room = float(lib.world_map.clearance(g[None, :2])[0]) - lib.footprint_radius
        regs = [p for p in self.palette.policies if p.capture]
        parts = ["no trim policy of the library has it in its goal domain"]
        if regs:
            small = min(regs, key=lambda p: p.start_radii.position)
            need = small.outer_factors[0] * small.start_radii.position
            parts.append(
                f"no capture regulator fits there (the smallest needs {need:.2f} m of "
                "clearance beyond the footprint and a rest trim of the library within its "
                f"start domain, {small.start_radii.position:.2f} m)"
            )
        capture = capture_for(lib)
        opts = capture.options
        if capture.available and opts is not None and capture.shifts_available:
            need = capture.shift_end_reach
            reach = 2 * opts.shift_radius
            if room < need:
                parts.append(
                    f"no shift ends there (a shift's outer domain needs {need:.3f} m of "
                    f"clearance beyond the footprint at its end; the goal has {room:.3f} m)"
                )
                todo = (
                    f"move the goal to at least {need:.3f} m beyond the footprint from "
                    "every obstacle"
                )
            else:
                parts.append(
                    f"and no way of at most two shifts ({reach:g} m) from a rest trim of "
                    "the library reaches it with every swept outer domain clear of the "
                    "obstacles (the goal has "
                    f"{room:.3f} m of clearance beyond the footprint)"
                )
                todo = (
                    f"move the goal within {reach:g} m of open space where the library has "
                    "rest trims, or use more lattice halvings"
                )
        else:
            todo = "move the goal away from obstacles or use more lattice halvings"
        return "; ".join(parts) + f"; {todo}"

    def goal_domains_contain(self, rows: IntArray, g: FloatArray) -> BoolArray:
        """Whether G of each library row in ``rows`` contains the position state ``g``:
        ``g`` taken into each policy's own frame and tested against its G there (the
        same ellipsoid as the world-frame G, rotated by a quarter turn), vectorised."""
        lib = self.library
        out = np.zeros(rows.shape, dtype=bool)
        for p in np.unique(lib.palette_index[rows]):
            sel = np.flatnonzero(lib.palette_index[rows] == p)
            pol = self.palette.policies[int(p)]
            local = pol.domain(pol.duration)
            r = rows[sel]
            q = np.empty((r.size, 4))
            for k in range(4):  # world -> policy frame: rotate by -k quarter turns
                m = lib.orientation[r] == k
                if np.any(m):
                    rt = quarter_turn(k).T
                    q[m, :2] = (g[:2] - lib.start_xy[r[m]]) @ rt.T
                    q[m, 2:] = g[2:] @ rt.T
            out[sel] = local.contains(q)
        return out

    def terminal(self, goal: ArrayLike, goal_id: int) -> Terminal | None:
        """The terminal a task toward ``goal`` ends with, if ``goal_id`` is the approach
        trim :meth:`goal_policy` chose for it; None when that trim ends at the goal (a
        goal on the lattice needs no terminal)."""
        g = np.asarray(goal, dtype=float)
        if 0 <= goal_id < len(self.library) and bool(
            np.linalg.norm(self.library.end_state[goal_id] - g) <= ON_LATTICE
        ):
            return None
        terms = self._terminals.get(tuple(float(v) for v in g))
        for term in terms or ():
            if term.approach == goal_id:
                return term
        return None

    def terminal_policies(self, goal: ArrayLike) -> tuple[Terminal, ...]:
        """Terminals for a goal at rest off the lattice, best first.

        The capture regulators first: for each capture regulator of the palette,
        largest first, whose outer domain (a disc of radius ``outer_factors[0]`` ×
        e_p(S) around the goal, not shrinking) grown by the footprint is clear of
        obstacles: every rest trim of the library whose G lies in the regulator's S at
        the goal (exact ellipsoid containment), nearest first. Where no regulator fits
        and no trim's G contains the goal, the shift terminals
        (:meth:`Capture.shift_terminals`). Empty when none fits.
        """
        g = np.asarray(goal, dtype=float)
        key = tuple(float(v) for v in g)
        got = self._terminals.get(key)
        if got is not None:
            return got
        result: tuple[Terminal, ...] = self._regulators(g, every_size=False)
        if result:
            result = self._graceful(g, result)
        elif self._containing_trim(g) < 0:
            result = self._shift_terminals(g)
        self._terminals[key] = result
        return result

    def alternatives(self, goal: ArrayLike) -> tuple[Terminal, ...]:
        """Every terminal for a goal at rest, for a task that cannot end on its own (a
        start that cannot reach it, moving obstacles that block it): the capture
        regulators of every size that fits (largest first, each with the rest trims
        whose G lies in its S), then the shift terminals of one and of two shifts (a
        goal on the lattice is the end of shifts from other rest trims too). Of the
        rest trims of one palette policy at one point (its four orientations, which
        prepare and are prepared by the same policies: S and G are rotation
        invariant) only the first met approaches. Cached per goal."""
        g = np.asarray(goal, dtype=float)
        key = (*(float(v) for v in g), math.inf)
        got = self._terminals.get(key)
        if got is None:
            lib = self.library
            every = self._regulators(g, every_size=True) + self._shift_terminals(g, every=True)
            first: dict[tuple[float, float, int], int] = {}
            kept = []
            for term in every:
                a = term.approach
                xy = lib.start_xy[a]
                which = (float(xy[0]), float(xy[1]), int(lib.palette_index[a]))
                if first.setdefault(which, a) == a:
                    kept.append(term)
            got = tuple(kept)
            self._terminals[key] = got
        return got

    def _graceful(self, g: FloatArray, regulators: tuple[Terminal, ...]) -> tuple[Terminal, ...]:
        """``regulators`` with each one replaced by the best shift terminal from the same
        approach trim where one reaches the goal: the way to the goal is the same, and
        the task ends without the regulator's step of the reference (up to the
        regulator's S, 0.2 m and more), the shifts' reference moving on to the grid
        point next to the goal and a regulator there stepping by at most the grid's
        half diagonal (:meth:`Capture.shift_terminals`)."""
        by_approach: dict[int, Terminal] = {}
        for term in self._shift_terminals(g):
            by_approach.setdefault(term.approach, term)
        return tuple(by_approach.get(t.approach, t) for t in regulators)

    def _shift_terminals(self, g: FloatArray, *, every: bool = False) -> tuple[Terminal, ...]:
        capture = capture_for(self.library)
        return capture.shift_terminals(g, every=every) if capture.available else ()

    def _regulators(self, g: FloatArray, *, every_size: bool) -> tuple[TerminalPolicy, ...]:
        """Terminal regulators at ``g``: of the largest size that fits with a rest trim's
        G in its S, or (``every_size``) of every size that fits."""
        lib = self.library
        clearance = float(lib.world_map.clearance(g[None, :2])[0]) - lib.footprint_radius
        rest = lib.trim_indices(PrimitiveKind.REST)
        out: list[TerminalPolicy] = []
        regs = sorted(
            (p for p in self.palette.policies if p.capture),
            key=lambda p: -p.start_radii.position,
        )
        for reg in regs:
            reach = reg.outer_factors[0] * reg.start_radii.position
            if clearance < reach:
                continue
            ends = lib.end_state[rest]
            dist = np.linalg.norm(ends[:, :2] - g[:2], axis=1)
            near = np.flatnonzero(dist <= reg.start_radii.position)
            near = near[np.lexsort((lib.durations[rest[near]], dist[near]))]
            for i in rest[near]:
                term = TerminalPolicy(reg, 0.0, g[:2].copy(), int(i))
                if term.start_domain.contains_domain(lib.policy(int(i)).goal_domain):
                    out.append(term)
            if out and not every_size:
                break
        return tuple(out)
