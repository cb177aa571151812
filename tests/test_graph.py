"""Gracefully prepares graph: hash join against brute force, CSR structure and costs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import synthetic
from scipy.sparse import csgraph
from synthetic import GAINS, palette, primitive

from gracenav import ConfigError
from gracenav.control import ControllerGains
from gracenav.library import PolicyLibrary, build_library
from gracenav.palette import Palette
from gracenav.planning.graph import (
    FINE_COST_FACTOR,
    PreparesGraph,
    build_graph,
    gains_equal,
    gracefully_prepares,
)
from gracenav.policies import (
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
)
from gracenav.world import WorldMap, load_map

X, Y, Z = (0.5, 0.0), (0.0, 0.5), (0.0, 0.0)


# -- inline fixtures ---------------------------------------------------------------------


def tweaked(prim: SampledPrimitive, name: str, **end: float) -> SampledPrimitive:
    """A copy with a changed last sample: ``lean_x`` (rad) or ``accel_x`` (m/s²)."""
    states, pos = prim.states.copy(), prim.position.copy()
    states[-1, 2] += end.get("lean_x", 0.0)
    pos[-1, 4] += end.get("accel_x", 0.0)
    return dataclasses.replace(prim, name=name, states=states, position=pos)


def policy(
    prim: SampledPrimitive,
    start: tuple[float, float] = (0.2, 0.2),
    goal: tuple[float, float] = (0.1, 0.1),
    *,
    gains: ControllerGains = GAINS,
    correlation: float = 0.0,
) -> MotionPolicy:
    return synthetic.policy(prim, start, goal, (1.2, 2.0), gains=gains, correlation=correlation)


def mixed_palette() -> Palette:
    """Chains of rest, cruise and turns, plus one policy failing each condition."""
    rest = primitive("rest", (0.0, 0.0), kind=PrimitiveKind.REST)
    to_rest = primitive("x_to_rest", (1.0, 0.0), X, Z, 2.5)
    return palette(
        policy(rest),
        policy(primitive("cruise_x", (0.5, 0.0), X, X, 1.0, PrimitiveKind.CRUISE)),
        policy(primitive("rest_to_x", (1.0, 0.0), Z, X, 2.5)),
        policy(to_rest),
        policy(primitive("x_to_y", (0.5, 0.5), X, Y, 1.5)),
        policy(primitive("y_to_x", (0.5, 0.5), Y, X, 1.5)),
        policy(primitive("hop", (0.5, 0.5), duration=2.0), (0.15, 0.15), (0.05, 0.05)),
        # (i) fails into anything with S = 0.2: its G is larger.
        policy(primitive("big_goal", (0.5, 0.0), duration=2.0), (0.3, 0.3), (0.25, 0.25)),
        # (iii) fails: other gains.
        policy(
            primitive("other_gains", (1.0, 0.0), duration=2.5),
            gains=ControllerGains(lqr=2 * np.ones((2, 4))),
        ),
        # (ii) fails: a lean jump, and an acceleration jump, at the end.
        policy(tweaked(to_rest, "lean_jump", lean_x=0.01)),
        policy(tweaked(to_rest, "accel_jump", accel_x=0.01)),
        # Correlated domains: G of the rest trim inside this S only if the shapes nest.
        policy(
            primitive("corr_hop", (0.5, 0.0), duration=2.0),
            (0.25, 0.3),
            (0.1, 0.1),
            correlation=-0.6,
        ),
    )


def free_map(x1: float, y1: float, obstacles: list | None = None) -> WorldMap:
    return load_map(
        {"bounds": [[0.0, 0.0], [x1, y1]], "obstacles": obstacles or [], "resolution": 0.05}
    )


def brute_force(lib: PolicyLibrary) -> set[tuple[int, int]]:
    views = [lib.policy(i) for i in range(len(lib))]
    return {
        (i, j)
        for i, a in enumerate(views)
        for j, b in enumerate(views)
        if i != j and gracefully_prepares(a, b)
    }


def edge_set(graph: PreparesGraph) -> set[tuple[int, int]]:
    src, dst = graph.edges()
    return set(zip(src.tolist(), dst.tolist(), strict=True))


# -- tests -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("size", "halvings"), [pytest.param(3.0, 0, marks=pytest.mark.slow), (2.0, 1)]
)
def test_graph_matches_brute_force(size: float, halvings: int) -> None:
    wmap = free_map(size, size, [{"circle": {"center": [size / 2, size / 2], "radius": 0.15}}])
    lib = build_library(
        mixed_palette(), wmap, footprint_radius=0.05, max_halvings=halvings, coverage_samples=200
    )
    assert lib.spacing == pytest.approx(0.5 / 2**halvings, abs=1e-15)
    graph = build_graph(lib)
    expected = brute_force(lib)
    assert len(expected) > 50
    assert edge_set(graph) == expected
    names = [p.name for p in lib.palette.policies]
    src, dst = graph.edges()
    pairs = {
        (names[a], names[b])
        for a, b in zip(lib.palette_index[src], lib.palette_index[dst], strict=True)
    }
    # Each deliberately broken policy loses the edges it should, and only those.
    assert {b for a, b in pairs if a == "big_goal"} <= {"big_goal"}  # (i): G too large
    assert {b for a, b in pairs if a == "other_gains"} <= {"other_gains"}  # (iii)
    assert {a for a, b in pairs if b == "other_gains"} <= {"other_gains"}
    assert not {a for a, _ in pairs} & {"lean_jump", "accel_jump"}  # (ii)
    if size < 3.0:
        return
    assert ("big_goal", "big_goal") in pairs
    assert ("rest", "big_goal") in pairs
    assert ("cruise_x", "lean_jump") in pairs and ("cruise_x", "accel_jump") in pairs
    assert ("other_gains", "other_gains") in pairs
    assert {("x_to_rest", "rest"), ("rest", "rest_to_x"), ("cruise_x", "x_to_y")} <= pairs
    assert ("rest", "corr_hop") in pairs and ("hop", "corr_hop") in pairs


def test_gracefully_prepares_each_condition() -> None:
    pal = mixed_palette()
    lib = build_library(
        pal, free_map(4.0, 4.0), footprint_radius=0.05, max_halvings=0, coverage_samples=200
    )
    names = [p.name for p in pal.policies]

    def find(name: str, k: int, x: float, y: float) -> int:
        p = names.index(name)
        sel = np.flatnonzero(
            (lib.palette_index == p)
            & (lib.orientation == k)
            & np.all(np.abs(lib.start_xy - [x, y]) < 1e-9, axis=1)
        )
        assert sel.size == 1, (name, k, x, y)
        return int(sel[0])

    rest_at = find("rest", 0, 2.0, 2.0)
    v = lib.policy
    assert gracefully_prepares(v(find("x_to_rest", 0, 1.0, 2.0)), v(rest_at))
    assert gracefully_prepares(v(find("x_to_rest", 2, 3.0, 2.0)), v(rest_at))  # rotated by 180°
    assert not gracefully_prepares(v(find("x_to_rest", 0, 1.0, 1.5)), v(rest_at))  # ends elsewhere
    assert not gracefully_prepares(v(find("big_goal", 0, 1.5, 2.0)), v(rest_at))  # (i)
    assert not gracefully_prepares(v(find("lean_jump", 0, 1.0, 2.0)), v(rest_at))  # (ii) lean
    assert not gracefully_prepares(v(find("accel_jump", 0, 1.0, 2.0)), v(rest_at))  # (ii) accel
    assert not gracefully_prepares(v(find("other_gains", 0, 1.0, 2.0)), v(rest_at))  # (iii)
    assert not gracefully_prepares(v(find("rest_to_x", 0, 1.0, 2.0)), v(rest_at))  # moving end
    # Turns: +x -> +y then, rotated by 90°, +y -> -x.
    assert gracefully_prepares(v(find("x_to_y", 0, 1.5, 1.5)), v(find("x_to_y", 1, 2.0, 2.0)))
    assert not gracefully_prepares(v(find("x_to_y", 0, 1.5, 1.5)), v(find("x_to_y", 0, 2.0, 2.0)))
    # The rest trim prepares itself, but the graph holds no self-loops.
    assert gracefully_prepares(v(rest_at), v(rest_at))
    graph = build_graph(lib)
    assert rest_at not in graph.successors(rest_at).tolist()
    assert graph.adjacency.diagonal().sum() == 0.0


def test_gains_equal() -> None:
    assert gains_equal(GAINS, GAINS)
    assert gains_equal(GAINS, ControllerGains(lqr=np.ones((2, 4))))
    assert not gains_equal(GAINS, ControllerGains(lqr=2 * np.ones((2, 4))))
    assert not gains_equal(GAINS, dataclasses.replace(GAINS, friction_compensation=False))


def test_csr_shapes_and_costs() -> None:
    lib = build_library(
        mixed_palette(),
        free_map(3.0, 3.0),
        footprint_radius=0.05,
        max_halvings=0,
        coverage_samples=200,
    )
    graph = build_graph(lib)
    n = len(lib)
    assert graph.num_nodes == n and graph.adjacency.shape == (n, n)
    assert graph.num_edges == graph.adjacency.nnz > 0
    t, d = graph.csr("time"), graph.csr("distance")
    assert t is graph.adjacency
    assert d.shape == (n, n) and d.nnz == t.nnz
    np.testing.assert_array_equal(d.indices, t.indices)
    np.testing.assert_array_equal(d.indptr, t.indptr)
    assert t.has_sorted_indices
    src, dst = graph.edges()
    assert np.all(src != dst)
    # A fine copy costs FINE_COST_FACTOR times its duration or length, exactly.
    factor = np.where(lib.is_fine(np.arange(n)), FINE_COST_FACTOR, 1.0)
    assert 0 < np.count_nonzero(factor > 1) < n
    np.testing.assert_allclose(t.data, (factor * lib.durations)[src], rtol=0, atol=0)
    np.testing.assert_allclose(d.data, (factor * lib.path_lengths)[src], rtol=0, atol=0)
    np.testing.assert_array_equal(graph.time_weights, t.data)
    np.testing.assert_array_equal(graph.node_cost("time"), factor * lib.durations)
    np.testing.assert_array_equal(graph.node_cost("distance"), factor * lib.path_lengths)
    # Costs by construction: a 1 s cruise trim of 0.5 m.
    cruise = np.flatnonzero(lib.palette_index[src] == 1)
    np.testing.assert_allclose(t.data[cruise], 1.0, atol=1e-12)
    np.testing.assert_allclose(d.data[cruise], 0.5, rtol=1e-9)
    # Rest trims cost no distance: their edges are explicit zeros that csgraph keeps.
    zero = np.flatnonzero(d.data == 0.0)
    assert zero.size > 0
    i, j = int(src[zero[0]]), int(dst[zero[0]])
    dist = csgraph.dijkstra(d, indices=i)
    assert dist[j] == 0.0
    assert np.isfinite(csgraph.dijkstra(t, indices=i)[j])
    with pytest.raises(ConfigError, match="cost"):
        graph.csr("energy")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="cost"):
        graph.node_cost("energy")  # type: ignore[arg-type]
    assert "PreparesGraph(" in repr(graph)


def test_csc_is_the_adjacency_by_columns_built_once() -> None:
    lib = build_library(
        mixed_palette(),
        free_map(3.0, 3.0),
        footprint_radius=0.05,
        max_halvings=1,
        coverage_samples=100,
    )
    graph = build_graph(lib)
    for cost in ("distance", "time"):
        got, want = graph.csc(cost), graph.csr(cost).tocsc()  # type: ignore[arg-type]
        assert got.format == "csc" and got.shape == want.shape and got.has_sorted_indices
        assert got.indices.dtype == got.indptr.dtype == np.int32
        np.testing.assert_array_equal(got.indptr, want.indptr)
        np.testing.assert_array_equal(got.indices, want.indices)
        np.testing.assert_array_equal(got.data, want.data)  # explicit zeros included
        assert graph.csc(cost) is got  # cached
    # Both costs share one index structure; the transpose is the reversed graph, uncopied.
    t, d = graph.csc("time"), graph.csc("distance")
    assert np.shares_memory(t.indices, d.indices) and np.shares_memory(t.indptr, d.indptr)
    assert np.any(d.data == 0.0) and not np.any(t.data == 0.0)
    rev = t.T
    assert rev.format == "csr" and np.shares_memory(rev.indices, t.indices)
    src, dst = graph.edges()
    reversed_edges = set(zip(*np.nonzero(rev.toarray()), strict=True))
    assert {(int(b), int(a)) for a, b in zip(src, dst, strict=True)} == reversed_edges
    with pytest.raises(ConfigError, match="cost"):
        graph.csc("energy")  # type: ignore[arg-type]


def test_bad_inputs() -> None:
    lib = build_library(
        mixed_palette(),
        free_map(2.0, 2.0),
        footprint_radius=0.05,
        max_halvings=0,
        coverage_samples=100,
    )
    with pytest.raises(ConfigError, match="PolicyLibrary"):
        build_graph("library")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="atol"):
        build_graph(lib, atol=0.0)
    with pytest.raises(ConfigError, match="atol"):
        build_graph(lib, atol=0.2)


def test_empty_library_gives_an_empty_graph() -> None:
    wmap = free_map(1.0, 1.0)
    big = palette(policy(primitive("rest", (0.0, 0.0), kind=PrimitiveKind.REST), (0.5, 0.5)))
    lib = build_library(big, wmap, max_halvings=0, coverage_samples=50)
    assert len(lib) == 0
    graph = build_graph(lib)
    assert graph.num_nodes == 0 and graph.num_edges == 0
    assert graph.csr("distance").shape == (0, 0)
    assert graph.csc("distance").shape == (0, 0) and graph.csc("time").nnz == 0


@pytest.mark.parametrize("dense", [True, False])
def test_lattice_edges_generate_the_matrices(monkeypatch: pytest.MonkeyPatch, dense: bool) -> None:
    """The edges are generated from the lattice, through the dense (point, type) table or
    by bisection among a type's rows; the matrices built from them agree row by row with
    the generator, and nothing per edge is built until asked for."""
    import gracenav.planning.graph as graph_module

    if not dense:
        monkeypatch.setattr(graph_module, "DENSE_LOOKUP", 0)
    lib = build_library(
        mixed_palette(),
        free_map(3.0, 3.0, [{"rectangle": {"min": [1.2, 1.2], "max": [1.6, 1.7]}}]),
        footprint_radius=0.05,
        max_halvings=1,
        coverage_samples=100,
    )
    graph = build_graph(lib)
    assert (graph.lattice_edges.table.size > 0) == dense
    assert not graph._cache  # no matrix yet
    e = graph.num_edges
    assert e > 1000 and not any(k.startswith("csr") or k.startswith("csc") for k in graph._cache)
    csc = graph.csc("time")
    assert "csr" not in graph._cache  # the reversed graph is built without the forward one
    a = graph.adjacency
    assert a.nnz == csc.nnz == e
    for i in range(len(lib)):
        np.testing.assert_array_equal(graph.successors(i), a.indices[a.indptr[i] : a.indptr[i + 1]])
    assert edge_set(graph) == {
        (int(i), int(j))
        for j in range(len(lib))
        for i in csc.indices[csc.indptr[j] : csc.indptr[j + 1]]
    }
    with pytest.raises(IndexError):
        graph.successors(len(lib))


def test_lookup_modes_give_the_same_graph(monkeypatch: pytest.MonkeyPatch) -> None:
    import gracenav.planning.graph as graph_module

    lib = build_library(
        mixed_palette(),
        free_map(2.5, 2.0),
        footprint_radius=0.05,
        max_halvings=1,
        coverage_samples=100,
    )
    dense = build_graph(lib).adjacency
    monkeypatch.setattr(graph_module, "DENSE_LOOKUP", 0)
    sparse_lookup = build_graph(lib).adjacency
    np.testing.assert_array_equal(dense.indptr, sparse_lookup.indptr)
    np.testing.assert_array_equal(dense.indices, sparse_lookup.indices)


def test_search_form_stores_the_reversed_graph_below_the_limit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import gracenav.planning.graph as graph_module

    lib = build_library(
        mixed_palette(),
        free_map(2.0, 2.0),
        footprint_radius=0.05,
        max_halvings=0,
        coverage_samples=100,
    )
    graph = build_graph(lib)
    assert graph.search_form("distance") is graph.csc("distance")
    assert graph.cached_csc("time") is None
    monkeypatch.setattr(graph_module, "STORED_EDGES", 0)
    fresh = build_graph(lib)
    assert fresh.search_form("time") is fresh and fresh.cached_csc("time") is None
    with pytest.raises(ConfigError, match="cost"):
        fresh.search_form("energy")  # type: ignore[arg-type]


@pytest.mark.parametrize("dense", [True, False])
def test_edge_count_of_the_shipped_palette(
    monkeypatch: pytest.MonkeyPatch, box_room_library: PolicyLibrary, dense: bool
) -> None:
    """The edge count (merged by point without the dense table) is the matrices' on a
    library of the shipped palette, whose rest policies prepare themselves."""
    import gracenav.planning.graph as graph_module

    if not dense:
        monkeypatch.setattr(graph_module, "DENSE_LOOKUP", 0)
    graph = build_graph(box_room_library)
    assert (graph.lattice_edges.table.size > 0) == dense
    e = graph.num_edges
    assert e == graph.adjacency.nnz > 10_000
