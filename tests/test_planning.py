"""The single-goal optimal tree against an independent Bellman-Ford on random graphs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse

from gracenav import PlanningError
from gracenav.planning import CostCriterion, plan_tree


def random_graph(n: int, p: float, seed: int) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0.5, 3.0, n)  # the cost of executing each policy
    mask = rng.random((n, n)) < p
    np.fill_diagonal(mask, False)
    i, j = np.nonzero(mask)
    return scipy.sparse.csr_matrix((cost[i], (i, j)), shape=(n, n)), cost


def bellman_ford_to(goal: int, adj: scipy.sparse.csr_matrix) -> np.ndarray:
    dense = adj.toarray()
    n = dense.shape[0]
    d = np.full(n, np.inf)
    d[goal] = 0.0
    for _ in range(n):
        cand = np.where(dense > 0, dense + d[None, :], np.inf).min(axis=1)
        d = np.minimum(d, cand)
    return d


@pytest.mark.parametrize("seed", range(5))
def test_cost_to_go_matches_bellman_ford(seed: int) -> None:
    adj, cost = random_graph(60, 0.06, seed)
    tree = plan_tree(adj, 7)
    want = bellman_ford_to(7, adj)
    np.testing.assert_allclose(tree.cost_to_go, want, rtol=1e-12)
    for i in range(60):
        if np.isfinite(want[i]) and i != 7:
            path = tree.path_from(i)
            assert path[0] == i and path[-1] == 7
            # Every step is an edge and the costs add up to the cost-to-go.
            assert all(adj[a, b] > 0 for a, b in itertools.pairwise(path))
            assert sum(cost[k] for k in path[:-1]) == pytest.approx(want[i], rel=1e-12)
        elif i != 7:
            assert tree.next_policy[i] == -1
            with pytest.raises(PlanningError, match="cannot be reached"):
                tree.path_from(i)


def test_goal_index_checked() -> None:
    adj, _ = random_graph(5, 0.5, 0)
    with pytest.raises(PlanningError, match="outside the library"):
        plan_tree(adj, 9)
    assert plan_tree(adj, 0, criterion="distance").criterion is CostCriterion.DISTANCE
