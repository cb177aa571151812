"""The gracefully prepares graph Ω(L) of a motion policy library (paper Sec. III-C, IV-A).

Φ1 gracefully prepares Φ2 (Φ1 ⪰G Φ2) iff

(i) G1 ⊂ S2: the goal domain of Φ1 lies in the start domain of Φ2;
(ii) σ1(t_f1) = σ2(0) and σ̇1(t_f1) = σ̇2(0): the reference position, velocity and
     acceleration are continuous through the switch (here: the position samples' last
     row of Φ1 equals the first row of Φ2 in x, y, ẋ, ẏ, ẍ, ÿ), and so are the body
     lean and lean rate of the reference states;
(iii) φ1(t_f1) = φ2(0): both policies use identical controller gains.

Nodes of Ω(L) are library policies; there is an edge i → j iff policy i gracefully
prepares policy j (i ≠ j: a rest trim prepares itself, but a self-loop never lies on
a shortest path and is left out).

Construction is a hash join, O(N + E) in the library size N and edge count E. On a
lattice every end state is a lattice point plus a boundary state that depends on the
palette policy and orientation only (its *type*, 4 P of them). Conditions (i), (iii)
and (ii) except position are decided once per pair of types (≈156² pairs); the end
position of each policy is its start cell plus its type's lattice offset (its end
displacement over the spacing, rounded, accepted if within ``atol``), and the
successors are the policies of compatible types starting at that cell, found by a
table lookup on (type, lattice point). No pair of library policies is ever compared.

The edges are not stored: :func:`build_graph` keeps the type tables, each policy's type
and point, and the lookup table (:class:`LatticeEdges`, about 8 bytes per policy plus
4 bytes per (point, type) pair), O(N + T²) to build. The successors or predecessors of
a policy are generated on demand (:mod:`gracenav.planning._search`), and the sparse matrices are
built from them on first use. On a 100 m open hall this is the difference between
175 M edges (about 5 GiB with both costs and the reversed graph) and 140 MiB.

Edge costs: entry (i, j) of the adjacency matrix is the cost of *executing policy i*
(then switching to j): its duration t_f (s) for the fastest-time criterion, or the
XY length of its reference path (m) for the shortest-path criterion
(:class:`CostCriterion`, by value :data:`CostName`). A fine copy of a policy
(:attr:`gracenav.policies.VerificationOptions.fine_scales`) costs
:data:`FINE_COST_FACTOR` times as much: its domains hold the robot as well as the
policy's own, but leave a push less room (it runs nearer obstacles and its S is
smaller), so trees take one only where it saves that much, in passages the unscaled
policies do not fit. The
shortest-path distance from i to a goal node is then the cost-to-go of starting
policy i, not counting the goal policy itself. Rest trims have zero path length, so
distance graphs hold explicit zero entries (which :mod:`scipy.sparse.csgraph` treats
as edges).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import weakref
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from gracenav.errors import ConfigError
from gracenav.library import InstantiatedPolicy, PolicyLibrary
from gracenav.planning._search import (
    _count_all_edges,
    _count_edges,
    _count_rows_edges,
    _fill_edges,
    _point_move_mask,
    _successors_of,
)

__all__ = [
    "DENSE_LOOKUP",
    "FINE_COST_FACTOR",
    "STORED_EDGES",
    "CostCriterion",
    "CostName",
    "LatticeEdges",
    "PreparesGraph",
    "build_graph",
    "gains_equal",
    "gracefully_prepares",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


class CostCriterion(enum.Enum):
    """Optimality criterion of the trees: what executing a policy costs."""

    TIME = "time"
    DISTANCE = "distance"


#: A :class:`CostCriterion` by its value, as the graph's methods and scenario files take it.
CostName = Literal["time", "distance"]
_COSTS = tuple(c.value for c in CostCriterion)

#: Cost of a fine copy over that of the policy it copies (see the module notes). With
#: 1 (no preference) the tree on the 5 m room runs beside its box on fine copies to
#: save 3 % of the time, and 11 of 300 pushes there (bench/bench_pushes.py, seed 0)
#: end in balancing mode, 9 of them touching the box, instead of none with 2.
FINE_COST_FACTOR = 2.0

#: Default absolute tolerance of state continuity (m, m/s, m/s², rad, rad/s).
DEFAULT_ATOL = 1e-6
#: Largest (type, point) lookup table (int32 entries: 256 MiB) kept with the implicit
#: edges; a larger one is left out and a row found by bisection, about 10 times slower
#: (the 100 m office at d with the fine copies: 35 M entries, 20 s instead of 2 s to
#: store its reversed graph).
DENSE_LOOKUP = 1 << 26
#: Most edges for which :meth:`PreparesGraph.search_form` stores the reversed graph
#: (12 bytes per edge: 96 MiB). Storing it takes about 0.14 µs an edge (2.3 s for the
#: 16.7 M edges of the 30 m × 50 m warehouse at d/2), paid before the first command;
#: beyond this the trees search the implicit edges lazily (the same trees), and the
#: warehouse's first command comes 1.5 s sooner (bench/bench_bigmaps.py).
STORED_EDGES = (96 << 20) // 12

# Most rows whose edges are counted to decide that a graph is beyond STORED_EDGES
# (PreparesGraph._fits_stored): 20 000 put the mean within 4.4 edges a row of the
# graph's for 192 successor types (the shipped palette's most).
_EDGE_SAMPLE_ROWS = 20_000


def gains_equal(a: object, b: object) -> bool:
    """Whether two controller gain sets are identical (every field equal, arrays exactly)."""
    if a is b:
        return True
    if type(a) is not type(b) or not dataclasses.is_dataclass(a):
        return bool(a == b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif x != y:
            return False
    return True


def gracefully_prepares(
    first: InstantiatedPolicy, second: InstantiatedPolicy, *, atol: float = DEFAULT_ATOL
) -> bool:
    """Φ1 ⪰G Φ2 by the general definition, for any two instantiated policies.

    (i) uses the exact ellipsoid containment
    :meth:`gracenav.policies.domains.EllipsoidalDomain.contains_domain` (tolerance 1e-9 on the
    quadratic form); (ii) compares the world-frame reference rows (x, y, ẋ, ẏ, ẍ, ÿ)
    and lean / lean rate at t_f1 and 0 within ``atol``; (iii) compares the gains.
    Meant for checks and tests: :func:`build_graph` decides the same relation in bulk.
    A capture regulator is never prepared (it only catches a robot that no other
    policy's S contains), so it is never ``second``.
    """
    if second.policy.capture:
        return False
    a_ref, b_ref = first.reference_positions, second.reference_positions
    if not np.all(np.abs(a_ref[-1] - b_ref[0]) <= atol):
        return False
    if not np.all(np.abs(first.reference_lean[-1] - second.reference_lean[0]) <= atol):
        return False
    if not gains_equal(first.policy.gains, second.policy.gains):
        return False
    return second.start_domain.contains_domain(first.goal_domain, tol=1e-9)


@dataclass(frozen=True, eq=False)
class LatticeEdges:
    """The edges of Ω(L) in implicit form: what generates them from the lattice.

    A library policy is a (type, lattice point) pair. Policy i of type t gracefully
    prepares policy j iff j's type is compatible with t (conditions (i), (iii) and
    (ii) except position, decided once per pair of types) and j starts at i's start
    point plus t's end offset in lattice cells. So every edge is found from the
    type tables and a lookup from (type, point) to library row; none is stored.

    Attributes
    ----------
    lattice_shape : tuple of int
        (ny, nx) of the library's lattice.
    row_type, row_point : ndarray of int32, shape (N,)
        Type and lattice point id (iy · nx + ix) of each library row.
    succ_ptr : ndarray of int64, shape (T + 1,)
    succ_type : ndarray of int32
        Types compatible as successors of each type, ascending:
        ``succ_type[succ_ptr[t]:succ_ptr[t + 1]]``.
    pred_ptr : ndarray of int64, shape (T + 1,)
    pred_type : ndarray of int32
        Types compatible as predecessors of each type, grouped by end offset (y, then
        x), ascending within a group.
    offset : ndarray of int64, shape (T, 2)
        End offset of each type in lattice cells (x, y).
    type_first : ndarray of int64, shape (T + 1,)
        First library row of each type (rows are in type order).
    table : ndarray of int32, shape (P · T,) or (0,)
        Library row of each (point, type) pair (−1 if none) at point · T + t, when it
        fits in :data:`DENSE_LOOKUP` entries; otherwise empty and a row is found by
        bisection among its type's rows. Point-major: the successors of a policy, all
        at one point, are one contiguous stretch of the table.
    """

    lattice_shape: tuple[int, int]
    row_type: NDArray[np.int32]
    row_point: NDArray[np.int32]
    succ_ptr: IntArray
    succ_type: NDArray[np.int32]
    pred_ptr: IntArray
    pred_type: NDArray[np.int32]
    offset: IntArray
    type_first: IntArray
    table: NDArray[np.int32]

    @property
    def nbytes(self) -> int:
        """Bytes held by the arrays."""
        return sum(
            int(getattr(self, f.name).nbytes)
            for f in dataclasses.fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        )

    def kernel_args(self) -> tuple[Any, ...]:
        """The arrays and sizes the compiled edge generators take, in their order."""
        ny, nx = self.lattice_shape
        return (
            self.row_type,
            self.row_point,
            nx,
            ny,
            self.pred_ptr,
            self.pred_type,
            self.succ_ptr,
            self.succ_type,
            self.offset[:, 0].copy(),
            self.offset[:, 1].copy(),
            self.type_first,
            self.table,
        )


@dataclass(frozen=True, eq=False)
class PreparesGraph:
    """The gracefully prepares graph Ω(L): directed, nodes = library policies.

    The edges are generated from the lattice (:class:`LatticeEdges`); the sparse
    matrices below are built on first use and kept, so a graph on a building-scale
    map costs memory per edge only if a matrix is asked for (see the module notes
    and :func:`gracenav.planning.plan_tree`, which searches the implicit form).

    Attributes
    ----------
    library : PolicyLibrary
    lattice_edges : LatticeEdges
        The implicit form of the edges.
    atol : float
        Tolerance of the state continuity checks.

    Notes
    -----
    Every edge i → j costs the execution of its source policy i, so the weights of
    the edges into j, listed by :meth:`csc`, are the node costs of their sources.
    """

    library: PolicyLibrary
    lattice_edges: LatticeEdges
    atol: float = DEFAULT_ATOL
    _cache: dict[str, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __repr__(self) -> str:
        return f"PreparesGraph({self.num_nodes} nodes, {self.num_edges} edges)"

    @property
    def num_nodes(self) -> int:
        """N, the number of library policies."""
        return len(self.library)

    @property
    def num_edges(self) -> int:
        """E, the number of gracefully prepares edges (counted on first use, O(N + E))."""
        out = self._cache.get("num_edges")
        if out is None:
            a = self._cache.get("csr")
            stored = self._cache.get("csc-structure")
            if a is not None:
                out = int(a.nnz)
            elif stored is not None:
                out = int(stored[0][-1])
            else:
                out = int(_count_all_edges(*self.lattice_edges.kernel_args()))
            self._cache["num_edges"] = out
        return int(out)

    @property
    def adjacency(self) -> sparse.csr_matrix:
        """The adjacency matrix (N, N), built on first use and kept (20 bytes per edge
        with :attr:`distance_weights`).

        Entry (i, j) is the fastest-time cost of the edge i → j: the duration of
        policy i (s). Sorted indices, no duplicates, no self-loops.
        """
        out = self._cache.get("csr")
        if out is None:
            n = self.num_nodes
            indptr, indices = _materialise(self, forward=True)
            data = np.repeat(self.node_cost("time"), np.diff(indptr))
            out = sparse.csr_matrix((data, indices, indptr), shape=(n, n), copy=False)
            out.has_sorted_indices = True
            self._cache["csr"] = out
        return out

    @property
    def distance_weights(self) -> FloatArray:
        """Shortest-path cost of each edge, aligned with ``adjacency.data``: the XY path
        length of the source policy's reference (m), shape (E,)."""
        out = self._cache.get("distance_weights")
        if out is None:
            out = np.repeat(self.node_cost("distance"), np.diff(self.adjacency.indptr))
            self._cache["distance_weights"] = out
        return out

    @property
    def time_weights(self) -> FloatArray:
        """Fastest-time cost of each stored edge (s), aligned with ``adjacency.data``."""
        out: FloatArray = self.adjacency.data
        return out

    def node_cost(self, cost: CostName = "time") -> FloatArray:
        """Cost of executing each policy: duration (s) or XY path length (m), times
        :data:`FINE_COST_FACTOR` for a fine copy, shape (N,)."""
        key = f"node_cost_{cost}"
        out = self._cache.get(key)
        if out is None:
            out = self._cache[key] = self.type_cost(cost)[self.library.type_index]
        return np.asarray(out)

    def type_cost(self, cost: CostName = "time") -> FloatArray:
        """Cost of executing a policy of each type: duration (s) or XY path length (m),
        times :data:`FINE_COST_FACTOR` for a fine copy, shape (T,);
        ``node_cost(cost)[i] == type_cost(cost)[type of i]``."""
        _check_cost(cost)
        types = self.library.types
        base = types.duration if cost == "time" else types.path_length
        out: FloatArray = np.where(types.fine_factor < 1.0, FINE_COST_FACTOR * base, base)
        return out

    def csr(self, cost: CostName = "time") -> sparse.csr_matrix:
        """The adjacency matrix (N, N) weighted by ``cost`` ("time" or "distance").

        Both share one sparsity structure; only ``data`` differs.
        """
        _check_cost(cost)
        if cost == "time":
            return self.adjacency
        a = self.adjacency
        return sparse.csr_matrix(
            (self.distance_weights, a.indices, a.indptr), shape=a.shape, copy=False
        )

    def csc(self, cost: CostName = "time") -> sparse.csc_matrix:
        """The adjacency matrix (N, N) weighted by ``cost``, stored by columns.

        Column j lists the policies that gracefully prepare j, so ``csc(cost).T`` is the
        reversed graph in CSR form without a copy. Built on the first call (O(N + E),
        from the lattice, without the forward matrix) and kept: the row indices and
        column pointers (int32 below 2³¹ edges) are shared by both costs, the weights
        (float64) are per cost, so the first cost asked for costs 12 bytes per edge
        (+ 4 per node), the second 8 more. Sorted indices, the same entries as
        :meth:`csr` (explicit zeros included).
        """
        _check_cost(cost)
        out = self._cache.get(f"csc-{cost}")
        if out is None:
            base = self._cache.get("csc-structure")
            if base is None:
                base = self._cache["csc-structure"] = _materialise(self, forward=False)
            indptr, indices = base
            data = np.ascontiguousarray(self.node_cost(cost)[indices], dtype=np.float64)
            n = self.num_nodes
            out = sparse.csc_matrix((data, indices, indptr), shape=(n, n), copy=False)
            out.has_sorted_indices = True
            self._cache[f"csc-{cost}"] = out
        return out

    def point_moves(self) -> tuple[NDArray[np.uint64], IntArray, IntArray, IntArray]:
        """How a lattice point can move along the graph's edges, built on first use and
        kept (8 bytes per lattice point for up to 64 moves).

        A *move* is a nonzero end offset of a policy type with successors: a policy
        of that type at point p has its successors at p + the offset.

        Returns
        -------
        mask : ndarray of uint64, shape (ny · nx, ⌈K / 64⌉)
            Bit k of ``mask[p, k // 64]`` is set iff a library policy at point p (id
            iy · nx + ix) makes move k.
        move_dx, move_dy : ndarray of int64, shape (K,)
            The moves in lattice cells.
        type_move : ndarray of int64, shape (T,)
            The move of each type; −1 for a type without successors or one that ends
            where it starts.
        """
        out = self._cache.get("point-moves")
        if out is None:
            e = self.lattice_edges
            ny, nx = e.lattice_shape
            moving = (np.diff(e.succ_ptr) > 0) & np.any(e.offset != 0, axis=1)
            moves, inverse = np.unique(e.offset[moving], axis=0, return_inverse=True)
            type_move = np.full(e.offset.shape[0], -1, dtype=np.int64)
            type_move[moving] = inverse.ravel()
            words = max(1, -(-moves.shape[0] // 64))
            mask = _point_move_mask(e.row_type, e.row_point, type_move, nx * ny, words)
            out = self._cache["point-moves"] = (
                mask,
                np.ascontiguousarray(moves[:, 0], dtype=np.int64),
                np.ascontiguousarray(moves[:, 1], dtype=np.int64),
                type_move,
            )
        return out

    def cached_csc(self, cost: CostName = "time") -> sparse.csc_matrix | None:
        """:meth:`csc` if it has been built, else None (nothing is built)."""
        _check_cost(cost)
        return self._cache.get(f"csc-{cost}")

    def search_form(self, cost: CostName = "time") -> sparse.csc_matrix | PreparesGraph:
        """What to give :func:`gracenav.planning.plan_tree` for repeated trees.

        The reversed graph in CSC form (:meth:`csc`, built now) when the graph has at
        most :data:`STORED_EDGES` edges, the fastest to search; otherwise the graph
        itself, whose edges the search generates from the lattice (no memory per
        edge). Both give the same trees.
        """
        _check_cost(cost)
        if self._fits_stored():
            return self.csc(cost)
        return self

    def _fits_stored(self) -> bool:
        """Whether the graph has at most :data:`STORED_EDGES` edges. The count is exact
        unless a seeded sample of m rows (2 %, at most ``_EDGE_SAMPLE_ROWS``) puts it
        beyond the limit by more than its Hoeffding margin (a row has at most R edges,
        R the most successor types of a type: the sample's mean is within
        R √(ln(2/δ) / 2m) of the graph's but for a probability δ = 10⁻⁹): a decision
        between two equivalent forms, kept, which spares counting the edges of a
        building-scale graph (≈ 3 s for the hall's 175 M, 21 s for the 79 M of the
        100 m office at d/2, whose lookups bisect)."""
        n = self.num_nodes
        if self._cache.get("sampled-beyond-stored"):
            return False
        if "num_edges" not in self._cache and "csr" not in self._cache and n > 1_000_000:
            m = min(n // 50, _EDGE_SAMPLE_ROWS)
            rows = np.sort(np.random.default_rng(0).choice(n, m, replace=False))
            sample = _count_rows_edges(rows, *self.lattice_edges.kernel_args())
            most = int(np.diff(self.lattice_edges.succ_ptr).max(initial=0))
            margin = most * math.sqrt(math.log(2.0 / 1e-9) / (2.0 * m))
            if (sample / m - margin) * n > STORED_EDGES:
                self._cache["sampled-beyond-stored"] = True  # each controller asks
                return False
        return self.num_edges <= STORED_EDGES

    def successors(self, i: int) -> IntArray:
        """Library rows that policy ``i`` gracefully prepares, ascending."""
        n = self.num_nodes
        if not 0 <= i < n:
            raise IndexError(f"library policy {i} out of range for a library of {n} policies")
        args = self.lattice_edges.kernel_args()
        buf = np.empty(max(int(np.diff(self.lattice_edges.succ_ptr).max(initial=0)), 1), np.int64)
        m = _successors_of(int(i), buf, *args)
        out: IntArray = buf[:m].copy()
        return out

    def edges(self) -> tuple[IntArray, IntArray]:
        """Source and target rows of every edge, shapes (E,), in CSR order."""
        a = self.adjacency
        src = np.repeat(np.arange(a.shape[0], dtype=np.int64), np.diff(a.indptr))
        return src, a.indices.astype(np.int64)


def _check_cost(cost: str) -> None:
    if cost not in _COSTS:
        raise ConfigError(f"cost must be one of {', '.join(_COSTS)}, got {cost!r}")


def _gains_classes(library: PolicyLibrary) -> IntArray:
    """Class id of each palette policy's gains (equal gains, equal id)."""
    reps: list[Any] = []
    out = np.empty(len(library.palette.policies), dtype=np.int64)
    for p, pol in enumerate(library.palette.policies):
        for k, g in enumerate(reps):
            if gains_equal(g, pol.gains):
                out[p] = k
                break
        else:
            out[p] = len(reps)
            reps.append(pol.gains)
    return out


#: :func:`_type_edges`'s tables by the identity of the library's types (held weakly;
#: every library of a palette shares its types), for the palette (held weakly) and the
#: (spacing, atol) they were computed for: they depend on nothing else.
_TYPE_EDGES: dict[int, tuple[weakref.ref[Any], weakref.ref[Any], dict[str, Any]]] = {}


_TypeEdges = tuple[IntArray, NDArray[np.int32], IntArray, NDArray[np.int32], IntArray]


def _type_edges(library: PolicyLibrary, atol: float) -> _TypeEdges:
    """The type-level tables of :class:`LatticeEdges` (``succ_ptr``, ``succ_type``,
    ``pred_ptr``, ``pred_type``, ``offset``), read-only, computed once per palette's
    types, spacing and tolerance (:func:`_type_compatibility`)."""
    types, palette = library.types, library.palette
    key = id(types)
    entry = _TYPE_EDGES.get(key)
    if entry is None or entry[0]() is not types or entry[1]() is not palette:

        def forget(ref: weakref.ref[Any]) -> None:
            if key in _TYPE_EDGES and _TYPE_EDGES[key][0] is ref:
                del _TYPE_EDGES[key]

        entry = _TYPE_EDGES[key] = (weakref.ref(types, forget), weakref.ref(palette), {})
    which = f"{library.spacing!r}-{atol!r}"
    got = entry[2].get(which)
    if got is None:
        compat, cells = _type_compatibility(library, atol)
        succ_ptr = np.concatenate([[0], np.cumsum(compat.sum(axis=1))]).astype(np.int64)
        succ_type = np.nonzero(compat)[1].astype(np.int32)
        pred_ptr = np.concatenate([[0], np.cumsum(compat.sum(axis=0))]).astype(np.int64)
        # Predecessor types grouped by end offset (one table row per group), types ascending.
        succ_of, pred_of = np.nonzero(compat.T)
        order = np.lexsort((pred_of, cells[pred_of, 0], cells[pred_of, 1], succ_of))
        pred_type = pred_of[order].astype(np.int32)
        offset = np.ascontiguousarray(cells, dtype=np.int64)
        got = (succ_ptr, succ_type, pred_ptr, pred_type, offset)
        for a in got:
            a.flags.writeable = False
        entry[2][which] = got
    out: _TypeEdges = got
    return out


def _type_compatibility(library: PolicyLibrary, atol: float) -> tuple[BoolArray, IntArray]:
    """Compatible type pairs (T, T) and each type's end offset in lattice cells (T, 2);
    types whose end is off the lattice have no successor."""
    types = library.types
    s = library.spacing
    # Each test runs on the distinct rows only (a policy's larger-domain variants share
    # its boundary states and all policies share G), then is expanded to type pairs.
    end8, end_of = np.unique(types.boundary("end"), axis=0, return_inverse=True)
    start8, start_of = np.unique(types.boundary("start"), axis=0, return_inverse=True)
    states_ok = np.all(np.abs(end8[:, None, :] - start8[None, :, :]) <= atol, axis=2)
    states_ok = states_ok[end_of.reshape(-1)][:, start_of.reshape(-1)]
    gains = _gains_classes(library)[types.palette_index]
    gains_ok = gains[:, None] == gains[None, :]
    # (i) G1 ⊂ S2 for concentric domains of shape M ⊗ I₂: M_S2 ≼ M_G1 (for a shared
    # domain shape this is DomainRadii.contains: every extent of G1 at most S2's).
    goal_m, goal_of = np.unique(types.goal_shape, axis=0, return_inverse=True)
    start_m, start_m_of = np.unique(types.start_shape, axis=0, return_inverse=True)
    diff = goal_m[:, None] - start_m[None, :]
    tr = diff[..., 0, 0] + diff[..., 1, 1]
    det = diff[..., 0, 0] * diff[..., 1, 1] - diff[..., 0, 1] * diff[..., 1, 0]
    lam_min = 0.5 * tr - np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
    scale = np.maximum(
        np.abs(goal_m).max(axis=(1, 2))[:, None],
        np.abs(start_m).max(axis=(1, 2))[None, :],
    )
    domain_ok = (lam_min >= -1e-9 * scale)[goal_of.reshape(-1)][:, start_m_of.reshape(-1)]
    cells = np.rint(types.end_offset / s)
    on_lattice = np.all(np.abs(types.end_offset - cells * s) <= atol, axis=1)
    # Capture regulators only catch a robot that no other policy's S contains: no
    # policy prepares one (they are sources of the graph).
    compat = states_ok & gains_ok & domain_ok & on_lattice[:, None] & ~types.is_capture[None, :]
    return compat, cells.astype(np.int64)


def build_graph(library: PolicyLibrary, *, atol: float = DEFAULT_ATOL) -> PreparesGraph:
    """Build the gracefully prepares graph of a library by hashing end states.

    Parameters
    ----------
    library : PolicyLibrary
    atol : float
        Absolute tolerance of the continuity conditions (ii) on position (m), velocity
        (m/s), acceleration (m/s²), lean (rad) and lean rate (rad/s); must be below a
        quarter of the lattice spacing.

    Returns
    -------
    PreparesGraph
        Edges i → j for every i ≠ j with Φ_i ⪰G Φ_j; see the module notes for costs.

    Raises
    ------
    ConfigError
        If ``library`` is not a PolicyLibrary or ``atol`` is not a small positive number.
    """
    if not isinstance(library, PolicyLibrary):
        raise ConfigError(
            f"library must be a PolicyLibrary (see gracenav.library.build_library), got "
            f"{type(library).__name__}"
        )
    if not (isinstance(atol, int | float) and 0 < atol < 0.25 * library.spacing):
        raise ConfigError(
            f"atol must be positive and below a quarter of the lattice spacing "
            f"({0.25 * library.spacing:g} m), got {atol!r}"
        )
    ny, nx = library.lattice_shape
    n_points = nx * ny
    succ_ptr, succ_type, pred_ptr, pred_type, offset = _type_edges(library, atol)
    n_types = offset.shape[0]
    row_type = np.ascontiguousarray(library.type_index, dtype=np.int32)
    cell = library.start_cell
    row_point = np.ascontiguousarray(cell[:, 1] * nx + cell[:, 0], dtype=np.int32)
    type_first = np.searchsorted(row_type, np.arange(n_types + 1)).astype(np.int64)
    if n_types * n_points <= DENSE_LOOKUP:
        table = np.full(n_types * n_points, -1, dtype=np.int32)
        table[row_point.astype(np.int64) * n_types + row_type] = np.arange(
            len(library), dtype=np.int32
        )
    else:
        table = np.zeros(0, dtype=np.int32)
    edges = LatticeEdges(
        lattice_shape=(ny, nx),
        row_type=row_type,
        row_point=row_point,
        succ_ptr=succ_ptr,
        succ_type=succ_type,
        pred_ptr=pred_ptr,
        pred_type=pred_type,
        offset=offset,
        type_first=type_first,
        table=table,
    )
    return PreparesGraph(library=library, lattice_edges=edges, atol=float(atol))


def _materialise(graph: PreparesGraph, *, forward: bool) -> tuple[NDArray[Any], NDArray[Any]]:
    """(indptr, indices) of the adjacency by rows (``forward``) or by columns, sorted."""
    n = graph.num_nodes
    args = graph.lattice_edges.kernel_args()
    counts = np.empty(n, dtype=np.int64)
    _count_edges(counts, forward, *args)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    index_dtype = np.int32 if max(n, int(indptr[-1])) < 2**31 - 1 else np.int64
    indices = np.empty(int(indptr[-1]), dtype=index_dtype)
    _fill_edges(indptr, indices, forward, *args)
    return indptr.astype(index_dtype), indices
