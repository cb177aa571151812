"""Moving and new obstacles: sensing, invalidating policies, and repairing the tree.

The paper's single-goal tree "allows real-time regeneration ... needed to account for
changing goals and dynamic obstacles" (Sec. V). Here the library stays as it was built
on the static map; an obstacle the robot learns of takes policies *out* of it, and the
tree is repaired rather than searched again.

**Sensing.** Every :attr:`ObstacleSensing.period` (s) of episode time the hybrid
controller looks at every present moving obstacle; one whose edge is within
:attr:`ObstacleSensing.range` (m) of the robot is *known*, with its true position and
velocity (a perfect sensor with a limited range). Out of range, or gone, it is
forgotten: that is how a doorway that clears becomes passable again.

**Invalidation.** A known obstacle at c moving at velocity u is predicted to sweep the
capsule from c to c + u·(T + period) over the next T + period seconds; policy i (of
duration T) is *blocked* if its swept D' (the reference position of every sample of
its duration, grown by the position extent of D'(t)) grown by the footprint comes
within the obstacle's radius plus :attr:`ObstacleSensing.margin` of that capsule. The
test is conservative: it takes the whole capsule against the whole sweep, regardless of
when each is reached, and the samples are :data:`SWEEP_STEP` (m) apart along the
reference, so half a step is added to the margin. A policy is judged when it is started
and again every period while it runs.

**Repair.** Edges cost their source policy's execution (:class:`PreparesGraph`), so the
tree is ``cost_to_go[i] = c_i + min over unblocked successors j of cost_to_go[j]``.
:func:`repair_tree` updates the previous tree for the policies that became blocked and
those that became free, and touches only what changes: every policy whose tree path ran
through a newly blocked one (found by walking the tree's children, O(affected)) loses
its cost; each of those and each newly freed policy is seeded with the best of its
unblocked successors; a Dijkstra over the reversed graph from these seeds then raises
and lowers exactly the costs that change (a policy is pushed again only when its cost
drops). The result has the costs of a full search on the graph without the blocked
policies (a test compares them with :func:`gracenav.planning.plan_tree` on random
blockings), and the same next policies whenever no two successors tie."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from gracenav.planning import PolicyTree
from gracenav.world.moving import MovingObstacle

__all__ = [
    "HOLD_HORIZON",
    "HOLD_MARGIN",
    "SWEEP_STEP",
    "KnownObstacle",
    "ObstacleSensing",
    "ReplanEvent",
    "SweptDomains",
    "blocked_policies",
    "repair_tree",
    "sense",
]

FloatArray = NDArray[np.float64]

IntArray = NDArray[np.int64]

BoolArray = NDArray[np.bool_]

SWEEP_STEP = 0.05
"""Largest distance (m) between two samples of a swept D' along its reference."""

HOLD_HORIZON = 6.0
"""Where the robot waits (a rest trim, or balancing mode's point) must stay clear of
every known obstacle's predicted motion over this time (s), not only over the policy's
duration: a rest trim is held for as long as the way stays blocked. 6 s: a person at
walking speed crosses a 5 m corridor in that time."""

HOLD_MARGIN = 0.25
"""Extra clearance (m) of balancing mode's point from the obstacles' predicted motion:
balancing mode is not verified, and a robot caught moving overshoots its point by a
few decimetres."""


@dataclass(frozen=True)
class ObstacleSensing:
    """How the hybrid controller learns of moving obstacles.

    Attributes
    ----------
    range : float
        Sensing range (m) from the robot's centre to an obstacle's edge. 3 m: what a
        planar lidar or depth camera on a person-height robot sees reliably indoors.
    period : float
        Time (s) between two looks; the obstacles' motion over a period is added to
        their predicted sweep. 0.1 s: a 10 Hz sensor.
    margin : float
        Extra clearance (m) kept from a known obstacle, beyond the footprint.
    """

    range: float = 3.0
    period: float = 0.1
    margin: float = 0.05

    def __post_init__(self) -> None:
        for name in ("range", "period"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if not (math.isfinite(self.margin) and self.margin >= 0.0):
            raise ValueError(f"margin must be >= 0 and finite, got {self.margin!r}")


@dataclass(frozen=True)
class KnownObstacle:
    """What the robot knows of an obstacle at one time: centre (m), velocity (m/s) and
    radius (m), and which scenario obstacle it is."""

    index: int
    center: tuple[float, float]
    velocity: tuple[float, float]
    radius: float


@dataclass(frozen=True)
class ReplanEvent:
    """One repair of the tree.

    Attributes
    ----------
    time : float
        Episode time (s).
    reason : str
        ``obstacle_sensed`` (a new obstacle is known), ``obstacle_moved`` (a known
        one moved: the blocked set changed), ``obstacle_cleared`` (one was forgotten and
        policies became free), ``policy_left`` (a policy the robot left too often is set
        aside, :attr:`gracenav.execution.ExecutionOptions.set_aside_exits`); for the
        decoupled baseline (:mod:`gracenav.baseline`), ``tracking_error`` (a new
        geometric plan from the measured state).
    latency_s : float
        Wall time of invalidation and repair (s).
    blocked : int
        Policies blocked after it.
    changed : int
        Policies whose cost-to-go changed.
    """

    time: float
    reason: str
    latency_s: float
    blocked: int
    changed: int


def sense(
    obstacles: Sequence[MovingObstacle], xy: FloatArray, t: float, sensing: ObstacleSensing
) -> tuple[KnownObstacle, ...]:
    """The obstacles present at time ``t`` whose edge is within the sensing range of the
    robot at ``xy``."""
    out = []
    for k, ob in enumerate(obstacles):
        if not bool(ob.present(t)):
            continue
        c = ob.position(t)
        if float(np.linalg.norm(c - xy)) - ob.radius <= sensing.range:
            v = ob.velocity(t)
            out.append(
                KnownObstacle(k, (float(c[0]), float(c[1])), (float(v[0]), float(v[1])), ob.radius)
            )
    return tuple(out)


@dataclass
class SweptDomains:
    """Each palette policy's swept D' in its own frame, sampled along its reference.

    Attributes
    ----------
    points : list of ndarray, shape (k, 2)
        Reference positions (m), at most :data:`SWEEP_STEP` apart.
    radii : list of ndarray, shape (k,)
        Position extent of D' at those samples (m).
    durations : ndarray, shape (P,)
        (s)
    reach : float
        Largest distance from a policy's start to its swept D' edge (m): rows farther
        than this plus the obstacle's reach from an obstacle cannot be blocked by it.
    """

    points: list[FloatArray]
    radii: list[FloatArray]
    durations: FloatArray
    reach: float
    _flat: tuple[IntArray, FloatArray, FloatArray, FloatArray] | None = field(
        default=None, repr=False
    )

    def flat(self) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
        """The samples of all policies in one array each: pointers (P + 1,), points
        (K, 2), radii (K,), and each policy's reach from its start (P,)."""
        got = self._flat
        if got is None:
            sizes = np.array([len(r) for r in self.radii], dtype=np.int64)
            ptr = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
            pts = np.ascontiguousarray(np.concatenate(self.points), dtype=float)
            rad = np.ascontiguousarray(np.concatenate(self.radii), dtype=float)
            reach = np.array(
                [
                    float(np.max(np.linalg.norm(p, axis=1) + r))
                    for p, r in zip(self.points, self.radii, strict=True)
                ]
            )
            got = (ptr, pts, rad, reach)
            self._flat = got
        return got

    @classmethod
    def of_palette(cls, palette: Any) -> SweptDomains:
        """Sample every palette policy's D' (about :data:`SWEEP_STEP` apart)."""
        points, radii, durs = [], [], []
        reach = 0.0
        for pol in palette.policies:
            prim = pol.primitive
            pos = np.asarray(prim.position[:, :2], dtype=float)
            step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
            cum = np.concatenate(([0.0], np.cumsum(step)))
            n = max(2, math.ceil(cum[-1] / SWEEP_STEP) + 1)
            # Sample every tick where the reference moves slowly, else by arc length:
            # take the ticks nearest to n equally spaced arc lengths plus both ends.
            idx = np.unique(
                np.concatenate(
                    ([0, pos.shape[0] - 1], np.searchsorted(cum, np.linspace(0, cum[-1], n)))
                )
            )
            idx = idx[idx < pos.shape[0]]
            t = idx * prim.dt
            rp, _ = pol.outer_extents(t)
            rp = np.broadcast_to(np.asarray(rp, dtype=float), t.shape).copy()
            points.append(pos[idx])
            radii.append(rp)
            durs.append(pol.duration)
            reach = max(reach, float(np.max(np.linalg.norm(pos[idx], axis=1) + rp)))
        return cls(points, radii, np.asarray(durs, dtype=float), reach)


def blocked_policies(
    library: Any,
    swept: SweptDomains,
    known: Sequence[KnownObstacle],
    *,
    footprint: float,
    sensing: ObstacleSensing,
) -> BoolArray:
    """Library rows whose swept D', grown by ``footprint``, comes within an obstacle's
    radius plus the margin of its predicted capsule (see the module notes). Compiled:
    each row is first tested by its start point against the capsule grown by the
    largest reach of its palette policy, then sample by sample."""
    n = len(library)
    out = np.zeros(n, dtype=bool)
    if not known:
        return out
    flat = swept.flat()
    for ob in known:
        _block_kernel(
            library.start_xy,
            library.palette_index,
            library.orientation,
            flat[0],
            flat[1],
            flat[2],
            flat[3],
            swept.durations,
            float(ob.center[0]),
            float(ob.center[1]),
            float(ob.velocity[0]),
            float(ob.velocity[1]),
            sensing.period,
            ob.radius + footprint + sensing.margin + 0.5 * SWEEP_STEP,
            out,
        )
    return out


@njit(cache=True, nogil=True)
def _capsule_distance(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    dx, dy = bx - ax, by - ay
    den = dx * dx + dy * dy
    s = 0.0
    if den > 0.0:
        s = ((px - ax) * dx + (py - ay) * dy) / den
        s = min(max(s, 0.0), 1.0)
    ex, ey = px - ax - s * dx, py - ay - s * dy
    return math.sqrt(ex * ex + ey * ey)


@njit(cache=True, nogil=True)
def _block_kernel(
    start: Any,
    pal: Any,
    orient: Any,
    ptr: Any,
    pts: Any,
    rad: Any,
    reach: Any,
    durations: Any,
    cx: float,
    cy: float,
    ux: float,
    uy: float,
    period: float,
    grow: float,
    out: Any,
) -> None:
    for i in range(start.shape[0]):
        if out[i]:
            continue
        p = pal[i]
        h = durations[p] + period
        bx, by = cx + ux * h, cy + uy * h
        sx, sy = start[i, 0], start[i, 1]
        if _capsule_distance(sx, sy, cx, cy, bx, by) > reach[p] + grow:
            continue
        k = orient[i]
        for e in range(ptr[p], ptr[p + 1]):
            lx, ly = pts[e, 0], pts[e, 1]
            # Exact quarter turns (library.quarter_turn): k · 90° counter-clockwise.
            if k == 0:
                wx, wy = lx, ly
            elif k == 1:
                wx, wy = -ly, lx
            elif k == 2:
                wx, wy = -lx, -ly
            else:
                wx, wy = ly, -lx
            if _capsule_distance(sx + wx, sy + wy, cx, cy, bx, by) - rad[e] < grow:
                out[i] = True
                break


def _segment_distance(points: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance from each point (N, 2) to the segment from ``a`` to ``b``."""
    ab = b - a
    den = float(ab @ ab)
    if den == 0.0:
        return np.asarray(np.linalg.norm(points - a, axis=1))
    s = np.clip((points - a) @ ab / den, 0.0, 1.0)
    return np.asarray(np.linalg.norm(points - (a + s[:, None] * ab), axis=1))


def repair_tree(
    tree: PolicyTree,
    graph: Any,
    was_blocked: BoolArray,
    blocked: BoolArray,
) -> tuple[PolicyTree, int]:
    """The tree of the graph without the ``blocked`` policies, from ``tree``, the tree
    of the graph without the ``was_blocked`` ones (see the module notes).

    Returns
    -------
    tree : PolicyTree
        A new tree (the input is not modified).
    changed : int
        Policies whose cost-to-go changed.
    """
    cost = tree.criterion.value
    fwd = graph.csr(cost)
    rev = graph.csc(cost)
    node_cost = np.ascontiguousarray(graph.node_cost(cost), dtype=np.float64)
    dist = tree.cost_to_go.copy()
    nxt = tree.next_policy.copy()
    blocked = np.ascontiguousarray(blocked, dtype=np.bool_)
    newly = np.flatnonzero(blocked & ~was_blocked).astype(np.int64)
    freed = np.flatnonzero(~blocked & was_blocked).astype(np.int64)
    changed = _repair(
        fwd.indptr,
        fwd.indices,
        rev.indptr,
        rev.indices,
        node_cost,
        int(tree.goal),
        blocked,
        newly,
        freed,
        dist,
        nxt,
    )
    return (
        PolicyTree(goal=tree.goal, next_policy=nxt, cost_to_go=dist, criterion=tree.criterion),
        int(changed),
    )


@njit(cache=True, nogil=True)
def _better(dj: float, j: int, dk: float, k: int) -> bool:
    """Tie rule of :mod:`gracenav.planning`: smaller cost-to-go, then smaller index."""
    return dj < dk or (dj == dk and j < k)


@njit(cache=True, nogil=True)
def _repair(
    f_ptr: Any,
    f_idx: Any,
    r_ptr: Any,
    r_idx: Any,
    c: Any,
    goal: int,
    blocked: Any,
    newly: Any,
    freed: Any,
    dist: Any,
    nxt: Any,
) -> int:
    n = dist.size
    old = dist.copy()
    # Children of each policy in the tree (counting sort of nxt).
    count = np.zeros(n + 1, np.int64)
    for i in range(n):
        if nxt[i] >= 0:
            count[nxt[i] + 1] += 1
    for i in range(n):
        count[i + 1] += count[i]
    child = np.empty(count[n], np.int64)
    fill = count[:n].copy()
    for i in range(n):
        j = nxt[i]
        if j >= 0:
            child[fill[j]] = i
            fill[j] += 1
    # Raise: every policy whose tree path runs through a newly blocked one.
    affected = np.zeros(n, np.bool_)
    stack = np.empty(n, np.int64)
    top = 0
    for q in range(newly.size):
        b = newly[q]
        if not affected[b]:
            affected[b] = True
            stack[top] = b
            top += 1
    while top > 0:
        top -= 1
        j = stack[top]
        dist[j] = np.inf
        nxt[j] = -1
        for e in range(count[j], count[j + 1]):
            i = child[e]
            if not affected[i]:
                affected[i] = True
                stack[top] = i
                top += 1
    # Seeds: affected and freed policies, from their best unblocked successor.
    heap_key = np.empty(n + 1, np.float64)
    heap_node = np.empty(n + 1, np.int64)
    size = 0
    cap = n + 1
    if blocked[goal]:
        for i in range(n):
            dist[i] = np.inf
            nxt[i] = -1
    else:
        if affected[goal] or dist[goal] != 0.0:
            dist[goal] = 0.0
            nxt[goal] = -1
        for phase in range(2):
            src = np.flatnonzero(affected) if phase == 0 else freed
            for q in range(src.size):
                i = src[q]
                if blocked[i] or i == goal:
                    continue
                best = np.inf
                bj = -1
                for e in range(f_ptr[i], f_ptr[i + 1]):
                    j = f_idx[e]
                    if blocked[j] or not dist[j] < np.inf:
                        continue
                    d = c[i] + dist[j]
                    if d < best or (d == best and _better(dist[j], j, dist[bj], bj)):
                        best = d
                        bj = j
                if bj >= 0 and (best < dist[i] or (best == dist[i] and nxt[i] != bj)):
                    dist[i] = best
                    nxt[i] = bj
                    if size >= cap:
                        heap_key, heap_node, cap = _grow(heap_key, heap_node, cap)
                    size = _push(heap_key, heap_node, size, best, i)
        # Blocked policies have no cost (those not on any old path included).
        for i in range(n):
            if blocked[i]:
                dist[i] = np.inf
                nxt[i] = -1
        if not blocked[goal] and freed.size > 0:
            for q in range(freed.size):  # a freed goal is the source again
                if freed[q] == goal:
                    if size >= cap:
                        heap_key, heap_node, cap = _grow(heap_key, heap_node, cap)
                    size = _push(heap_key, heap_node, size, 0.0, goal)
        while size > 0:
            dj = heap_key[0]
            j = heap_node[0]
            size = _pop(heap_key, heap_node, size)
            if dj > dist[j]:
                continue  # stale entry
            for e in range(r_ptr[j], r_ptr[j + 1]):
                i = r_idx[e]
                if blocked[i] or i == goal:
                    continue
                d = c[i] + dj
                if d < dist[i]:
                    dist[i] = d
                    nxt[i] = j
                    if size >= cap:
                        heap_key, heap_node, cap = _grow(heap_key, heap_node, cap)
                    size = _push(heap_key, heap_node, size, d, i)
                elif d == dist[i] and nxt[i] != j and nxt[i] >= 0:
                    if _better(dj, j, dist[nxt[i]], nxt[i]):
                        nxt[i] = j
    changed = 0
    for i in range(n):
        if not (dist[i] == old[i] or (dist[i] != dist[i] and old[i] != old[i])):
            changed += 1
    return changed


@njit(cache=True, nogil=True)
def _grow(keys: Any, nodes: Any, cap: int) -> Any:
    k2 = np.empty(2 * cap, np.float64)
    n2 = np.empty(2 * cap, np.int64)
    k2[:cap] = keys
    n2[:cap] = nodes
    return k2, n2, 2 * cap


@njit(cache=True, nogil=True)
def _push(keys: Any, nodes: Any, size: int, key: float, node: int) -> int:
    i = size
    keys[i] = key
    nodes[i] = node
    while i > 0:
        parent = (i - 1) // 2
        if keys[parent] <= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        nodes[parent], nodes[i] = nodes[i], nodes[parent]
        i = parent
    return size + 1


@njit(cache=True, nogil=True)
def _pop(keys: Any, nodes: Any, size: int) -> int:
    size -= 1
    keys[0] = keys[size]
    nodes[0] = nodes[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        m = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            m = left + 1
        if keys[i] <= keys[m]:
            break
        keys[i], keys[m] = keys[m], keys[i]
        nodes[i], nodes[m] = nodes[m], nodes[i]
        i = m
    return size


def timed_repair(
    tree: PolicyTree,
    graph: Any,
    library: Any,
    swept: SweptDomains,
    known: Sequence[KnownObstacle],
    was_blocked: BoolArray,
    *,
    footprint: float,
    sensing: ObstacleSensing,
) -> tuple[PolicyTree, BoolArray, float, int]:
    """Invalidate and repair; returns the tree, the blocked mask, the wall time (s)
    and the number of policies whose cost changed."""
    t0 = time.perf_counter()
    blocked = blocked_policies(library, swept, known, footprint=footprint, sensing=sensing)
    if np.array_equal(blocked, was_blocked):
        return tree, blocked, time.perf_counter() - t0, 0
    new, changed = repair_tree(tree, graph, was_blocked, blocked)
    return new, blocked, time.perf_counter() - t0, changed


def _warm_up(library: Any, graph: Any, swept: SweptDomains) -> None:
    """Run the compiled kernels once on this library's and graph's own arrays (numba
    compiles one version per dtype and per read-only flag): an obstacle out of reach
    of every policy, and a repair that changes nothing."""
    n = len(library)
    out = np.zeros(n, dtype=bool)
    ptr, pts, rad, reach = swept.flat()
    far = 1e9
    _block_kernel(
        library.start_xy,
        library.palette_index,
        library.orientation,
        ptr,
        pts,
        rad,
        reach,
        swept.durations,
        far,
        far,
        0.0,
        0.0,
        0.1,
        0.5,
        out,
    )
    fwd, rev = graph.csr("time"), graph.csc("time")
    none = np.zeros(0, dtype=np.int64)
    _repair(
        fwd.indptr,
        fwd.indices,
        rev.indptr,
        rev.indices,
        np.ascontiguousarray(graph.node_cost("time"), dtype=np.float64),
        0,
        out,
        none,
        none,
        np.zeros(n),
        np.full(n, -1, dtype=np.int64),
    )
