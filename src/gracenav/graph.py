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

Edge costs: entry (i, j) of the adjacency matrix is the cost of *executing policy i*
(then switching to j): its duration t_f (s) for the fastest-time criterion, or the
XY length of its reference path (m) for the shortest-path criterion. The
shortest-path distance from i to a goal node is then the cost-to-go of starting
policy i, not counting the goal policy itself. Rest trims have zero path length, so
distance graphs hold explicit zero entries (which :mod:`scipy.sparse.csgraph` treats
as edges).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from gracenav.errors import ConfigError
from gracenav.library import InstantiatedPolicy, PolicyLibrary

__all__ = ["CostName", "PreparesGraph", "build_graph", "gains_equal", "gracefully_prepares"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

CostName = Literal["time", "distance"]
_COSTS = ("time", "distance")
#: Default absolute tolerance of state continuity (m, m/s, m/s², rad, rad/s).
DEFAULT_ATOL = 1e-6
_DENSE_LOOKUP = 1 << 25  # largest (type, point) table (int32 entries) built for the join
_EDGE_CHUNK = 1 << 22  # candidate edges examined at once


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
    :meth:`gracenav.domains.EllipsoidalDomain.contains_domain` (tolerance 1e-9 on the
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
class PreparesGraph:
    """The gracefully prepares graph Ω(L): directed, nodes = library policies.

    Attributes
    ----------
    library : PolicyLibrary
    adjacency : scipy.sparse.csr_matrix, shape (N, N)
        Entry (i, j) is the fastest-time cost of the edge i → j: the duration of
        policy i (s). Sorted indices, no duplicates, no self-loops.
    distance_weights : ndarray, shape (E,)
        Shortest-path cost of each stored edge, aligned with ``adjacency.data``: the
        XY path length of the source policy's reference (m).
    atol : float
        Tolerance of the state continuity checks.

    Notes
    -----
    Every edge i → j costs the execution of its source policy i, so the weights of
    the edges into j, listed by :meth:`csc`, are the node costs of their sources.
    """

    library: PolicyLibrary
    adjacency: sparse.csr_matrix
    distance_weights: FloatArray
    atol: float = DEFAULT_ATOL
    _csc: dict[str, sparse.csc_matrix] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __repr__(self) -> str:
        return f"PreparesGraph({self.num_nodes} nodes, {self.num_edges} edges)"

    @property
    def num_nodes(self) -> int:
        """N, the number of library policies."""
        return int(self.adjacency.shape[0])

    @property
    def num_edges(self) -> int:
        """E, the number of gracefully prepares edges."""
        return int(self.adjacency.nnz)

    @property
    def time_weights(self) -> FloatArray:
        """Fastest-time cost of each stored edge (s), aligned with ``adjacency.data``."""
        out: FloatArray = self.adjacency.data
        return out

    def node_cost(self, cost: CostName = "time") -> FloatArray:
        """Cost of executing each policy: duration (s) or XY path length (m), shape (N,)."""
        _check_cost(cost)
        lib = self.library
        out: FloatArray = lib.durations if cost == "time" else lib.path_lengths
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
        reversed graph in CSR form without a copy: what :func:`gracenav.planning.plan_tree`
        searches. Built on the first call (O(N + E)) and kept: the row indices and column
        pointers (int32 below 2³¹ edges) are shared by both costs, the weights (float64)
        are per cost, so the first cost asked for adds 12 bytes per edge (+ 4 per node)
        to the graph's 20 bytes per edge, the second 8 more. Sorted indices, the same
        entries as :meth:`csr` (explicit zeros included).
        """
        _check_cost(cost)
        out = self._csc.get(cost)
        if out is None:
            if self._csc:
                base = next(iter(self._csc.values()))
            else:
                base = self.adjacency.tocsc()
            # Entry (i, j) is the cost of executing policy i, the row index.
            data = np.ascontiguousarray(self.node_cost(cost)[base.indices], dtype=np.float64)
            out = sparse.csc_matrix(
                (data, base.indices, base.indptr), shape=self.adjacency.shape, copy=False
            )
            out.has_sorted_indices = True
            self._csc[cost] = out
        return out

    def successors(self, i: int) -> IntArray:
        """Library rows that policy ``i`` gracefully prepares, ascending."""
        a = self.adjacency
        out: IntArray = a.indices[a.indptr[i] : a.indptr[i + 1]].astype(np.int64)
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
    n = len(library)
    ny, nx = library.lattice_shape
    n_points = nx * ny
    compat, cells = _type_compatibility(library, atol)
    n_types = compat.shape[0]
    succ_ptr = np.concatenate([[0], np.cumsum(compat.sum(axis=1))]).astype(np.int64)
    succ_type = np.nonzero(compat)[1].astype(np.int64)

    row_type = library.type_index
    key = row_type * n_points + library.point_index  # strictly increasing in row order
    dense = n_types * n_points <= _DENSE_LOOKUP
    if dense:
        table = np.full(n_types * n_points, -1, dtype=np.int32 if n < 2**31 else np.int64)
        table[key] = np.arange(n)
    end_cell = library.start_cell + cells[row_type]
    inside = (
        (end_cell[:, 0] >= 0)
        & (end_cell[:, 0] < nx)
        & (end_cell[:, 1] >= 0)
        & (end_cell[:, 1] < ny)
    )
    end_point = end_cell[:, 1] * nx + end_cell[:, 0]
    n_succ = np.where(inside, succ_ptr[row_type + 1] - succ_ptr[row_type], 0)

    src_parts: list[IntArray] = []
    dst_parts: list[IntArray] = []
    cum = np.cumsum(n_succ)
    lo = 0
    while lo < n:
        base = cum[lo - 1] if lo else 0
        hi = int(np.searchsorted(cum, base + _EDGE_CHUNK, side="right"))
        hi = max(hi, lo + 1)
        rows = np.arange(lo, hi)
        counts = n_succ[lo:hi]
        rep = np.repeat(rows, counts)
        ramp = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        t2 = succ_type[succ_ptr[row_type[rep]] + ramp]
        cand = t2 * n_points + end_point[rep]
        if dense:
            j = table[cand].astype(np.int64)
        else:
            pos = np.searchsorted(key, cand)
            pos_c = np.minimum(pos, max(n - 1, 0))
            j = np.where((pos < n) & (key[pos_c] == cand), pos_c, -1)
        keep = (j >= 0) & (j != rep)
        src_parts.append(rep[keep])
        dst_parts.append(j[keep])
        lo = hi
    src = np.concatenate(src_parts) if src_parts else np.zeros(0, np.int64)
    dst = np.concatenate(dst_parts) if dst_parts else np.zeros(0, np.int64)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(src, minlength=n))])
    index_dtype = np.int32 if max(n, src.size) < 2**31 - 1 else np.int64
    adjacency = sparse.csr_matrix(
        (
            np.ascontiguousarray(library.durations[src], dtype=np.float64),
            dst.astype(index_dtype),
            indptr.astype(index_dtype),
        ),
        shape=(n, n),
    )
    adjacency.has_sorted_indices = True
    return PreparesGraph(
        library=library,
        adjacency=adjacency,
        distance_weights=np.ascontiguousarray(library.path_lengths[src], dtype=np.float64),
        atol=float(atol),
    )
