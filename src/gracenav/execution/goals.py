"""Goals of a task on a library: the trim policy a task ends on, and for a goal at rest
off the lattice the terminal regulator placed there (a capture regulator whose S holds
the G of a rest trim of the library)."""

from __future__ import annotations

import weakref

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError, PlanningError
from gracenav.execution.capture import TerminalPolicy
from gracenav.library import PolicyLibrary, quarter_turn
from gracenav.policies import PrimitiveKind

__all__ = ["Goals"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Distance (m, m/s) within which a goal counts as the end state of a lattice trim.
_ON_LATTICE = 1e-9

#: Terminal regulators by goal (:meth:`HybridController.terminal_policies`) of each
#: library: they depend on the library and the goal only, so every controller on the same
#: library (a scenario's runs, a campaign's trials) shares them, as long as it lives.
_TERMINALS: weakref.WeakKeyDictionary[
    PolicyLibrary, dict[tuple[float, ...], tuple[TerminalPolicy, ...]]
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
        contains, the rest trim the task ends on before the terminal regulator at the
        goal takes over (:meth:`terminal_policies`).

        Raises
        ------
        PlanningError
            If the goal is outside the map, in an obstacle (grown by the footprint), or
            no trim policy's goal domain contains it and no terminal regulator fits
            there (outside coverage).
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
        trims = self.library.trim_indices()
        ends = self.library.end_state[trims]
        candidates = []
        # Nearest first; among equally near trims (a rest trim and the longer capture
        # trim end at the same state) the shortest, so a task does not end on a hold
        # longer than it needs.
        order = np.lexsort((self.library.durations[trims], np.linalg.norm(ends - g, axis=1)))
        near = trims[order][:64]
        inside = np.flatnonzero(self.goal_domains_contain(near, g))
        if inside.size:
            candidates.append(int(near[inside[0]]))
        at_rest = bool(np.all(g[2:] == 0.0))
        exact = bool(candidates) and bool(
            np.linalg.norm(self.library.end_state[candidates[0]] - g) <= _ON_LATTICE
        )
        if candidates and (exact or not at_rest):
            return candidates[0]
        # A goal at rest off the lattice: a terminal regulator brings the robot onto it;
        # without one, the trim whose G contains it (within G's extent of the goal).
        terminals = self.terminal_policies(g) if at_rest else ()
        if terminals:
            return terminals[0].approach
        if candidates:
            return candidates[0]
        where = ", ".join(f"{v:g}" for v in g)
        if np.all(g[2:] == 0.0):
            raise PlanningError(
                f"goal ({where}) is outside coverage: no trim policy of the library has it in "
                "its goal domain and no capture regulator fits there (it needs a clearance of "
                "the footprint plus its outer domain radius, and a rest trim of the library "
                "within its start domain); move the goal away from obstacles or use more "
                "lattice halvings"
            )
        raise PlanningError(
            f"goal ({where}) is outside coverage: a moving goal must be a cruise trim of the "
            "library (on the instantiation lattice, at a trim velocity, away from obstacles)"
        )

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

    def terminal(self, goal: ArrayLike, goal_id: int) -> TerminalPolicy | None:
        """The terminal regulator a task toward ``goal`` ends with, if ``goal_id`` is the
        approach trim :meth:`goal_policy` chose for it."""
        terms = self._terminals.get(tuple(float(v) for v in np.asarray(goal, dtype=float)))
        for term in terms or ():
            if term.approach == goal_id:
                return term
        return None

    def terminal_policies(self, goal: ArrayLike) -> tuple[TerminalPolicy, ...]:
        """Terminal regulators for a goal at rest off the lattice, best first.

        For each capture regulator of the palette, largest first, whose outer domain
        (a disc of radius ``outer_factors[0]`` × e_p(S) around the goal, not shrinking)
        grown by the footprint is clear of obstacles: every rest trim of the library
        whose G lies in the regulator's S at the goal (exact ellipsoid containment),
        nearest first. Empty when the palette has no regulators or none fits.
        """
        g = np.asarray(goal, dtype=float)
        key = tuple(float(v) for v in g)
        got = self._terminals.get(key)
        if got is not None:
            return got
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
            if out:
                break
        result = tuple(out)
        self._terminals[key] = result
        return result
