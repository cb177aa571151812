"""Planning in motion policy space (paper Sec. IV-B): the single-goal optimal tree.

Dijkstra's algorithm runs from the goal policy on the *reversed* gracefully
prepares graph, so one search gives every library policy its optimal next
policy toward the goal and its cost-to-go: no replanning is needed when a
disturbance moves the robot into another policy's domain.

The reversed graph in CSR form is the adjacency matrix in CSC form, reinterpreted:
pass :meth:`gracenav.graph.PreparesGraph.csc` (built once per graph) and a tree costs
only the search; an adjacency in any other form is converted on every call, O(N + E).

The search is a compiled (numba) Dijkstra that uses one property of these graphs: an
edge costs the execution of a policy, and a palette has few distinct durations and path
lengths (18 and 39 for the 139-policy palette) however large the map. With one FIFO
queue per distinct edge cost, each queue receives its keys in increasing order (a key is
the settled cost-to-go, which only grows, plus the queue's constant cost), so a push is
an append and a pop takes the smallest of the queue heads, kept in a binary heap of at
most :data:`_MAX_QUEUES` queues: O(E + N log K) for K distinct costs instead of
O(E + N log N). Measured side by side with :func:`scipy.sparse.csgraph.dijkstra` on the
same arrays (``bench/bench_planning.py``, medians): 1.8 times faster on the paper's 3.5 m
area, 3 times on the 50 m office for random goals and 1.3 times for goals in its
corridors, whose trees span half the library (there the scan of the edges, random
accesses into a 320,000-policy array, dominates). Graphs with more distinct costs,
or whose costs are not those of their source policies (a policy reached again at a lower
cost), are searched with an indexed binary heap instead: the same costs, and with
positive costs the same next policies. Each search allocates about 17 bytes per policy.

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

import enum
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse
from numba import njit
from numpy.typing import NDArray

from gracenav.errors import ConfigError, PlanningError

__all__ = ["CostCriterion", "PolicyTree", "plan_tree"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Most distinct edge costs searched with one FIFO queue each (see the module notes).
_MAX_QUEUES = 256
_TABLE = 1024  # open-addressing table from an edge cost to its queue (a power of 2)
# Status of the compiled searches.
_DONE, _NEGATIVE, _TOO_MANY_COSTS, _REVISITED = 0, 1, 2, 3


class CostCriterion(enum.Enum):
    """Optimality criterion of the tree."""

    TIME = "time"
    DISTANCE = "distance"


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
        path = [int(i)]
        while path[-1] != self.goal:
            path.append(int(self.next_policy[path[-1]]))
            if len(path) > self.next_policy.size:  # pragma: no cover - a tree has no cycles
                raise PlanningError("corrupt policy tree (cycle)")
        return path


def plan_tree(
    adjacency: scipy.sparse.sparray | scipy.sparse.spmatrix,
    goal: int,
    *,
    criterion: CostCriterion | str = CostCriterion.TIME,
) -> PolicyTree:
    """Dijkstra from ``goal`` on the reversed graph.

    Parameters
    ----------
    adjacency : scipy.sparse matrix or array, shape (N, N)
        Entry (i, j) is the cost of executing policy i when i gracefully
        prepares j; stored entries are edges, explicit zeros included. In CSC form
        (:meth:`gracenav.graph.PreparesGraph.csc`) its arrays are the reversed graph
        at no cost; any other form (:meth:`gracenav.graph.PreparesGraph.csr`) is
        converted to CSC on every call, O(N + E).
    goal : int
        Library index of the goal policy.
    criterion : CostCriterion or str
        Recorded in the result; the costs themselves come from ``adjacency``.

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
    n = adjacency.shape[0]
    if adjacency.shape != (n, n):
        raise ConfigError(f"adjacency must be square, got {adjacency.shape}")
    if not 0 <= goal < n:
        raise PlanningError(f"goal policy index {goal} is outside the library (0..{n - 1})")
    if n >= 2**31 - 1:  # the searches index their queues with int32
        raise ConfigError(f"a tree is searched over fewer than 2**31 - 1 policies, got {n}")
    # Column j of the CSC form lists the policies that prepare j: row j of the reversed
    # graph in CSR form.
    reverse = adjacency if adjacency.format == "csc" else adjacency.tocsc()
    indptr, indices = reverse.indptr, reverse.indices
    weights = np.ascontiguousarray(reverse.data, dtype=np.float64)
    dist: FloatArray = np.empty(n, dtype=np.float64)
    nxt: IntArray = np.empty(n, dtype=np.int64)
    status = _search_queues(indptr, indices, weights, int(goal), dist, nxt)
    if status in (_TOO_MANY_COSTS, _REVISITED):
        status = _search_heap(indptr, indices, weights, int(goal), dist, nxt)
    if status == _NEGATIVE:
        raise ConfigError(
            "adjacency has a negative or NaN edge cost; costs are policy durations (s) "
            "or path lengths (m), both >= 0"
        )
    return PolicyTree(goal=int(goal), next_policy=nxt, cost_to_go=dist, criterion=crit)


# The compiled searches below fill ``dist`` (cost-to-go, inf if unreachable) and ``nxt``
# (next policy, -1 at the goal and where unreachable) from the reversed graph in CSR
# form (``indptr``, ``indices``, ``weights``: row j lists the policies i that prepare j
# and the cost of executing i), and return a status. A policy is *settled* when its
# cost-to-go is final; settled keys never decrease. Each relaxation of i from j that
# ties with the current best replaces ``nxt[i]`` if j has the same cost-to-go as the
# current choice and a smaller index (see the module notes): with positive costs every
# successor that attains ``dist[i]`` settles before ``i``, so all are compared.


@njit(cache=True, nogil=True)
def _search_queues(indptr: Any, indices: Any, weights: Any, goal: int, dist: Any, nxt: Any) -> int:
    """Dijkstra with one FIFO queue per distinct edge cost (see the module notes).

    Queue entries live in one pool of N + 1 slots, linked per queue; a policy is queued
    again only if reached at a lower cost, which graphs whose edges cost their source
    policy never do. Returns ``_TOO_MANY_COSTS`` or ``_REVISITED`` when the pool or
    the queues run out, and the caller searches again with :func:`_search_heap`.
    """
    n = dist.size
    for k in range(n):
        dist[k] = np.inf
        nxt[k] = -1
    settled = np.zeros(n, np.bool_)
    cap = n + 1
    e_node = np.empty(cap, np.int32)  # pool: policy, key and next entry of its queue
    e_key = np.empty(cap, np.float64)
    e_next = np.empty(cap, np.int32)
    q_head = np.full(_MAX_QUEUES, -1, np.int32)
    q_tail = np.full(_MAX_QUEUES, -1, np.int32)
    q_cost = np.empty(_MAX_QUEUES, np.float64)
    table = np.full(_TABLE, -1, np.int32)
    h_queue = np.empty(_MAX_QUEUES, np.int32)  # binary heap of the non-empty queues,
    h_key = np.empty(_MAX_QUEUES, np.float64)  # keyed by their head entry
    # The goal, alone in the queue of cost 0 (hash slot 0).
    q_cost[0] = 0.0
    n_queues = 1
    table[0] = 0
    dist[goal] = 0.0
    e_node[0] = goal
    e_key[0] = 0.0
    e_next[0] = -1
    count = 1
    q_head[0] = 0
    q_tail[0] = 0
    h_queue[0] = 0
    h_key[0] = 0.0
    h_size = 1
    last_cost = -1.0  # the queue of the last cost looked up
    last_queue = 0
    while h_size > 0:
        c = h_queue[0]
        e = q_head[c]
        j = e_node[e]
        dj = e_key[e]
        nh = e_next[e]
        q_head[c] = nh
        # Queue c moves down the heap with its new head, or leaves it.
        v = c
        kv = np.inf
        if nh == -1:
            q_tail[c] = -1
            h_size -= 1
            if h_size > 0:
                v = h_queue[h_size]
                kv = h_key[h_size]
        else:
            kv = e_key[nh]
        if h_size > 0:
            p = 0
            while True:
                ch = 2 * p + 1
                if ch >= h_size:
                    break
                if ch + 1 < h_size and h_key[ch + 1] < h_key[ch]:
                    ch += 1
                if h_key[ch] < kv:
                    h_queue[p] = h_queue[ch]
                    h_key[p] = h_key[ch]
                    p = ch
                else:
                    break
            h_queue[p] = v
            h_key[p] = kv
        if settled[j] or dj > dist[j]:
            continue  # an entry left behind by a lower cost
        settled[j] = True
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            w = weights[k]
            if not w >= 0.0:
                return _NEGATIVE
            d = dj + w
            di = dist[i]
            if d < di:
                dist[i] = d
                nxt[i] = j
                if w == last_cost:
                    t = last_queue
                else:
                    h = (int(w * 1048576.0) * 40503) & (_TABLE - 1) if w < 1e9 else 1
                    while True:
                        t = table[h]
                        if t == -1:
                            if n_queues == _MAX_QUEUES:
                                return _TOO_MANY_COSTS
                            t = n_queues
                            n_queues += 1
                            q_cost[t] = w
                            table[h] = t
                            break
                        if q_cost[t] == w:
                            break
                        h = (h + 1) & (_TABLE - 1)
                    last_cost = w
                    last_queue = t
                if count == cap:
                    return _REVISITED
                e = count
                count += 1
                e_node[e] = i
                e_key[e] = d
                e_next[e] = -1
                if q_tail[t] == -1:
                    q_head[t] = e
                    p = h_size  # queue t enters the heap
                    h_size += 1
                    while p > 0:
                        pp = (p - 1) >> 1
                        if h_key[pp] > d:
                            h_queue[p] = h_queue[pp]
                            h_key[p] = h_key[pp]
                            p = pp
                        else:
                            break
                    h_queue[p] = t
                    h_key[p] = d
                else:
                    e_next[q_tail[t]] = e
                q_tail[t] = e
            elif d == di and (w > 0.0 or not settled[i]):
                m = nxt[i]
                if j < m and dj == dist[m]:
                    nxt[i] = j
    return _DONE


@njit(cache=True, nogil=True)
def _search_heap(indptr: Any, indices: Any, weights: Any, goal: int, dist: Any, nxt: Any) -> int:
    """Dijkstra with an indexed binary heap (decrease-key), for any non-negative costs."""
    n = dist.size
    for k in range(n):
        dist[k] = np.inf
        nxt[k] = -1
    heap = np.empty(n, np.int32)
    key = np.empty(n, np.float64)
    pos = np.full(n, -1, np.int32)  # heap slot; -1 never queued, -2 settled
    dist[goal] = 0.0
    heap[0] = goal
    key[0] = 0.0
    pos[goal] = 0
    size = 1
    while size > 0:
        j = heap[0]
        dj = key[0]
        pos[j] = -2
        size -= 1
        if size > 0:
            v = heap[size]
            kv = key[size]
            p = 0
            while True:
                c = 2 * p + 1
                if c >= size:
                    break
                if c + 1 < size and key[c + 1] < key[c]:
                    c += 1
                if key[c] < kv:
                    heap[p] = heap[c]
                    key[p] = key[c]
                    pos[heap[p]] = p
                    p = c
                else:
                    break
            heap[p] = v
            key[p] = kv
            pos[v] = p
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            w = weights[k]
            if not w >= 0.0:
                return _NEGATIVE
            d = dj + w
            di = dist[i]
            if d < di:
                dist[i] = d
                nxt[i] = j
                p = pos[i]
                if p == -1:
                    p = size
                    size += 1
                while p > 0:
                    q = (p - 1) >> 1
                    if key[q] > d:
                        heap[p] = heap[q]
                        key[p] = key[q]
                        pos[heap[p]] = p
                        p = q
                    else:
                        break
                heap[p] = i
                key[p] = d
                pos[i] = p
            elif d == di and (w > 0.0 or pos[i] != -2):
                m = nxt[i]
                if j < m and dj == dist[m]:
                    nxt[i] = j
    return _DONE
