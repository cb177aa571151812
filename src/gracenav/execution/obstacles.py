"""The hybrid controller's view of moving obstacles during a run: what it has seen within
its sensing range, which policies that blocks, the repaired tree and the replan log
(:class:`ObstacleTracker`); a look can be computed away from the control loop
(:meth:`ObstacleTracker.look`) and adopted later (:meth:`ObstacleTracker.apply`)."""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from gracenav.errors import ConfigError
from gracenav.planning import LazyPolicyTree, PolicyTree
from gracenav.planning import graph as _graph
from gracenav.planning.repair import (
    HOLD_HORIZON,
    BoolArray,
    FloatArray,
    KnownObstacle,
    ObstacleSensing,
    ReplanEvent,
    SweptDomains,
    _segment_distance,
    _warm_up,
    repair_tree,
    sense,
    timed_repair,
)
from gracenav.world.moving import MovingObstacle

if TYPE_CHECKING:
    from gracenav.library import PolicyLibrary

__all__ = ["Look"]


def _whole(tree: PolicyTree | LazyPolicyTree) -> PolicyTree:
    """``tree`` if it is a whole tree; the repair cannot start from a lazy one."""
    if isinstance(tree, LazyPolicyTree):
        raise ConfigError(
            f"moving obstacles need the whole single-goal tree, and on this graph "
            f"({tree.graph.num_edges} edges, above gracenav.planning.graph.STORED_EDGES = "
            f"{_graph.STORED_EDGES}) the hybrid controller computes it lazily: run tasks with "
            "moving obstacles on a smaller map or region (one library per region), or "
            "without moving obstacles"
        )
    return tree


@dataclass(frozen=True)
class Look:
    """One look at the moving obstacles (:meth:`ObstacleTracker.look`).

    Attributes
    ----------
    time : float
        When it looked (s).
    known : tuple of KnownObstacle
    tree : PolicyTree
        The tree repaired for what it saw.
    blocked : ndarray of bool, shape (len(library),)
    latency : float
        Wall time of the repair (s).
    changed : int
        Policies whose cost-to-go changed.
    """

    time: float
    known: tuple[KnownObstacle, ...]
    tree: PolicyTree
    blocked: BoolArray
    latency: float
    changed: int


#: Each library's swept D' (:meth:`SweptDomains.of_palette` of its palette), shared by
#: every tracker on the library and kept as long as the library lives.
_SWEPT: weakref.WeakKeyDictionary[PolicyLibrary, SweptDomains] = weakref.WeakKeyDictionary()

#: The libraries a tracker has run the replan kernels on once (:func:`_warm_up`).
_WARM: weakref.WeakSet[PolicyLibrary] = weakref.WeakSet()


class ObstacleTracker:
    """The hybrid controller's view of the moving obstacles during one run: what it
    knows, which policies that blocks, the repaired tree, and the replan log.

    Parameters
    ----------
    library, graph
        The controller's.
    obstacles : sequence of MovingObstacle
        The scenario's (their true motion; the tracker only looks within range).
    sensing : ObstacleSensing
    """

    def __init__(
        self,
        library: Any,
        graph: Any,
        obstacles: Sequence[MovingObstacle],
        sensing: ObstacleSensing,
    ) -> None:
        self.library = library
        self.graph = graph
        self.obstacles = tuple(obstacles)
        self.sensing = sensing
        swept = _SWEPT.get(library)
        if swept is None:
            swept = _SWEPT[library] = SweptDomains.of_palette(library.palette)
        self.swept: SweptDomains = swept
        self.blocked: BoolArray = np.zeros(len(library), dtype=bool)
        self.known: tuple[KnownObstacle, ...] = ()
        if library not in _WARM:
            # Compile (or load) the kernels outside the timed replans.
            _warm_up(library, graph, swept)
            _WARM.add(library)
        self.next_time = 0.0
        self.replans: list[ReplanEvent] = []

    @property
    def footprint(self) -> float:
        """The robot's footprint radius (m)."""
        return float(self.library.footprint_radius)

    def ticks_to_next(self, t: float, dt: float) -> int:
        """Control ticks until the next look (at least 1)."""
        return max(1, math.ceil((self.next_time - t) / dt - 1e-9))

    def due(self, t: float) -> bool:
        """Whether it is time to look again."""
        return t >= self.next_time - 1e-9

    def update(self, t: float, xy: FloatArray, tree: PolicyTree | LazyPolicyTree) -> PolicyTree:
        """Look at time ``t`` from ``xy``, block and free policies, repair ``tree``
        (the tree without the previously blocked policies) and log the replan:
        :meth:`look` and :meth:`apply` at once.

        Raises
        ------
        ConfigError
            If ``tree`` is a :class:`LazyPolicyTree`: the repair needs a whole tree.
        """
        self.next_time = t + self.sensing.period
        return self.apply(self.look(t, xy, tree))

    def look(self, t: float, xy: FloatArray, tree: PolicyTree | LazyPolicyTree) -> Look:
        """What a look at time ``t`` from ``xy`` sees and the tree repaired for it,
        without changing the tracker (a worker thread may compute it while the
        controller runs; :meth:`apply` adopts it).

        Raises
        ------
        ConfigError
            If ``tree`` is a :class:`LazyPolicyTree`: the repair needs a whole tree.
        """
        tree = _whole(tree)
        known = sense(self.obstacles, xy, t, self.sensing)
        new, blocked, latency, changed = timed_repair(
            tree,
            self.graph,
            self.library,
            self.swept,
            known,
            self.blocked,
            footprint=self.footprint,
            sensing=self.sensing,
        )
        return Look(t, known, new, blocked, latency, changed)

    def apply(self, look: Look) -> PolicyTree:
        """Adopt a :meth:`look`: the known obstacles and blocked policies, the replan
        log; returns its repaired tree."""
        before = {k.index for k in self.known}
        self.known = look.known
        if not np.array_equal(look.blocked, self.blocked):
            now = {k.index for k in look.known}
            reason = (
                "obstacle_sensed"
                if now - before
                else "obstacle_cleared"
                if before - now
                else "obstacle_moved"
            )
            self.replans.append(
                ReplanEvent(look.time, reason, look.latency, int(look.blocked.sum()), look.changed)
            )
        self.blocked = look.blocked
        return look.tree

    def retarget(self, tree: PolicyTree | LazyPolicyTree) -> PolicyTree:
        """``tree`` (a tree of the whole library, toward a new goal) without the
        currently blocked policies (ConfigError for a lazy tree, as :meth:`update`)."""
        tree = _whole(tree)
        if not np.any(self.blocked):
            return tree
        return repair_tree(tree, self.graph, np.zeros_like(self.blocked), self.blocked)[0]

    def is_blocked(self, row: int) -> bool:
        """Whether library row ``row`` is blocked now."""
        return bool(self.blocked[row])

    def disc_blocked(self, center: FloatArray, radius: float, duration: float) -> bool:
        """Whether a disc of D' of ``radius`` (m) held at ``center`` for ``duration``
        (s), grown by the footprint, meets a known obstacle's capsule."""
        for ob in self.known:
            c = np.asarray(ob.center, dtype=float)
            b = c + np.asarray(ob.velocity, dtype=float) * (duration + self.sensing.period)
            d = float(_segment_distance(np.asarray(center, dtype=float)[None, :], c, b)[0])
            if d - radius < ob.radius + self.footprint + self.sensing.margin:
                return True
        return False

    def sweep_blocked(self, points: FloatArray, reach: FloatArray, duration: float) -> bool:
        """Whether discs of radii ``reach`` (m) at ``points`` (k, 2), the swept D' of a
        placed policy (or several run one after another) of ``duration`` (s), grown by
        the footprint, meet a known obstacle's capsule (as :meth:`disc_blocked`)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        rad = np.asarray(reach, dtype=float).reshape(-1)
        for ob in self.known:
            c = np.asarray(ob.center, dtype=float)
            b = c + np.asarray(ob.velocity, dtype=float) * (duration + self.sensing.period)
            need = ob.radius + self.footprint + self.sensing.margin
            if np.any(_segment_distance(pts, c, b) - rad < need):
                return True
        return False

    def hold_clear(self, xy: FloatArray, radius: float) -> bool:
        """Whether a disc of ``radius`` (m) at ``xy`` is clear of every known obstacle's
        motion over :data:`HOLD_HORIZON` (footprint and margin included)."""
        return not self.disc_blocked(np.asarray(xy, dtype=float), radius, HOLD_HORIZON)

    def hold_row_clear(self, row: int) -> bool:
        """Whether rest trim ``row`` may be held (:meth:`hold_clear` of its D')."""
        pol = self.library.policy(int(row)).policy
        rad = float(np.max(pol.outer_extents(np.array([0.0, pol.duration]))[0]))
        return self.hold_clear(self.library.start_xy[int(row)], rad)

    def hold_policy(self, p: FloatArray) -> int:
        """Where the robot waits while the way is blocked: among the unblocked policies
        whose S contains ``p``, a rest trim that may be held (:meth:`hold_row_clear`),
        the one whose start is nearest; else a maneuver that ends at rest at a point
        that may be held, the shortest; else −1."""
        from gracenav.policies import PrimitiveKind

        lib = self.library
        hits = lib.start_domain_contains(np.asarray(p, dtype=float)[None, :])
        idx = hits.indices[hits.indptr[0] : hits.indptr[1]]
        idx = idx[~self.blocked[idx]]
        if idx.size == 0:
            return -1
        rest = np.isin(idx, lib.trim_indices(PrimitiveKind.REST))
        trims = [int(i) for i in idx[rest] if self.hold_row_clear(int(i))]
        if trims:
            d = np.linalg.norm(lib.start_xy[trims] - np.asarray(p[:2], dtype=float), axis=1)
            return trims[int(np.argmin(d))]
        ends = lib.end_state[idx]
        stops = idx[~rest & np.all(ends[:, 2:] == 0.0, axis=1)]
        stops = stops[np.argsort(lib.durations[stops], kind="stable")]
        for i in stops:
            if self.hold_clear(lib.end_state[int(i), :2], 0.0):
                return int(i)
        return -1

    def points_clear(self, points: FloatArray, radius: float) -> BoolArray:
        """Whether each disc of ``radius`` (m) at ``points`` (k, 2) is clear of every
        known obstacle's motion over :data:`HOLD_HORIZON` (footprint and margin
        included)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        ok = np.ones(pts.shape[0], dtype=bool)
        for ob in self.known:
            c = np.asarray(ob.center, dtype=float)
            b = c + np.asarray(ob.velocity, dtype=float) * (HOLD_HORIZON + self.sensing.period)
            need = ob.radius + self.footprint + self.sensing.margin + radius
            ok &= _segment_distance(pts, c, b) >= need
        return ok

    def path_clear(self, start: FloatArray, points: FloatArray, radius: float) -> bool:
        """Whether a way from ``start`` through ``points`` (k, 2) keeps discs of
        ``radius`` (m) clear of every known obstacle's motion over
        :data:`HOLD_HORIZON`, or for a robot already nearer than that, never nearer
        than it is at ``start``."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        here = np.asarray(start, dtype=float).reshape(1, 2)
        for ob in self.known:
            c = np.asarray(ob.center, dtype=float)
            b = c + np.asarray(ob.velocity, dtype=float) * (HOLD_HORIZON + self.sensing.period)
            need = ob.radius + self.footprint + self.sensing.margin + radius
            need = min(need, float(_segment_distance(here, c, b)[0]))
            if np.any(_segment_distance(pts, c, b) < need):
                return False
        return True
