"""The single-goal optimal tree: costs against an independent Bellman-Ford, a reference
heap Dijkstra and scipy's Dijkstra on a per-call transposed CSR (the tree as it was
computed before the compiled search), bit for bit; next policies against a brute-force
evaluation of the documented choice among equally good successors. Both compiled
searches (one FIFO queue per distinct cost, and the binary heap it falls back to) are
covered, and each test checks which one ran."""

from __future__ import annotations

import heapq
import itertools

import numpy as np
import pytest
import scipy.sparse
from scipy.sparse import csgraph
from synthetic import palette, policy, primitive

from gracenav import ConfigError, PlanningError
from gracenav.library import build_library
from gracenav.planning import CostCriterion, LazyPolicyTree, PolicyTree, plan_path, plan_tree
from gracenav.planning._search import (
    _DONE,
    _REVISITED,
    _TOO_MANY_COSTS,
    _search_heap,
    _search_heap_lattice,
    _search_queues,
)
from gracenav.planning.graph import build_graph
from gracenav.policies import PrimitiveKind
from gracenav.world import load_map

X, Y, Z = (0.5, 0.0), (0.0, 0.5), (0.0, 0.0)


def random_graph(
    n: int, p: float, seed: int, *, zero_fraction: float = 0.0, levels: int = 0
) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    """Edges i → j weighted by the cost of executing i; ``zero_fraction`` of the nodes
    cost nothing (as rest trims under the distance criterion), stored as explicit zeros;
    ``levels`` > 0 draws the costs from that many values (as a palette's few durations:
    many equally good paths). The last node is a dead end: no goal but itself is
    reachable from it."""
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0.5, 3.0, n)  # the cost of executing each policy
    if levels:
        cost = rng.choice(np.arange(1, levels + 1) * 0.375, n)
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


def searched_by(adj: scipy.sparse.spmatrix, goal: int) -> int:
    """Status of the FIFO-queue search on ``adj``: ``_DONE`` if it gave the tree, else
    why :func:`plan_tree` fell back to the heap search."""
    csc = scipy.sparse.csc_matrix(adj)
    n = csc.shape[0]
    dist, nxt = np.empty(n), np.empty(n, dtype=np.int64)
    return int(_search_queues(csc.indptr, csc.indices, csc.data, goal, dist, nxt))


def heap_search(adj: scipy.sparse.spmatrix, goal: int) -> tuple[np.ndarray, np.ndarray]:
    """Cost-to-go and next policy by the binary-heap search alone."""
    csc = scipy.sparse.csc_matrix(adj)
    n = csc.shape[0]
    dist, nxt = np.empty(n), np.empty(n, dtype=np.int64)
    assert _search_heap(csc.indptr, csc.indices, csc.data, goal, dist, nxt) == _DONE
    return dist, nxt


def documented_next(adj: scipy.sparse.csr_matrix, goal: int, dist: np.ndarray) -> np.ndarray:
    """The next policy the module notes define, by brute force over each policy's
    successors: among those j with cost(i → j) + dist[j] == dist[i] exactly, the one
    with the smallest dist[j], then the smallest index (positive costs)."""
    adj = scipy.sparse.csr_matrix(adj)
    nxt = np.full(adj.shape[0], -1, dtype=np.int64)
    for i in range(adj.shape[0]):
        if i == goal or not np.isfinite(dist[i]):
            continue
        row = slice(adj.indptr[i], adj.indptr[i + 1])
        succ, w = adj.indices[row], adj.data[row]
        attain = succ[w + dist[succ] == dist[i]]
        nxt[i] = min(attain.tolist(), key=lambda j: (dist[j], j))
    return nxt


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
@pytest.mark.parametrize("levels", [0, 3])
def test_positive_costs_give_scipys_costs_and_the_documented_next_policy(
    seed: int, levels: int
) -> None:
    adj, _ = random_graph(80, 0.05, seed, levels=levels)
    csc = adj.tocsc()
    ties = 0
    for goal in (0, 13, 79):
        dist, old_nxt = transposing_tree(adj, goal)
        want = documented_next(adj, goal, dist)
        ties += int(np.sum(want != old_nxt))
        assert searched_by(adj, goal) == _DONE  # the FIFO-queue search
        for form in (adj, csc, scipy.sparse.csr_array(adj), scipy.sparse.csc_array(csc)):
            tree = plan_tree(form, goal)
            np.testing.assert_array_equal(tree.cost_to_go, dist)
            np.testing.assert_array_equal(tree.next_policy, want)
            assert tree.next_policy.dtype == np.int64
        heap_dist, heap_nxt = heap_search(adj, goal)
        np.testing.assert_array_equal(heap_dist, dist)
        np.testing.assert_array_equal(heap_nxt, want)
        assert_optimal_tree(plan_tree(csc, goal), adj, bellman_ford_to(goal, adj))
    if levels:
        assert ties > 0  # equally good successors met, chosen by the rule, not by scipy


@pytest.mark.parametrize("seed", range(6))
def test_zero_costs_give_scipys_costs_and_an_optimal_acyclic_tree(seed: int) -> None:
    adj, _ = random_graph(80, 0.05, seed, zero_fraction=0.3, levels=3)
    for goal in (0, 13, 79):
        dist, _ = transposing_tree(adj, goal)
        assert searched_by(adj, goal) == _DONE
        tree = plan_tree(adj.tocsc(), goal)
        np.testing.assert_array_equal(tree.cost_to_go, dist)
        assert_optimal_tree(tree, adj, bellman_ford_to(goal, adj))
        heap_dist, heap_nxt = heap_search(adj, goal)
        np.testing.assert_array_equal(heap_dist, dist)
        assert_optimal_tree(
            PolicyTree(goal, heap_nxt, heap_dist, CostCriterion.TIME),
            adj,
            bellman_ford_to(goal, adj),
        )
        for i in np.flatnonzero(np.isfinite(dist)):
            assert tree.path_from(int(i))[-1] == goal  # no cycle


@pytest.mark.parametrize("seed", range(4))
def test_fallback_to_the_heap_search(seed: int) -> None:
    """Edge costs that are not their source's cost (a policy reached again at a lower
    cost) and more distinct costs than queues: the heap search gives the tree."""
    rng = np.random.default_rng(seed)
    n = 300
    mask = rng.random((n, n)) < 0.03
    np.fill_diagonal(mask, False)
    i, j = np.nonzero(mask)
    per_edge = scipy.sparse.csr_matrix(
        (rng.choice([0.5, 1.0, 1.5, 2.0], i.size), (i, j)), shape=(n, n)
    )
    per_node = scipy.sparse.csr_matrix((rng.uniform(0.5, 3.0, n)[i], (i, j)), shape=(n, n))
    assert np.unique(per_node.data).size > 256  # more distinct costs than queues
    for adj, why in ((per_edge, _REVISITED), (per_node, _TOO_MANY_COSTS)):
        assert searched_by(adj, 0) == why
        dist, _ = transposing_tree(adj, 0)
        assert np.isfinite(dist).sum() > n // 2
        tree = plan_tree(adj.tocsc(), 0)
        np.testing.assert_array_equal(tree.cost_to_go, dist)
        np.testing.assert_array_equal(tree.next_policy, documented_next(adj, 0, dist))
        assert_optimal_tree(tree, adj, bellman_ford_to(0, adj))


def test_negative_or_nan_costs_refused() -> None:
    for bad in (-1.0, np.nan):
        adj = scipy.sparse.csr_matrix(([1.0, bad, 1.0], ([0, 1, 2], [1, 2, 0])), shape=(3, 3))
        with pytest.raises(ConfigError, match="negative or NaN edge cost"):
            plan_tree(adj, 0)
        csc = adj.tocsc()
        dist, nxt = np.empty(3), np.empty(3, dtype=np.int64)
        assert _search_heap(csc.indptr, csc.indices, csc.data, 0, dist, nxt) != _DONE


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


def test_library_trees_have_the_transposing_trees_costs_and_the_documented_next() -> None:
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
            assert searched_by(graph.csc(cost), goal) == _DONE
            dist, _ = transposing_tree(fwd, goal)
            np.testing.assert_array_equal(tree.cost_to_go, dist)
            if cost == "time":  # positive costs: the documented choice, exactly
                np.testing.assert_array_equal(tree.next_policy, documented_next(fwd, goal, dist))
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


@pytest.mark.parametrize("dense", [True, False])
def test_trees_on_edges_generated_from_the_lattice_are_the_stored_graphs_trees(
    monkeypatch: pytest.MonkeyPatch, dense: bool
) -> None:
    """plan_tree on a graph that stores no edges gives exactly the tree of the stored
    reversed graph (the same relaxation order, so the same ties), by both searches."""
    import gracenav.planning.graph as graph_module

    if not dense:
        monkeypatch.setattr(graph_module, "DENSE_LOOKUP", 0)
    lib, stored = small_library_graph()
    implicit = build_graph(lib)
    trims = lib.trim_indices()
    rng = np.random.default_rng(3)
    for cost in ("time", "distance"):
        csc = stored.csc(cost)
        type_cost = implicit.type_cost(cost)
        for goal in rng.choice(trims, 5, replace=False):
            want = plan_tree(csc, int(goal), criterion=cost)
            got = plan_tree(implicit, int(goal), criterion=cost)
            assert implicit.cached_csc(cost) is None  # searched without a stored graph
            np.testing.assert_array_equal(got.cost_to_go, want.cost_to_go)
            np.testing.assert_array_equal(got.next_policy, want.next_policy)
            dist, nxt = np.empty(len(lib)), np.empty(len(lib), np.int64)
            args = implicit.lattice_edges.kernel_args()
            assert _search_heap_lattice(type_cost, int(goal), dist, nxt, *args) == _DONE
            np.testing.assert_array_equal(dist, want.cost_to_go)
            if cost == "time":
                np.testing.assert_array_equal(nxt, want.next_policy)
    # A graph whose reversed graph is built is searched on it.
    stored.csc("time")
    assert plan_tree(stored, int(trims[0])).cost_to_go.shape == (len(lib),)
    with pytest.raises(PlanningError, match="outside the library"):
        plan_tree(implicit, len(lib))


def test_point_to_point_paths_cost_the_trees_cost_to_go() -> None:
    """A* finds a path of the tree's cost-to-go (the heuristic is admissible): every
    step an edge, the cost the sum of the executed policies' costs."""
    lib, graph = small_library_graph()
    trims = lib.trim_indices()
    rng = np.random.default_rng(4)
    reached = unreached = 0
    for cost in ("time", "distance"):
        node_cost = graph.node_cost(cost)
        for goal in rng.choice(trims, 4, replace=False):
            tree = plan_tree(graph, int(goal), criterion=cost)
            for start in rng.choice(len(lib), 12, replace=False):
                path = plan_path(graph, int(start), int(goal), criterion=cost)
                if not tree.reachable(int(start)):
                    assert not path.reachable and path.cost == np.inf
                    unreached += 1
                    continue
                reached += 1
                assert path.policies[0] == start and path.policies[-1] == goal
                for a, b in itertools.pairwise(path.policies):
                    assert b in graph.successors(int(a))
                np.testing.assert_allclose(
                    path.cost, node_cost[path.policies[:-1]].sum(), rtol=1e-12, atol=1e-12
                )
                np.testing.assert_allclose(
                    path.cost, tree.cost_to_go[start], rtol=1e-12, atol=1e-12
                )
                assert 0 < path.expanded <= len(lib)
    assert reached > 10 and unreached > 0
    # Several starts: the cheapest; a start that is the goal costs nothing.
    goal = int(trims[0])
    tree = plan_tree(graph, goal)
    starts = np.flatnonzero(np.isfinite(tree.cost_to_go))[:5]
    best = plan_path(graph, starts, goal)
    np.testing.assert_allclose(best.cost, tree.cost_to_go[starts].min(), rtol=1e-12, atol=1e-12)
    assert plan_path(graph, goal, goal).cost == 0.0
    with pytest.raises(PlanningError, match="outside the library"):
        plan_path(graph, len(lib), goal)


def detour_library_graph():  # type: ignore[no-untyped-def]
    """The synthetic palette of :func:`small_library_graph` on an 8 m x 4 m room split
    by a wall with one gap at its north end: ways between the halves detour."""
    lib, _ = small_library_graph()
    wmap = load_map(
        {
            "bounds": [[0.0, 0.0], [8.0, 4.0]],
            "obstacles": [{"rectangle": {"min": [3.9, 0.0], "max": [4.1, 2.8]}}],
            "resolution": 0.05,
        }
    )
    lib = build_library(lib.palette, wmap, footprint_radius=0.05, max_halvings=0)
    return lib, build_graph(lib)


def points_cost_by_scipy(graph, cost: str, point: int, forward: bool) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The point bounds of :func:`plan_path` and :class:`LazyPolicyTree`, computed
    independently: scipy's Dijkstra to (or, ``forward``, from) ``point`` on a graph over
    lattice points with an edge p -> p + o for every library policy (at p, of a type
    with successors and end offset o != 0), costing the cheapest type with that offset
    anywhere."""
    e = graph.lattice_edges
    ny, nx = e.lattice_shape
    type_cost = graph.type_cost(cost)
    moving = (np.diff(e.succ_ptr) > 0) & np.any(e.offset != 0, axis=1)
    cheapest: dict[tuple[int, int], float] = {}
    for t in np.flatnonzero(moving):
        o = (int(e.offset[t, 0]), int(e.offset[t, 1]))
        cheapest[o] = min(cheapest.get(o, np.inf), float(type_cost[t]))
    pairs: dict[tuple[int, int], float] = {}
    for t, p in zip(e.row_type, e.row_point, strict=True):
        if not moving[t]:
            continue
        ox, oy = (int(v) for v in e.offset[t])
        x, y = int(p) % nx + ox, int(p) // nx + oy
        if 0 <= x < nx and 0 <= y < ny:
            pairs[(int(p), y * nx + x)] = cheapest[(ox, oy)]
    src, dst = np.array(list(pairs)).T
    adj = scipy.sparse.csr_matrix((list(pairs.values()), (src, dst)), shape=(nx * ny, nx * ny))
    return np.asarray(csgraph.dijkstra(adj if forward else adj.T.tocsr(), indices=point))


@pytest.mark.parametrize("where", ["room", "detour"])
def test_the_point_bounds_are_consistent_lower_bounds(where: str) -> None:
    """The lattice points' bounds (to the goal, of plan_path; from the queries, of a
    lazy tree): run to the end they are scipy's Dijkstra on the point graph (an
    independent construction), the points it cannot reach at its largest cost; stopped
    at a target they stay below every true cost (plan_tree's cost-to-go; scipy's
    costs from a query on the policy graph) and are consistent along every edge."""
    from gracenav.planning.trees import _points_heuristic

    lib, graph = small_library_graph() if where == "room" else detour_library_graph()
    e = graph.lattice_edges
    used = np.unique(e.row_point)
    trims = lib.trim_indices()
    rng = np.random.default_rng(12)
    margin = 1.0 - 1e-9
    for cost in ("time", "distance"):
        type_cost = np.ascontiguousarray(graph.type_cost(cost))
        node_cost = graph.node_cost(cost)
        adj = graph.csr(cost)
        src = np.repeat(np.arange(len(lib)), np.diff(adj.indptr))
        for goal in rng.choice(trims, 3, replace=False):
            query = int(rng.choice(len(lib)))
            for forward in (False, True):
                ends = np.arange(len(lib))
                if forward:  # from the query, stopped at the goal's point
                    whole, cut = _points_heuristic(
                        graph, type_cost, [query], int(goal), forward=True
                    )
                    want = points_cost_by_scipy(graph, cost, int(e.row_point[query]), True)
                    target = want[e.row_point[goal]]
                else:  # to the goal, from every point: run to the end
                    whole, cut = _points_heuristic(graph, type_cost, ends, int(goal))
                    want = points_cost_by_scipy(graph, cost, int(e.row_point[goal]), False)
                    target = np.inf
                    assert cut == np.isinf(want[used]).sum()
                want = want * margin
                # Settled points carry their cost; the others the cost where it stopped.
                stop = np.max(want[np.isfinite(want)]) if np.isinf(target) else target * margin
                want, got = want[used], whole[used]
                below = want < stop
                np.testing.assert_allclose(got[below], want[below], rtol=1e-12)
                np.testing.assert_allclose(got[~below], stop, rtol=1e-12)
                if forward:
                    true = csgraph.dijkstra(adj, indices=query)
                    h = whole[e.row_point]
                    assert np.all(h <= true)
                    step = h[src] + node_cost[src]  # h(j) <= h(i) + cost(i)
                    lhs = h[adj.indices]
                else:
                    tree = plan_tree(graph, int(goal), criterion=cost)
                    for start in (ends, [query]):
                        h = _points_heuristic(graph, type_cost, start, int(goal))[0][e.row_point]
                        assert np.all(h <= tree.cost_to_go)
                    step = node_cost[src] + h[adj.indices]  # h(i) <= cost(i) + h(j)
                    lhs = h[src]
                assert np.all((lhs <= step) | np.isclose(lhs, step, rtol=1e-12, atol=0))


def test_paths_around_a_wall_expand_less_with_the_point_heuristic(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Across the wall of the detour room the lattice points' bound cuts A*'s work (the
    gauge alone sees the straight line), and the path still costs the tree's
    cost-to-go."""
    import gracenav.planning.trees as trees

    lib, graph = detour_library_graph()
    trims = lib.trim_indices()
    xy = lib.start_xy[trims]
    west = trims[np.argmin(np.hypot(xy[:, 0] - 3.0, xy[:, 1] - 0.5))]
    east = trims[np.argmin(np.hypot(xy[:, 0] - 5.0, xy[:, 1] - 0.5))]
    tree = plan_tree(graph, int(east))
    assert np.isfinite(tree.cost_to_go[west])
    path = plan_path(graph, int(west), int(east))
    np.testing.assert_allclose(path.cost, tree.cost_to_go[west], rtol=1e-12, atol=1e-12)
    real = trees._points_heuristic
    monkeypatch.setattr(
        trees, "_points_heuristic", lambda g, c, s, q, **kw: (0.0 * real(g, c, s, q)[0], 0)
    )
    gauge_only = plan_path(graph, int(west), int(east))
    assert gauge_only.cost == path.cost
    assert path.expanded < 0.5 * gauge_only.expanded


def test_a_replan_joining_an_earlier_path_costs_the_trees_cost_to_go() -> None:
    """With ``via`` (an optimal path to the goal), A* stops where joining it is
    cheapest: still the tree's cost-to-go, and the path follows ``via`` from there."""
    lib, graph = small_library_graph()
    trims = lib.trim_indices()
    rng = np.random.default_rng(6)
    checked = 0
    for goal in rng.choice(trims, 4, replace=False):
        tree = plan_tree(graph, int(goal))
        reach = np.flatnonzero(np.isfinite(tree.cost_to_go))
        if reach.size < 3:
            continue
        for first, second in rng.choice(reach, (6, 2)):
            via = plan_path(graph, int(first), int(goal))
            path = plan_path(graph, int(second), int(goal), via=via)
            np.testing.assert_allclose(path.cost, tree.cost_to_go[second], rtol=1e-12, atol=1e-12)
            assert path.policies[0] == second and path.policies[-1] == goal
            for a, b in itertools.pairwise(path.policies):
                assert b in graph.successors(int(a))
            checked += 1
    assert checked > 6
    with pytest.raises(ConfigError, match="via"):
        plan_path(
            graph, int(trims[1]), int(trims[0]), via=plan_path(graph, int(trims[1]), int(trims[1]))
        )


def assert_lazy_matches(lazy: LazyPolicyTree, whole: PolicyTree, graph, cost: str) -> int:  # type: ignore[no-untyped-def]
    """Closed rows carry the whole tree's cost-to-go (exactly with positive costs, and
    its next policy; with zero costs, within rounding: two zero-cost policies that
    prepare each other leave the last bit to the order of the search); following
    next_policy sums to that cost; the others read inf / -1. Returns how many rows
    are closed."""
    closed = lazy.closed(np.arange(whole.cost_to_go.size))
    if cost == "time":
        np.testing.assert_array_equal(lazy.cost_to_go[closed], whole.cost_to_go[closed])
    else:
        np.testing.assert_allclose(
            lazy.cost_to_go[closed], whole.cost_to_go[closed], rtol=1e-12, atol=1e-12
        )
    assert np.all(np.isinf(lazy.cost_to_go[~closed]))
    assert np.all(lazy.next_policy[~closed] == -1)
    if cost == "time":
        np.testing.assert_array_equal(lazy.next_policy[closed], whole.next_policy[closed])
    node_cost = graph.node_cost(cost)
    for i in np.flatnonzero(closed & np.isfinite(lazy.cost_to_go))[:40]:
        path = lazy.path_from(int(i))
        assert path[-1] == whole.goal
        for a, b in itertools.pairwise(path):
            assert b in graph.successors(a)
        total = 0.0
        for a in path[-2::-1]:  # summed from the goal, as the search does
            total = total + node_cost[a]
        assert total == lazy.cost_to_go[i]
    return int(closed.sum())


@pytest.mark.parametrize("dense", [True, False])
def test_lazy_tree_closes_rows_at_the_whole_trees_cost_to_go(
    monkeypatch: pytest.MonkeyPatch, dense: bool
) -> None:
    """A lazy tree settled on random queries (all of them, or the best) closes them at
    plan_tree's cost-to-go and next policy, resumed call after call, on edges generated
    from the lattice (both lookups) and on a stored reversed graph."""
    import gracenav.planning.graph as graph_module

    if not dense:
        monkeypatch.setattr(graph_module, "DENSE_LOOKUP", 0)
    lib, stored = small_library_graph()
    implicit = build_graph(lib)
    n = len(lib)
    trims = lib.trim_indices()
    rng = np.random.default_rng(8)
    partial = 0
    for cost in ("time", "distance"):
        stored.csc(cost)
        for goal in rng.choice(trims, 4, replace=False):
            whole = plan_tree(stored.csc(cost), int(goal), criterion=cost)
            reach = np.flatnonzero(np.isfinite(whole.cost_to_go))
            for graph in (implicit, stored):
                lazy = LazyPolicyTree(graph, int(goal), criterion=cost)
                assert lazy._implicit is (graph is implicit)
                for k in range(4):  # reachable rows, then any (some unreachable)
                    rows = rng.choice(reach if k < 3 else np.arange(n), 3)
                    best = bool(rng.integers(2))
                    assert lazy.settle(rows, best=best)
                    if best and np.isfinite(whole.cost_to_go[rows]).any():
                        k = int(np.argmin(whole.cost_to_go[rows]))
                        assert int(np.argmin(lazy.cost_to_go[rows])) == k
                        ties = rows[whole.cost_to_go[rows] == whole.cost_to_go[rows[k]]]
                        assert np.all(lazy.closed(ties))
                    elif not best:
                        assert np.all(lazy.closed(rows))
                    closed = assert_lazy_matches(lazy, whole, graph, cost)
                    partial += closed < n
                got = lazy.whole()
                np.testing.assert_allclose(got.cost_to_go, whole.cost_to_go, rtol=1e-12)
                if cost == "time":
                    np.testing.assert_array_equal(got.cost_to_go, whole.cost_to_go)
                    np.testing.assert_array_equal(got.next_policy, whole.next_policy)
                assert lazy.complete
    assert partial > 10  # most queries leave the tree partial


def test_lazy_tree_resumed_equals_a_fresh_search() -> None:
    """Queries after earlier ones give what a fresh tree gives for them (the same
    closed costs and next policies, the same best row); a query on closed ground
    closes nothing more."""
    lib, graph = small_library_graph()
    trims = lib.trim_indices()
    rng = np.random.default_rng(9)
    used = 0
    for goal in rng.choice(trims, 12, replace=False):
        whole = plan_tree(graph, int(goal))
        reach = np.flatnonzero(np.isfinite(whole.cost_to_go))
        if reach.size < 50:
            continue
        used += 1
        kept = LazyPolicyTree(graph, int(goal))
        for _ in range(5):
            rows = rng.choice(reach, 4, replace=False)
            fresh = LazyPolicyTree(graph, int(goal))
            fresh.settle(rows, best=True)
            kept.settle(rows, best=True)
            assert int(np.argmin(kept.cost_to_go[rows])) == int(np.argmin(fresh.cost_to_go[rows]))
            both = fresh.closed(np.arange(len(lib))) & kept.closed(np.arange(len(lib)))
            assert np.all(fresh.closed(np.arange(len(lib))) <= kept.closed(np.arange(len(lib))))
            np.testing.assert_array_equal(kept.cost_to_go[both], fresh.cost_to_go[both])
            np.testing.assert_array_equal(kept.next_policy[both], fresh.next_policy[both])
            before = kept.expanded
            kept.settle(rows)  # every row: no more than the remaining ones need
            again = kept.expanded
            kept.settle(rows)
            assert kept.expanded == again >= before
            np.testing.assert_array_equal(kept.cost_to_go[rows], whole.cost_to_go[rows])
    assert used >= 3


def test_lazy_tree_unreachable_budget_and_errors() -> None:
    lib, graph = small_library_graph()
    trims = lib.trim_indices()
    rng = np.random.default_rng(10)
    for goal in rng.choice(trims, 6, replace=False):
        whole = plan_tree(graph, int(goal))
        dead = np.flatnonzero(np.isinf(whole.cost_to_go))
        if dead.size and np.isfinite(whole.cost_to_go).sum() > 50:
            break
    else:  # pragma: no cover - the library has dead ends
        pytest.fail("no goal with unreachable policies")
    lazy = LazyPolicyTree(graph, int(goal))
    # A budget stops early and leaves a tree that resumes to the same answer.
    far = np.flatnonzero(np.isfinite(whole.cost_to_go))
    far = far[np.argsort(whole.cost_to_go[far])[-3:]]
    assert not lazy.settle(far, budget=5)
    assert lazy.expanded == 5
    assert lazy.settle(far)
    np.testing.assert_array_equal(lazy.cost_to_go[far], whole.cost_to_go[far])
    # Unreachable: inf, found by closing everything that reaches the goal.
    assert not lazy.reachable(int(dead[0]))
    assert lazy.complete and np.all(lazy.closed(dead))
    np.testing.assert_array_equal(lazy.cost_to_go, whole.cost_to_go)
    with pytest.raises(PlanningError, match="cannot be reached"):
        lazy.path_from(int(dead[0]))
    # The best of rows some of which are unreachable: the reachable ones decide.
    fresh = LazyPolicyTree(graph, int(goal))
    rows = np.array([dead[0], far[0]])
    fresh.settle(rows, best=True)
    assert fresh.cost_to_go[far[0]] == whole.cost_to_go[far[0]]
    with pytest.raises(PlanningError, match="outside the library"):
        LazyPolicyTree(graph, len(lib))
    with pytest.raises(PlanningError, match="outside the library"):
        fresh.settle([len(lib)])
    assert fresh.path_from(int(goal)) == [int(goal)]


@pytest.mark.parametrize("where", ["area", "office"])
def test_lazy_tree_on_real_palette_libraries(where: str, request: pytest.FixtureRequest) -> None:
    """The real palette on the 3.5 m area (two halvings) and a 14 m office: random
    goals, queries of the policies whose S contains a random state (best, as the hybrid
    controller asks), then a whole lazy tree: plan_tree's costs, both criteria."""
    from gracenav.world import office_map

    pal = request.getfixturevalue("palette")  # conftest's; `palette` here is synthetic
    if where == "area":
        wm = load_map({"bounds": [[0, 0], [3.5, 3.5]], "obstacles": [], "resolution": 0.05})
        lib = build_library(pal, wm, max_halvings=2)
    else:
        lib = build_library(pal, office_map(14.0, 0.05, seed=1), max_halvings=0)
    graph = build_graph(lib)
    trims = lib.trim_indices()
    rng = np.random.default_rng(12)
    answered = 0
    for cost in ("time", "distance"):
        for goal in rng.choice(trims, 3, replace=False):
            whole = plan_tree(graph.csc(cost), int(goal), criterion=cost)
            lazy = LazyPolicyTree(build_graph(lib), int(goal), criterion=cost)
            for row in rng.choice(len(lib), 16, replace=False):
                state = lib.start_state[row].copy()
                state[2:] += rng.normal(0.0, 0.05, 2)
                hits = lib.start_domain_contains(state[None, :])
                rows = hits.indices[hits.indptr[0] : hits.indptr[1]]
                if rows.size == 0:
                    continue
                lazy.settle(rows, best=True)
                want = whole.cost_to_go[rows]
                if np.isfinite(want).any():
                    assert int(np.argmin(lazy.cost_to_go[rows])) == int(np.argmin(want))
                    answered += 1
                assert_lazy_matches(lazy, whole, graph, cost)
            np.testing.assert_allclose(lazy.whole().cost_to_go, whole.cost_to_go, rtol=1e-12)
    assert answered > 10


def test_lazy_tree_answers_pushes_along_its_path(
    monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> None:
    """After a first query, states pushed off the planned path (velocity perturbed by
    5 cm/s): the best policy is the whole tree's, and most are answered without
    resuming the search (a closed row provably cheapest)."""
    import gracenav.planning.trees as planning_module
    from gracenav.world import office_map

    calls = []
    kernel = planning_module._lazy_settle

    def counted(*args):  # type: ignore[no-untyped-def]
        calls.append(1)
        return kernel(*args)

    monkeypatch.setattr(planning_module, "_lazy_settle", counted)
    shipped = request.getfixturevalue("palette")  # conftest's; `palette` here is synthetic
    lib = build_library(shipped, office_map(14.0, 0.05, seed=1), max_halvings=0)
    graph = build_graph(lib)
    trims = lib.trim_indices()
    rng = np.random.default_rng(13)
    asked = partly_open = 0
    for goal in rng.choice(trims, 16, replace=False):
        whole = plan_tree(graph.csc("time"), int(goal))
        reach = trims[np.isfinite(whole.cost_to_go[trims])]
        start = int(reach[np.argmax(whole.cost_to_go[reach])])
        lazy = LazyPolicyTree(build_graph(lib), int(goal))
        lazy.settle([start], best=True)
        for row in lazy.path_from(start)[1:-1]:
            state = lib.start_state[row].copy()
            state[2:] += rng.normal(0.0, 0.05, 2)
            hits = lib.start_domain_contains(state[None, :])
            rows = hits.indices[hits.indptr[0] : hits.indptr[1]]
            if rows.size == 0 or not np.isfinite(whole.cost_to_go[rows]).any():
                continue
            partly_open += not np.all(lazy.closed(rows))
            lazy.settle(rows, best=True)
            assert int(np.argmin(lazy.cost_to_go[rows])) == int(np.argmin(whole.cost_to_go[rows]))
            asked += 1
    assert asked > 20 and partly_open > 20
    assert len(calls) < 16 + partly_open / 2  # most needed no search
