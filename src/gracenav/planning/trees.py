"""Planning in motion policy space (paper Sec. IV-B): the single-goal optimal tree.

Dijkstra's algorithm runs from the goal policy on the *reversed* gracefully
prepares graph, so one search gives every library policy its optimal next
policy toward the goal and its cost-to-go: no replanning is needed when a
disturbance moves the robot into another policy's domain.

The reversed graph in CSR form is the adjacency matrix in CSC form, reinterpreted:
pass :meth:`gracenav.planning.graph.PreparesGraph.csc` (built once per graph) and a tree costs
only the search; an adjacency in any other form is converted on every call, O(N + E).

The search is a compiled (numba) Dijkstra that uses one property of these graphs: an
edge costs the execution of a policy, and a palette has few distinct durations and path
lengths (33 and 77 for the 219-policy palette) however large the map. With one FIFO
queue per distinct edge cost, each queue receives its keys in increasing order (a key is
the settled cost-to-go, which only grows, plus the queue's constant cost), so a push is
an append and a pop takes the smallest of the queue heads, kept in a binary heap of at
most ``_MAX_QUEUES`` queues (:mod:`gracenav.planning._search`): O(E + N log K) for K
distinct costs instead of O(E + N log N). Measured side by side with
:func:`scipy.sparse.csgraph.dijkstra` on the same arrays (``bench/bench_planning.py``,
medians): 1.8 times faster on the paper's 3.5 m area, 3 times on the 50 m office for
random goals and 1.3 times for goals in its corridors, whose trees span half the library
(there the scan of the edges, random accesses into a 320,000-policy array, dominates).
Graphs with more distinct costs, or whose costs are not those of their source policies
(a policy reached again at a lower cost), are searched with an indexed binary heap
instead: the same costs, and with positive costs the same next policies. Each search
allocates about 17 bytes per policy.

On a graph that stores no edges (:class:`gracenav.planning.graph.PreparesGraph` given instead
of a matrix) the same search generates the edges into each settled policy from the
lattice, in the same order (ascending rows), so the tree is the same; it costs no
memory per edge but about ten times the time (each predecessor is a probe of the
lookup table). For a point-to-point task on a building-scale map, :func:`plan_path`
searches forward from the start with A* instead of building the whole tree.

Equally good next policies are common on a lattice (two paths around a square), and
the tree does not depend on the order in which the search meets them (scipy's Dijkstra
keeps whichever it settles first): ``next_policy[i]`` is, among the successors j with
``cost(i → j) + cost_to_go[j] == cost_to_go[i]`` (floating point, exactly), the one with
the smallest ``cost_to_go[j]``, then the smallest index, whenever every edge cost is
positive (and not lost in rounding: above about 1e-16 times the costs-to-go). With
zero-cost edges (rest trims under the distance criterion) a successor of equal
cost-to-go can be settled after ``i``; the choice is then among the successors settled
before ``i``, which keeps the tree acyclic.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import ConvexHull, QhullError

from gracenav.errors import ConfigError, PlanningError
from gracenav.planning._search import (
    _BUDGET,
    _NEGATIVE,
    _REVISITED,
    _TOO_MANY_COSTS,
    _astar,
    _lazy_settle,
    _points_cost_to_go,
    _search_heap,
    _search_heap_lattice,
    _search_queues,
    _search_queues_lattice,
)
from gracenav.planning.graph import CostCriterion, PreparesGraph

__all__ = [
    "CostCriterion",
    "LazyPolicyTree",
    "PolicyPath",
    "PolicyTree",
    "plan_path",
    "plan_tree",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class PolicyTree:
    """The single-goal optimal tree Γ(Ω, G).

    Attributes
    ----------
    goal : int
        Library index of the goal policy (a trim policy).
    next_policy : ndarray of int, shape (N,)
        The optimal next policy of each library policy toward the goal; −1 for
        the goal itself and for policies from which the goal is unreachable.
    cost_to_go : ndarray, shape (N,)
        Cost (s or m) of executing the policies from each policy up to, not
        including, the goal policy; inf where unreachable.
    criterion : CostCriterion
    """

    goal: int
    next_policy: IntArray
    cost_to_go: FloatArray
    criterion: CostCriterion

    def reachable(self, i: int) -> bool:
        """Whether the goal can be reached from policy ``i``."""
        return bool(np.isfinite(self.cost_to_go[i]))

    def path_from(self, i: int) -> list[int]:
        """Policy indices from ``i`` to the goal, both included.

        Raises
        ------
        PlanningError
            If the goal is unreachable from ``i``.
        """
        if not self.reachable(i):
            raise PlanningError(
                f"the goal policy {self.goal} cannot be reached from library policy {i}"
            )
        return _follow(self.next_policy, int(i), self.goal)


def plan_tree(
    adjacency: scipy.sparse.sparray | scipy.sparse.spmatrix | PreparesGraph,
    goal: int,
    *,
    criterion: CostCriterion | str = CostCriterion.TIME,
) -> PolicyTree:
    """Dijkstra from ``goal`` on the reversed graph.

    Parameters
    ----------
    adjacency : scipy.sparse matrix or array, shape (N, N), or PreparesGraph
        Entry (i, j) is the cost of executing policy i when i gracefully
        prepares j; stored entries are edges, explicit zeros included. In CSC form
        (:meth:`gracenav.planning.graph.PreparesGraph.csc`) its arrays are the reversed graph
        at no cost; any other form (:meth:`gracenav.planning.graph.PreparesGraph.csr`) is
        converted to CSC on every call, O(N + E). A :class:`PreparesGraph` is searched
        on its stored reversed graph for ``criterion`` if it has built one, otherwise
        on edges generated from the lattice (no memory per edge); the tree is the same.
    goal : int
        Library index of the goal policy.
    criterion : CostCriterion or str
        Recorded in the result; the costs themselves come from ``adjacency`` (from the
        graph's policy costs for ``criterion`` when a PreparesGraph is given).

    Returns
    -------
    PolicyTree
        Equally good next policies are chosen as the module notes say.

    Raises
    ------
    ConfigError
        If ``adjacency`` is not square or a stored cost the search meets is negative
        or NaN.
    PlanningError
        If ``goal`` is not a library index.
    """
    crit = CostCriterion(criterion) if isinstance(criterion, str) else criterion
    graph: PreparesGraph | None = None
    matrix: Any = adjacency
    if isinstance(adjacency, PreparesGraph):
        stored = adjacency.cached_csc(crit.value)
        if stored is None:
            graph = adjacency
        else:
            matrix = stored
    if graph is not None:
        n = graph.num_nodes
    else:
        n = matrix.shape[0]
        if matrix.shape != (n, n):
            raise ConfigError(f"adjacency must be square, got {matrix.shape}")
    if not 0 <= goal < n:
        raise PlanningError(f"goal policy index {goal} is outside the library (0..{n - 1})")
    if n >= 2**31 - 1:  # the searches index their queues with int32
        raise ConfigError(f"a tree is searched over fewer than 2**31 - 1 policies, got {n}")
    dist: FloatArray = np.empty(n, dtype=np.float64)
    nxt: IntArray = np.empty(n, dtype=np.int64)
    if graph is not None:
        lattice = graph.lattice_edges.kernel_args()
        type_cost = np.ascontiguousarray(graph.type_cost(crit.value), dtype=np.float64)
        status = _search_queues_lattice(type_cost, int(goal), dist, nxt, *lattice)
        if status in (_TOO_MANY_COSTS, _REVISITED):
            status = _search_heap_lattice(type_cost, int(goal), dist, nxt, *lattice)
    else:
        # Column j of the CSC form lists the policies that prepare j: row j of the
        # reversed graph in CSR form.
        reverse = matrix if matrix.format == "csc" else matrix.tocsc()
        indptr, indices = reverse.indptr, reverse.indices
        weights = np.ascontiguousarray(reverse.data, dtype=np.float64)
        status = _search_queues(indptr, indices, weights, int(goal), dist, nxt)
        if status in (_TOO_MANY_COSTS, _REVISITED):
            status = _search_heap(indptr, indices, weights, int(goal), dist, nxt)
    if status == _NEGATIVE:
        raise ConfigError(
            "adjacency has a negative or NaN edge cost; costs are policy durations (s) "
            "or path lengths (m), both >= 0"
        )
    return PolicyTree(goal=int(goal), next_policy=nxt, cost_to_go=dist, criterion=crit)


@dataclass(frozen=True)
class PolicyPath:
    """An optimal sequence of library policies from a start to a goal policy (A*).

    Attributes
    ----------
    policies : ndarray of int, shape (K,)
        Library rows from the start to the goal policy, both included; empty if the
        goal cannot be reached.
    cost : float
        Cost (s or m) of executing the policies before the goal policy: the tree's
        ``cost_to_go`` of the start, up to rounding; inf if unreachable.
    expanded : int
        Policies the search expanded (a measure of its work).
    criterion : CostCriterion
    """

    policies: IntArray
    cost: float
    expanded: int
    criterion: CostCriterion

    @property
    def reachable(self) -> bool:
        """Whether the goal was reached."""
        return bool(self.policies.size)


def plan_path(
    graph: PreparesGraph,
    start: int | ArrayLike,
    goal: int,
    *,
    criterion: CostCriterion | str = CostCriterion.TIME,
    via: PolicyPath | None = None,
) -> PolicyPath:
    """A* from the start policy (or the cheapest of several) to ``goal`` on the graph's
    edges generated from the lattice: a point-to-point plan without a whole tree.

    The heuristic of a policy is the gauge g(D) = min {λ >= 0 : D ∈ λ P} of the lattice
    displacement D from its start to the goal policy's start, P the convex hull of the
    origin and of o / c for every policy type with successors (o its end offset in
    cells, c its cost). A path of policies with costs c_k covers Σ o_k, and g is
    sublinear with g(o_k) <= c_k, so g(D) is a lower bound of the cost-to-go that grows
    by at most the cost of each edge (consistent): the path is optimal and its cost
    equals the tree's cost-to-go up to rounding. g is at least the straight-line
    distance over the fastest type's cells per unit cost, and larger in directions
    no single type moves in. Where the way detours (walls between start and goal) the
    heuristic is the larger bound of the lattice points: a Dijkstra from the goal's
    point over lattice points (:meth:`PreparesGraph.point_moves`), a point moving by
    the end offset of any type that has a policy there at the cheapest cost of a type
    with that offset, stopped once the start points are settled (the points not
    settled get the cost at which it stopped). Every policy path maps onto such a
    sequence of moves at no more cost, so this bound is consistent too. Both bounds
    are scaled by 1 − 1e-9 to stay below every cost-to-go in floating point. Equally
    good paths are broken by deeper search first, then smaller library rows.

    Parameters
    ----------
    graph : PreparesGraph
    start : int or array_like of int
        Library row(s) of the start policy (e.g. those whose S contains the robot).
    goal : int
        Library row of the goal policy.
    criterion : CostCriterion or str
        Cost of a policy: its duration ("time", s) or path length ("distance", m).
    via : PolicyPath, optional
        An earlier optimal path to ``goal`` (same criterion), e.g. the one a push took
        the robot off: every suffix of it is optimal, so the search stops where joining
        it is cheapest and no open policy can do better (a local replan), and the
        result follows it from there.

    Returns
    -------
    PolicyPath

    Raises
    ------
    PlanningError
        If a start or the goal is not a library index.
    ConfigError
        If a policy cost the search meets is negative or NaN.
    """
    crit = CostCriterion(criterion) if isinstance(criterion, str) else criterion
    n = graph.num_nodes
    starts = np.atleast_1d(np.asarray(start, dtype=np.int64))
    for k in (*starts.tolist(), goal):
        if not 0 <= k < n:
            raise PlanningError(f"policy index {k} is outside the library (0..{n - 1})")
    edges = graph.lattice_edges
    type_cost = np.ascontiguousarray(graph.type_cost(crit.value), dtype=np.float64)
    h_x, h_y = _gauge_facets(edges.offset, type_cost, np.diff(edges.succ_ptr) > 0)
    if via is not None:
        if via.criterion is not crit or not via.reachable or int(via.policies[-1]) != goal:
            raise ConfigError("via must be a reachable path to the same goal policy and criterion")
        steps = type_cost[edges.row_type[via.policies[:-1]]]
        to_go = via.cost - np.concatenate([[0.0], np.cumsum(steps)])
        to_go[-1] = 0.0
        order = np.argsort(via.policies)
        join_rows = np.ascontiguousarray(via.policies[order], dtype=np.int64)
        join_cost = np.ascontiguousarray(np.maximum(to_go[order], 0.0), dtype=np.float64)
    else:
        join_rows = np.array([goal], dtype=np.int64)
        join_cost = np.zeros(1, dtype=np.float64)
    h_point, cut_off = _points_heuristic(graph, type_cost, starts, goal)
    if cut_off == np.unique(edges.row_point[starts]).size:
        # No sequence of the policies' moves leads from a start point to the goal's.
        return PolicyPath(np.zeros(0, np.int64), float("inf"), 0, crit)
    g_cost: FloatArray = np.empty(n, dtype=np.float64)
    parent: IntArray = np.empty(n, dtype=np.int64)
    status, expanded, joined = _astar(
        starts,
        int(goal),
        join_rows,
        join_cost,
        type_cost,
        h_x,
        h_y,
        h_point,
        g_cost,
        parent,
        *edges.kernel_args(),
    )
    if status == _NEGATIVE:
        raise ConfigError(
            "a policy has a negative or NaN cost; costs are policy durations (s) or path "
            "lengths (m), both >= 0"
        )
    if joined < 0:
        return PolicyPath(np.zeros(0, np.int64), float("inf"), int(expanded), crit)
    path = [int(joined)]
    while parent[path[-1]] >= 0:
        path.append(int(parent[path[-1]]))
    prefix = np.array(path[::-1], dtype=np.int64)
    k = int(np.searchsorted(join_rows, joined))
    cost = float(g_cost[joined] + join_cost[k])
    if via is not None and joined != goal:
        at = int(np.flatnonzero(via.policies == joined)[0])
        prefix = np.concatenate([prefix, via.policies[at + 1 :]])
    return PolicyPath(prefix, cost, int(expanded), crit)


def _points_heuristic(
    graph: PreparesGraph,
    type_cost: FloatArray,
    starts: IntArray,
    goal: int,
    *,
    forward: bool = False,
) -> tuple[FloatArray, int]:
    """A lower bound of the cost-to-go of the policies at each lattice point (see
    :func:`plan_path`), or with ``forward`` of the cost from the nearest of ``starts``
    to them (:class:`LazyPolicyTree`); zero everywhere when a cost is negative or NaN
    (the search reports it) or no policy moves. Also returns how many of the target
    points (the start points; forward, the goal's) no sequence of moves reaches."""
    edges = graph.lattice_edges
    ny, nx = edges.lattice_shape
    out: FloatArray = np.zeros(nx * ny, dtype=np.float64)
    mask, move_dx, move_dy, type_move = graph.point_moves()
    if not move_dx.size or not np.all(type_cost >= 0.0):
        return out, 0
    move_cost = np.full(move_dx.size, np.inf)
    moving = type_move >= 0
    np.minimum.at(move_cost, type_move[moving], type_cost[moving])
    goal_point = edges.row_point[np.atleast_1d(goal)].astype(np.int64)
    start_points = edges.row_point[starts].astype(np.int64)
    cut_off = _points_cost_to_go(
        start_points if forward else goal_point,
        goal_point if forward else start_points,
        forward,
        nx,
        ny,
        mask,
        move_dx,
        move_dy,
        move_cost,
        out,
    )
    # The margin of the gauge: the sums above, in another order than the search's,
    # stay below every true cost-to-go despite rounding.
    out *= 1.0 - 1e-9
    return out, int(cut_off)


def _gauge_facets(
    offset: IntArray, type_cost: FloatArray, has_successors: NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray]:
    """Coefficients (h_x, h_y) of the gauge of P (see :func:`plan_path`): one pair per
    edge of P not through the origin, g(D) = max(0, max_f h_x[f] D_x + h_y[f] D_y); none
    (g = 0) when no type with successors both moves and costs something."""
    cells = offset.astype(np.float64)
    use = has_successors & np.any(offset != 0, axis=1) & (type_cost > 0)
    empty = np.zeros(0, dtype=np.float64)
    if np.any(has_successors & np.any(offset != 0, axis=1) & (type_cost <= 0)):
        return empty, empty  # a free move: no positive lower bound
    pts = np.unique(cells[use] / type_cost[use, None], axis=0)
    if pts.shape[0] < 2:
        return empty, empty
    pts = np.concatenate([pts, np.zeros((1, 2))])
    try:
        hull = ConvexHull(pts)
    except QhullError:  # collinear: bound by the farthest point along every direction
        far = float(np.hypot(*pts.T).max())
        ang = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
        return np.cos(ang) * np.cos(np.pi / 64) / far, np.sin(ang) * np.cos(np.pi / 64) / far
    eq = hull.equations  # a x + b y + c <= 0 inside, (a, b) a unit normal
    keep = eq[:, 2] < -1e-12  # edges through the origin bound nothing
    b = -eq[keep, 2]
    # A margin far above rounding keeps the bound below every true cost-to-go.
    margin = 1.0 - 1e-9
    return (
        np.ascontiguousarray(margin * eq[keep, 0] / b),
        np.ascontiguousarray(margin * eq[keep, 1] / b),
    )


class LazyPolicyTree:
    """The single-goal optimal tree Γ(Ω, G), computed only as far as it is read.

    A backward A* from the goal policy over the predecessors (the graph's stored
    reversed graph for the criterion if it has built one, else edges generated from the
    lattice), resumed by every :meth:`settle`. Its key is g + h: g the cost-to-go found
    so far (exact once a policy is *closed*), h a lower bound of the cost from the
    policies asked for (the *queries*) to the policy: the gauge of :func:`plan_path`
    applied to the displacement from the nearest query's start to the policy's start,
    consistent, so each policy closes at its exact cost-to-go. A new call re-keys the
    open policies with its own queries' heuristic and continues: what is closed stays
    closed, so a query on ground already explored costs nothing, and one near it (a
    robot pushed off its path) only the few policies between.

    Closed policies have the cost-to-go of :func:`plan_tree` (the same floating-point
    sums) and, with positive costs, its next policy (among equally good successors the
    smallest cost-to-go, then the smallest row: every such successor closes first);
    with zero costs, a successor closed before the policy (the tree stays acyclic).

    This is mutable search state (unlike :class:`PolicyTree`), owned by one controller.

    Parameters
    ----------
    graph : PreparesGraph
    goal : int
        Library row of the goal policy.
    criterion : CostCriterion or str

    Attributes
    ----------
    goal : int
    criterion : CostCriterion
    cost_to_go : ndarray, shape (N,)
        Cost (s or m) to the goal of each *closed* policy; inf for every other policy
        (not yet closed, or unreachable once :attr:`complete`). Read it only for rows
        that :meth:`settle` has closed.
    next_policy : ndarray of int, shape (N,)
        Optimal next policy of each closed policy; −1 for the goal and for every policy
        not closed.
    expanded : int
        Policies closed so far (a measure of the work done).

    Raises
    ------
    PlanningError
        If ``goal`` is not a library index.
    ConfigError
        If the library has 2**31 - 1 policies or more.

    Notes
    -----
    About 30 bytes per policy (tentative and final costs, next policies, two flags)
    plus the open heap (24 bytes per entry). Proving a policy unreachable closes every
    policy that reaches the goal: a whole tree's search.
    """

    def __init__(
        self,
        graph: PreparesGraph,
        goal: int,
        *,
        criterion: CostCriterion | str = CostCriterion.TIME,
    ) -> None:
        crit = CostCriterion(criterion) if isinstance(criterion, str) else criterion
        n = graph.num_nodes
        if not 0 <= goal < n:
            raise PlanningError(f"goal policy index {goal} is outside the library (0..{n - 1})")
        if n >= 2**31 - 1:
            raise ConfigError(f"a tree is searched over fewer than 2**31 - 1 policies, got {n}")
        self.graph = graph
        self.goal = int(goal)
        self.criterion = crit
        edges = graph.lattice_edges
        self._lattice = edges.kernel_args()
        self._type_cost = np.ascontiguousarray(graph.type_cost(crit.value), dtype=np.float64)
        self._h = _gauge_facets(edges.offset, self._type_cost, np.diff(edges.succ_ptr) > 0)
        stored = graph.cached_csc(crit.value)
        if stored is None:
            empty = np.zeros(1, dtype=np.int64)
            self._reverse: tuple[Any, Any, Any] = (empty, empty, np.zeros(1))
        else:
            self._reverse = (
                stored.indptr,
                stored.indices,
                np.ascontiguousarray(stored.data, dtype=np.float64),
            )
        self._implicit = stored is None
        self.cost_to_go: FloatArray = np.full(n, np.inf)
        self.next_policy: IntArray = np.full(n, -1, dtype=np.int64)
        self._g: FloatArray = np.full(n, np.inf)
        self._g[self.goal] = 0.0
        self._parent: NDArray[np.int32] = np.full(n, -1, dtype=np.int32)
        self._closed: NDArray[np.bool_] = np.zeros(n, dtype=np.bool_)
        self._mark: NDArray[np.bool_] = np.zeros(n, dtype=np.bool_)
        self._hf: FloatArray = np.zeros(1024)
        self._hg: FloatArray = np.zeros(1024)
        self._hn: IntArray = np.zeros(1024, dtype=np.int64)
        self._hn[0] = self.goal
        self._size = 1
        self._keyed: tuple[float, float, float] | None = None  # the heuristic of the keys
        self._keyed_points: FloatArray = np.zeros(0)  # and its point bound (none: empty)
        self.expanded = 0

    @property
    def complete(self) -> bool:
        """Whether every policy that reaches the goal is closed (the whole tree)."""
        return self._size == 0

    def closed(self, rows: ArrayLike) -> NDArray[np.bool_]:
        """Whether each of ``rows`` is closed (its cost-to-go and next policy final);
        after :attr:`complete`, every row is (inf for the unreachable)."""
        out: NDArray[np.bool_] = self._closed[np.asarray(rows, dtype=np.int64)] | self.complete
        return out

    def reached(self, rows: ArrayLike) -> NDArray[np.bool_]:
        """Whether each of ``rows`` is known to reach the goal: closed with a finite
        cost, or open (its tentative cost is the cost of a path to the goal). False
        says only that the search has not met the row yet, unless :attr:`complete`."""
        out: NDArray[np.bool_] = np.isfinite(self._g[np.asarray(rows, dtype=np.int64)])
        return out

    def settle(
        self, rows: ArrayLike = (), *, best: bool = False, budget: int | None = None
    ) -> bool:
        """Resume the search until ``rows`` are closed.

        Parameters
        ----------
        rows : array_like of int
            Library rows to close (e.g. the policies whose S contains the robot's
            state). Empty: close every policy that reaches the goal.
        best : bool
            Stop once the cheapest of ``rows`` and every one of equal cost are closed:
            the others then cost more (``argmin`` over :attr:`cost_to_go` of ``rows``
            is the best policy, with the same ties as the whole tree). A row that
            cannot reach the goal costs a whole search only if none of ``rows`` can.
        budget : int, optional
            Most policies to close in this call.

        Returns
        -------
        bool
            False if ``budget`` ran out first (what was closed stays closed).

        Raises
        ------
        PlanningError
            If a row is not a library index.
        ConfigError
            If a policy cost the search meets is negative or NaN.
        """
        q = np.ascontiguousarray(np.atleast_1d(np.asarray(rows, dtype=np.int64)))
        n = self._g.size
        if q.size and (q.min() < 0 or q.max() >= n):
            raise PlanningError(f"policy index outside the library (0..{n - 1}) in {rows!r}")
        if self._size == 0 or (q.size and np.all(self._closed[q])):
            return True
        # The heuristic: the gauge from the centre of the queries' start points, less
        # the largest gauge from the centre to one of them (one gauge per row).
        nx = self._lattice[2]
        h_x, h_y = self._h
        if best and q.size and self._keyed is not None and self._known_best(q):
            return True
        cx = cy = 0.0
        radius = np.inf  # no queries: h = 0
        h_point: FloatArray = np.zeros(0)
        if q.size:
            points = np.unique(self.graph.lattice_edges.row_point[q].astype(np.int64))
            qy = (points // nx).astype(np.float64)
            qx = points - qy * nx
            cx, cy = float(qx.mean()), float(qy.mean())
            radius = _gauge_of(qx - cx, qy - cy, h_x, h_y)
            h_point, _ = _points_heuristic(self.graph, self._type_cost, q, self.goal, forward=True)
        status, size, hf, hg, hn, expanded = _lazy_settle(
            self.goal,
            q,
            best,
            -1 if budget is None else int(budget),
            cx,
            cy,
            radius,
            self._type_cost,
            h_x,
            h_y,
            h_point,
            self._g,
            self.cost_to_go,
            self.next_policy,
            self._parent,
            self._closed,
            self._mark,
            self._hf,
            self._hg,
            self._hn,
            self._size,
            self._implicit,
            *self._reverse,
            *self._lattice,
        )
        self._hf, self._hg, self._hn, self._size = hf, hg, hn, int(size)
        self._keyed = (cx, cy, radius)
        self._keyed_points = h_point
        self.expanded += int(expanded)
        if status == _NEGATIVE:
            raise ConfigError(
                "a policy has a negative or NaN cost; costs are policy durations (s) or path "
                "lengths (m), both >= 0"
            )
        return bool(status != _BUDGET)

    def _known_best(self, q: IntArray) -> bool:
        """Whether the cheapest of ``q`` is known without a search: one is closed at a
        cost C, and every other costs more than C. A row not closed costs at least the
        least key of the open heap less its heuristic under those keys (A* with a
        consistent heuristic: an open row on its optimal path has a key at most that)."""
        done = self._closed[q]
        if not done.any():
            return False
        cost = float(self.cost_to_go[q[done]].min())
        rest = q[~done]
        if rest.size == 0:
            return True
        nx = self._lattice[2]
        pts = self.graph.lattice_edges.row_point[rest].astype(np.int64)
        py = pts // nx
        assert self._keyed is not None
        kx, ky, kr = self._keyed
        h_x, h_y = self._h
        h = np.zeros(rest.size)
        if h_x.size:
            dx, dy = (pts - py * nx) - kx, py - ky
            h = np.maximum(np.max(np.outer(dx, h_x) + np.outer(dy, h_y), axis=1) - kr, 0.0)
        if self._keyed_points.size:
            h = np.maximum(h, self._keyed_points[pts])
        bound = self._hf[0] - h  # with a margin far above rounding
        return bool(np.all(bound > cost + 1e-9 * (1.0 + abs(cost))))

    def reachable(self, i: int) -> bool:
        """Whether the goal can be reached from policy ``i`` (closes it if it can)."""
        self.settle([int(i)])
        return bool(np.isfinite(self.cost_to_go[i]))

    def path_from(self, i: int) -> list[int]:
        """Policy indices from ``i`` to the goal, both included (closes ``i``).

        Raises
        ------
        PlanningError
            If the goal is unreachable from ``i``.
        """
        if not self.reachable(i):
            raise PlanningError(
                f"the goal policy {self.goal} cannot be reached from library policy {i}"
            )
        return _follow(self.next_policy, int(i), self.goal)

    def whole(self) -> PolicyTree:
        """The whole tree (closes every policy that reaches the goal), as a copy."""
        self.settle()
        return PolicyTree(
            goal=self.goal,
            next_policy=self.next_policy.copy(),
            cost_to_go=self.cost_to_go.copy(),
            criterion=self.criterion,
        )


def _gauge_of(dx: FloatArray, dy: FloatArray, h_x: FloatArray, h_y: FloatArray) -> float:
    """Largest gauge (see :func:`_gauge_facets`) of the displacements (dx, dy), with a
    margin above rounding."""
    if h_x.size == 0:
        return 0.0
    g = np.max(np.outer(dx, h_x) + np.outer(dy, h_y), axis=1)
    return float(max(0.0, g.max()) * (1.0 + 1e-12) + 1e-12)


def _follow(next_policy: IntArray, i: int, goal: int) -> list[int]:
    """Rows from ``i`` along ``next_policy`` to ``goal``, both included."""
    path = [i]
    while path[-1] != goal:
        path.append(int(next_policy[path[-1]]))
        if len(path) > next_policy.size or path[-1] < 0:  # pragma: no cover - a tree
            raise PlanningError("corrupt policy tree (cycle)")
    return path
