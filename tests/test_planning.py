"""The single-goal optimal tree: against an independent Bellman-Ford and a reference
Dijkstra, and identical to the search on a per-call transposed CSR (the tree as it was
computed before the reversed graph was kept with the graph)."""

from __future__ import annotations

import heapq
import itertools

import numpy as np
import pytest
import scipy.sparse
from scipy.sparse import csgraph
from synthetic import palette, policy, primitive

from gracenav import PlanningError
from gracenav.graph import build_graph
from gracenav.library import build_library
from gracenav.planning import CostCriterion, PolicyTree, plan_tree
from gracenav.policies import PrimitiveKind
from gracenav.world import load_map

X, Y, Z = (0.5, 0.0), (0.0, 0.5), (0.0, 0.0)


def random_graph(
    n: int, p: float, seed: int, *, zero_fraction: float = 0.0
) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    """Edges i → j weighted by the cost of executing i; ``zero_fraction`` of the nodes
    cost nothing (as rest trims under the distance criterion), stored as explicit zeros.
    The last node is a dead end: no goal but itself is reachable from it."""
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0.5, 3.0, n)  # the cost of executing each policy
    cost[rng.random(n) < zero_fraction] = 0.0
    mask = rng.random((n, n)) < p
    np.fill_diagonal(mask, False)
    mask[-1] = False
    i, j = np.nonzero(mask)
    adj = scipy.sparse.csr_matrix((cost[i], j, np.r_[0, np.cumsum(mask.sum(1))]), shape=(n, n))
    assert adj.nnz == i.size  # explicit zeros kept
    return adj, cost


def transposing_tree(adj: scipy.sparse.csr_matrix, goal: int) -> tuple[np.ndarray, np.ndarray]:
    """Cost-to-go and next policy by scipy's Dijkstra on ``csr_matrix(adj.T)`` built on
    every call: the reference the cached reversed graph must reproduce exactly."""
    dist, pred = csgraph.dijkstra(
        scipy.sparse.csr_matrix(adj.T), directed=True, indices=goal, return_predecessors=True
    )
    nxt = np.asarray(pred, dtype=np.int64)
    nxt[nxt < 0] = -1
    return dist, nxt


def bellman_ford_to(goal: int, adj: scipy.sparse.csr_matrix) -> np.ndarray:
    """Cost-to-go by relaxing every stored edge (explicit zeros included) N times."""
    coo = adj.tocoo()
    src, dst, w = coo.row, coo.col, coo.data
    d = np.full(adj.shape[0], np.inf)
    d[goal] = 0.0
    for _ in range(adj.shape[0]):
        cand = np.full_like(d, np.inf)
        np.minimum.at(cand, src, w + d[dst])
        new = np.minimum(d, cand)
        if np.array_equal(new, d):
            break
        d = new
    return d


def heap_dijkstra_to(goal: int, adj: scipy.sparse.csr_matrix) -> np.ndarray:
    """Cost-to-go by a textbook binary-heap Dijkstra over predecessor lists."""
    coo = adj.tocoo()
    preds: list[list[tuple[int, float]]] = [[] for _ in range(adj.shape[0])]
    for i, j, w in zip(coo.row.tolist(), coo.col.tolist(), coo.data.tolist(), strict=True):
        preds[j].append((i, w))
    d = np.full(adj.shape[0], np.inf)
    d[goal] = 0.0
    heap = [(0.0, goal)]
    while heap:
        dj, j = heapq.heappop(heap)
        if dj > d[j]:
            continue
        for i, w in preds[j]:
            if dj + w < d[i]:
                d[i] = dj + w
                heapq.heappush(heap, (dj + w, i))
    return d


def assert_optimal_tree(tree: PolicyTree, adj: scipy.sparse.csr_matrix, want: np.ndarray) -> None:
    """Costs match ``want`` and every next policy is a stored edge that attains them."""
    np.testing.assert_allclose(tree.cost_to_go, want, rtol=1e-12, atol=0.0)
    nxt = tree.next_policy
    others = np.arange(want.size) != tree.goal
    np.testing.assert_array_equal(nxt >= 0, np.isfinite(want) & others)
    for i in np.flatnonzero(nxt >= 0):
        row = slice(adj.indptr[i], adj.indptr[i + 1])
        (k,) = np.flatnonzero(adj.indices[row] == nxt[i])
        step = adj.data[row][k] + want[nxt[i]]
        assert step == pytest.approx(want[i], rel=1e-12, abs=0.0)


@pytest.mark.parametrize("seed", range(5))
def test_cost_to_go_matches_bellman_ford(seed: int) -> None:
    adj, cost = random_graph(60, 0.06, seed)
    tree = plan_tree(adj, 7)
    want = bellman_ford_to(7, adj)
    assert 1 < np.isfinite(want).sum() < 60  # some reachable, the dead end not
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


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("zero_fraction", [0.0, 0.3])
def test_csc_and_csr_give_the_transposing_tree(seed: int, zero_fraction: float) -> None:
    adj, _ = random_graph(80, 0.05, seed, zero_fraction=zero_fraction)
    csc = adj.tocsc()
    for goal in (0, 13, 79):
        dist, nxt = transposing_tree(adj, goal)
        for form in (adj, csc, scipy.sparse.csr_array(adj), scipy.sparse.csc_array(csc)):
            tree = plan_tree(form, goal)
            np.testing.assert_array_equal(tree.cost_to_go, dist)
            np.testing.assert_array_equal(tree.next_policy, nxt)
            assert tree.next_policy.dtype == np.int64
        assert_optimal_tree(plan_tree(csc, goal), adj, bellman_ford_to(goal, adj))


def test_csc_input_is_not_copied() -> None:
    adj, _ = random_graph(30, 0.1, 0)
    csc = adj.tocsc()
    rev = csc.T
    assert rev.format == "csr"
    assert np.shares_memory(rev.indices, csc.indices) and np.shares_memory(rev.data, csc.data)


def small_library_graph():  # type: ignore[no-untyped-def]
    """A synthetic library on a 3 m square with an obstacle, at d/2 spacing."""
    pal = palette(
        policy(primitive("rest", (0.0, 0.0), kind=PrimitiveKind.REST)),
        policy(primitive("cruise_x", (0.5, 0.0), X, X, 1.0, PrimitiveKind.CRUISE)),
        policy(primitive("cruise_y", (0.0, 0.5), Y, Y, 1.0, PrimitiveKind.CRUISE)),
        policy(primitive("rest_to_x", (1.0, 0.0), Z, X, 2.5)),
        policy(primitive("x_to_rest", (1.0, 0.0), X, Z, 2.5)),
        policy(primitive("x_to_y", (0.5, 0.5), X, Y, 1.5)),
        policy(primitive("y_to_x", (0.5, 0.5), Y, X, 1.5)),
        policy(primitive("hop", (0.5, 0.5), duration=2.0), (0.15, 0.15), (0.05, 0.05)),
    )
    wmap = load_map(
        {
            "bounds": [[0.0, 0.0], [3.0, 3.0]],
            "obstacles": [{"circle": {"center": [1.5, 1.5], "radius": 0.2}}],
            "resolution": 0.05,
        }
    )
    lib = build_library(pal, wmap, footprint_radius=0.05, max_halvings=1, coverage_samples=100)
    return lib, build_graph(lib)


def test_library_trees_equal_the_transposing_tree_and_a_reference_dijkstra() -> None:
    lib, graph = small_library_graph()
    assert len(lib) > 300 and graph.num_edges > 2000
    trims = lib.trim_indices()
    rng = np.random.default_rng(0)
    reached = 0
    for cost in ("time", "distance"):
        fwd = graph.csr(cost)
        for goal in rng.choice(trims, 6, replace=False):
            goal = int(goal)
            tree = plan_tree(graph.csc(cost), goal, criterion=cost)
            dist, nxt = transposing_tree(fwd, goal)
            np.testing.assert_array_equal(tree.cost_to_go, dist)
            np.testing.assert_array_equal(tree.next_policy, nxt)
            assert_optimal_tree(tree, fwd, heap_dijkstra_to(goal, fwd))
            reached += int(np.isfinite(dist).sum())
    assert reached > 12 * 50  # the trees are not trivial


def test_goal_index_checked() -> None:
    adj, _ = random_graph(5, 0.5, 0)
    with pytest.raises(PlanningError, match="outside the library"):
        plan_tree(adj, 9)
    with pytest.raises(PlanningError, match="outside the library"):
        plan_tree(adj.tocsc(), -1)
    assert plan_tree(adj, 0, criterion="distance").criterion is CostCriterion.DISTANCE
