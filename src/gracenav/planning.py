"""Planning in motion policy space (paper Sec. IV-B): the single-goal optimal tree.

Dijkstra's algorithm runs from the goal policy on the *reversed* gracefully
prepares graph, so one search gives every library policy its optimal next
policy toward the goal and its cost-to-go: no replanning is needed when a
disturbance moves the robot into another policy's domain.

The reversed graph in CSR form is the adjacency matrix in CSC form, reinterpreted:
pass :meth:`gracenav.graph.PreparesGraph.csc` (built once per graph) and a tree costs
only the search; a CSR adjacency is transposed on every call, O(N + E).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from numpy.typing import NDArray

from gracenav.errors import ConfigError, PlanningError

__all__ = ["CostCriterion", "PolicyTree", "plan_tree"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


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
        (:meth:`gracenav.graph.PreparesGraph.csc`) its transpose is the reversed graph
        at no cost; any other form (:meth:`gracenav.graph.PreparesGraph.csr`) is
        transposed and converted on every call.
    goal : int
        Library index of the goal policy.
    criterion : CostCriterion or str
        Recorded in the result; the costs themselves come from ``adjacency``.

    Returns
    -------
    PolicyTree
    """
    crit = CostCriterion(criterion) if isinstance(criterion, str) else criterion
    n = adjacency.shape[0]
    if adjacency.shape != (n, n):
        raise ConfigError(f"adjacency must be square, got {adjacency.shape}")
    if not 0 <= goal < n:
        raise PlanningError(f"goal policy index {goal} is outside the library (0..{n - 1})")
    if adjacency.format == "csc":
        reverse = adjacency.T  # CSR over the same arrays: no copy
    else:
        reverse = adjacency.T.tocsr()
    dist, pred = scipy.sparse.csgraph.dijkstra(
        reverse, directed=True, indices=int(goal), return_predecessors=True
    )
    nxt = np.asarray(pred, dtype=np.int64)
    nxt[nxt < 0] = -1
    return PolicyTree(
        goal=int(goal),
        next_policy=nxt,
        cost_to_go=np.asarray(dist, dtype=np.float64),
        criterion=crit,
    )
