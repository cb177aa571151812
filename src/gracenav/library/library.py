"""The policy library (paper Sec. V-A): the palette's policies instantiated on a map, with
the index of their start domains and the coverage estimate."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from scipy import sparse

from gracenav.errors import ConfigError, MapError
from gracenav.library.types import (
    _CHUNK,
    _LATTICE_EPS,
    ORIENTATIONS,
    BoolArray,
    FloatArray,
    InstantiatedPolicy,
    InstantiationIteration,
    IntArray,
    PolicyTypes,
    _ramp,
    _readonly,
)
from gracenav.palette import Palette
from gracenav.policies import PrimitiveKind
from gracenav.world import WorldMap

__all__ = ["DEFAULT_COVERAGE_SAMPLES", "PolicyLibrary", "sample_position_states"]

#: Default number of position states sampled to estimate coverage (standard error
#: below 0.5 percentage points).
DEFAULT_COVERAGE_SAMPLES = 10_000


@dataclass(frozen=True)
class _StartIndex:
    """Spatial hash of start domains: library rows grouped by (start class, lattice point)."""

    class_velocity: FloatArray  # (C, 2) centre velocity of S
    class_shape: FloatArray  # (C, 3) a, b, c of the per-axis shape [[a, b], [b, c]]
    keys: IntArray  # (G,) sorted unique class * n_points + point
    group_start: IntArray  # (G + 1,) into order
    order: IntArray  # (N,) library rows sorted by key


@dataclass(frozen=True, eq=False)
class PolicyLibrary:
    """The motion policy library L(Π, M): every valid instantiation of the palette on a map.

    Rows are library policies in type order (type t = 4 p + k, then lattice point
    row-major). Arrays are read-only.

    Attributes
    ----------
    palette : Palette
    world_map : WorldMap
    footprint_radius : float
        Robot footprint radius (m) the swept outer domains were grown by.
    spacing : float
        Lattice spacing of the instantiation points (m).
    lattice_shape : tuple of int
        (ny, nx): instantiation points along y and x; point (ix, iy) is at
        ``origin + spacing · (ix, iy)``.
    origin : ndarray, shape (2,)
        Lattice origin: the map's minimum corner (m).
    types : PolicyTypes
        The palette at the four orientations.
    palette_index : ndarray of int, shape (N,)
    orientation : ndarray of int, shape (N,)
        k of each policy: rotation by k · 90°.
    start_cell : ndarray of int, shape (N, 2)
        Lattice indices (ix, iy) of the instantiation point.
    start_xy : ndarray, shape (N, 2)
        Instantiation point (m).
    start_state, end_state : ndarray, shape (N, 4)
        Reference position state (x, y, ẋ, ẏ) at t = 0 and t_f in the world frame
        (m, m/s): the centres of S and G.
    durations : ndarray, shape (N,)
        t_f (s).
    path_lengths : ndarray, shape (N,)
        XY length of the reference path (m).
    coverage : float
        Estimated coverage of the final iteration, in [0, 1].
    iterations : tuple of InstantiationIteration
        One record per lattice spacing tried, the last being this library's.
    sweep_step : float
        Largest arc length (m) between checked samples of the swept outer domains
        (plus at most one control tick of motion).
    speed_clearance : float
        Stopping allowance (s) the instantiation kept (see :func:`build_library`).
    design_push : float
        Design push (N s) the instantiation kept room to catch (0: none).
    """

    palette: Palette
    world_map: WorldMap
    footprint_radius: float
    spacing: float
    lattice_shape: tuple[int, int]
    origin: FloatArray
    types: PolicyTypes
    palette_index: IntArray
    orientation: IntArray
    start_cell: IntArray
    start_xy: FloatArray
    start_state: FloatArray
    end_state: FloatArray
    durations: FloatArray
    path_lengths: FloatArray
    coverage: float = float("nan")
    iterations: tuple[InstantiationIteration, ...] = ()
    sweep_step: float = 0.0
    speed_clearance: float = 0.0
    design_push: float = 0.0
    #: The spatial hash of the start domains, built by the first start-domain query
    #: (:meth:`_start_index`, its only writer; :meth:`_with_results` carries it over).
    _starts: _StartIndex | None = field(default=None, init=False, repr=False, compare=False)

    def __len__(self) -> int:
        return int(self.palette_index.shape[0])

    def __repr__(self) -> str:
        return (
            f"PolicyLibrary({len(self)} policies from {len(self.palette)} palette policies on "
            f"{self.world_map.name!r}, spacing {self.spacing:g} m, coverage {self.coverage:.3f})"
        )

    @property
    def type_index(self) -> IntArray:
        """Type t = 4 p + k of each policy, shape (N,)."""
        return self.palette_index * ORIENTATIONS + self.orientation

    @property
    def point_index(self) -> IntArray:
        """Lattice point id iy · nx + ix of each policy's start, shape (N,)."""
        nx = self.lattice_shape[1]
        out: IntArray = self.start_cell[:, 1] * nx + self.start_cell[:, 0]
        return out

    def policy(self, i: int) -> InstantiatedPolicy:
        """The instantiated view of library row ``i`` (world-frame domains and reference)."""
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"library policy {i} out of range for a library of {n} policies")
        i = int(i) % n
        p = int(self.palette_index[i])
        return InstantiatedPolicy(
            index=i,
            policy=self.palette.policies[p],
            palette_index=p,
            orientation=int(self.orientation[i]),
            start_xy=np.array(self.start_xy[i]),
        )

    def is_fine(self, rows: ArrayLike) -> BoolArray:
        """Whether each library row of ``rows`` is a fine copy of a palette policy
        (:attr:`gracenav.policies.VerificationOptions.fine_scales`), shape of ``rows``."""
        r = np.asarray(rows, dtype=np.int64)
        t = self.palette_index[r] * ORIENTATIONS + self.orientation[r]
        out: BoolArray = self.types.fine_factor[t] < 1.0
        return out

    def trim_indices(self, kind: PrimitiveKind | None = None) -> IntArray:
        """Rows whose primitive is a trim (or of trim ``kind``: REST or CRUISE), shape (n,).

        Capture regulators are not counted: they catch a moving robot, no task plans
        into them."""
        pols = self.palette.policies
        if kind is None:
            wanted = np.array([p.primitive.is_trim and not p.capture for p in pols], dtype=bool)
        else:
            if kind is PrimitiveKind.MANEUVER:
                raise ConfigError("trim_indices: kind must be REST, CRUISE or None, not MANEUVER")
            wanted = np.array(
                [p.primitive.kind is kind and not p.capture for p in pols], dtype=bool
            )
        if wanted.size == 0:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(wanted[self.palette_index]).astype(np.int64)

    # -- start domain queries --------------------------------------------------------

    def _start_index(self) -> _StartIndex:
        """The spatial hash of the start domains, built on first use."""
        idx = self._starts
        if idx is None:
            types = self.types
            m = types.start_shape
            rows = np.column_stack([types.start_velocity, m[:, 0, 0], m[:, 0, 1], m[:, 1, 1]])
            cls_rows, type_class = np.unique(rows, axis=0, return_inverse=True)
            type_class = type_class.reshape(-1)
            n_points = self.lattice_shape[0] * self.lattice_shape[1]
            key = type_class[self.type_index].astype(np.int64) * n_points + self.point_index
            order = np.argsort(key, kind="stable")
            keys, first = np.unique(key[order], return_index=True)
            idx = _StartIndex(
                class_velocity=_readonly(cls_rows[:, :2]),
                class_shape=_readonly(cls_rows[:, 2:]),
                keys=_readonly(keys.astype(np.int64)),
                group_start=_readonly(np.append(first, len(order)).astype(np.int64)),
                order=_readonly(order.astype(np.int64)),
            )
            object.__setattr__(self, "_starts", idx)  # a cache: the library stays frozen
        return idx

    def _with_results(
        self,
        *,
        coverage: float,
        iterations: tuple[InstantiationIteration, ...],
        speed_clearance: float,
        design_push: float = 0.0,
    ) -> PolicyLibrary:
        """This library with the results of :func:`build_library` recorded; the rows are
        the same, so it keeps the start-domain index already built."""
        out = replace(
            self,
            coverage=coverage,
            iterations=iterations,
            speed_clearance=speed_clearance,
            design_push=design_push,
        )
        object.__setattr__(out, "_starts", self._starts)
        return out

    def _hits(self, points: FloatArray) -> tuple[IntArray, IntArray]:
        """(query row, group) pairs where the group's start domain contains the point.

        With per-axis shape [[a, b], [b, c]], position offset e = x − q and velocity
        offset u = v − v_S, the value is a|e|² + 2b e·u + c|u|²
        = a|e + (b/a) u|² + (c − b²/a)|u|². For one start class (velocity and shape)
        the positions inside form a disc around x + (b/a) u of radius
        √((1 − (c − b²/a)|u|²)/a): only lattice points in its bounding box are looked
        up (:func:`_covered_kernel` makes the same test, stopping at the first hit).
        """
        idx = self._start_index()
        m = points.shape[0]
        if m == 0 or len(self) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        s = self.spacing
        shapes = idx.class_shape
        # Queries per chunk: bound the lattice candidates (bounding boxes) held at once.
        box = (2.0 / np.sqrt(shapes[:, 0].min()) / s + 2.0) ** 2
        rows = max(1024, int(_CHUNK // box))
        out_q: list[IntArray] = []
        out_g: list[IntArray] = []
        for lo in range(0, m, rows):
            q, g = self._hits_chunk(points[lo : lo + rows])
            out_q.append(q + lo)
            out_g.append(g)
        return np.concatenate(out_q), np.concatenate(out_g)

    def _hits_chunk(self, points: FloatArray) -> tuple[IntArray, IntArray]:
        idx = self._start_index()
        ny, nx = self.lattice_shape
        s = self.spacing
        x0, y0 = float(self.origin[0]), float(self.origin[1])
        px, py, vx, vy = points.T
        out_q: list[IntArray] = []
        out_g: list[IntArray] = []
        shapes = idx.class_shape
        for ci in range(shapes.shape[0]):
            a, b, c = (float(v) for v in shapes[ci])
            schur = c - b * b / a
            cvx, cvy = idx.class_velocity[ci]
            ux, uy = vx - cvx, vy - cvy
            uu = ux * ux + uy * uy
            qq = np.flatnonzero(uu * schur <= 1.0)
            if qq.size == 0:
                continue
            ux, uy, uu = ux[qq], uy[qq], uu[qq]
            r = np.sqrt(np.maximum(1.0 - uu * schur, 0.0) / a)
            cx = px[qq] + (b / a) * ux
            cy = py[qq] + (b / a) * uy
            ix0 = np.maximum(np.ceil((cx - r - x0) / s - _LATTICE_EPS), 0).astype(np.int64)
            ix1 = np.minimum(np.floor((cx + r - x0) / s + _LATTICE_EPS), nx - 1).astype(np.int64)
            iy0 = np.maximum(np.ceil((cy - r - y0) / s - _LATTICE_EPS), 0).astype(np.int64)
            iy1 = np.minimum(np.floor((cy + r - y0) / s + _LATTICE_EPS), ny - 1).astype(np.int64)
            wx = np.maximum(ix1 - ix0 + 1, 0)
            counts = wx * np.maximum(iy1 - iy0 + 1, 0)
            pair = np.repeat(np.arange(qq.size), counts)
            ramp = _ramp(counts)
            ix = ix0[pair] + ramp % wx[pair]
            iy = iy0[pair] + ramp // wx[pair]
            q = qq[pair]
            ex = px[q] - (x0 + ix * s)
            ey = py[q] - (y0 + iy * s)
            upx, upy = ux[pair], uy[pair]
            value = a * (ex * ex + ey * ey) + 2.0 * b * (ex * upx + ey * upy) + c * uu[pair]
            inside = value <= 1.0
            key = (int(ci) * (nx * ny)) + iy[inside] * nx + ix[inside]
            q = q[inside]
            pos = np.searchsorted(idx.keys, key)
            pos_c = np.minimum(pos, idx.keys.size - 1)
            found = (pos < idx.keys.size) & (idx.keys[pos_c] == key)
            out_q.append(q[found])
            out_g.append(pos[found])
        if not out_q:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(out_q), np.concatenate(out_g)

    def start_domain_covers(self, points: ArrayLike) -> BoolArray:
        """Whether each position state lies in at least one start domain S.

        Parameters
        ----------
        points : array_like, shape (M, 4)
            Position states (x, y, ẋ, ẏ) (m, m/s).

        Returns
        -------
        ndarray of bool, shape (M,)
        """
        p = _as_states(points)
        if p.shape[0] == 0 or len(self) == 0:
            return np.zeros(p.shape[0], dtype=bool)
        idx = self._start_index()
        shapes = idx.class_shape
        # Largest classes first: they settle the most queries early.
        order = np.argsort(shapes[:, 0] - shapes[:, 1] ** 2 / shapes[:, 2]).astype(np.int64)
        ny, nx = self.lattice_shape
        out: BoolArray = _covered_kernel(
            np.ascontiguousarray(p),
            order,
            np.ascontiguousarray(shapes),
            np.ascontiguousarray(idx.class_velocity),
            idx.keys,
            nx,
            ny,
            float(self.spacing),
            float(self.origin[0]),
            float(self.origin[1]),
        )
        return out

    def start_domain_contains(self, points: ArrayLike) -> sparse.csr_matrix:
        """Which library policies' start domains S contain each position state.

        A spatial hash of the start domains (grouped by start velocity, shape and
        lattice point) limits the candidates of each point to the lattice points
        within reach: the cost grows with the number of hits, not with M · N.

        Parameters
        ----------
        points : array_like, shape (M, 4)
            Position states (x, y, ẋ, ẏ) (m, m/s).

        Returns
        -------
        scipy.sparse.csr_matrix of bool, shape (M, N)
            Entry (m, i) is True iff S of policy i contains point m (boundary
            included); ``.indices[.indptr[m]:.indptr[m + 1]]`` lists them.
        """
        p = _as_states(points)
        idx = self._start_index()
        q, g = self._hits(p)
        counts = idx.group_start[g + 1] - idx.group_start[g]
        rows = np.repeat(q, counts)
        cols = idx.order[np.repeat(idx.group_start[g], counts) + _ramp(counts)]
        data = np.ones(rows.size, dtype=bool)
        return sparse.csr_matrix((data, (rows, cols)), shape=(p.shape[0], len(self)))


@njit(cache=True)
def _covered_kernel(
    points: FloatArray,
    order: IntArray,
    shapes: FloatArray,
    velocity: FloatArray,
    keys: IntArray,
    nx: int,
    ny: int,
    s: float,
    x0: float,
    y0: float,
) -> BoolArray:  # pragma: no cover - compiled
    """Whether each point lies in some start domain: the test of
    :meth:`PolicyLibrary._hits_chunk`, compiled, stopping at the first hit."""
    m = points.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    n_points = nx * ny
    for q in range(m):
        px, py, vx, vy = points[q, 0], points[q, 1], points[q, 2], points[q, 3]
        for ci in order:
            a, b, c = shapes[ci, 0], shapes[ci, 1], shapes[ci, 2]
            schur = c - b * b / a
            ux = vx - velocity[ci, 0]
            uy = vy - velocity[ci, 1]
            uu = ux * ux + uy * uy
            if uu * schur > 1.0:
                continue
            r = math.sqrt(max(1.0 - uu * schur, 0.0) / a)
            cx = px + (b / a) * ux
            cy = py + (b / a) * uy
            ix0 = max(math.ceil((cx - r - x0) / s - _LATTICE_EPS), 0)
            ix1 = min(math.floor((cx + r - x0) / s + _LATTICE_EPS), nx - 1)
            iy0 = max(math.ceil((cy - r - y0) / s - _LATTICE_EPS), 0)
            iy1 = min(math.floor((cy + r - y0) / s + _LATTICE_EPS), ny - 1)
            hit = False
            for iy in range(iy0, iy1 + 1):
                ey = py - (y0 + iy * s)
                for ix in range(ix0, ix1 + 1):
                    ex = px - (x0 + ix * s)
                    value = a * (ex * ex + ey * ey) + 2.0 * b * (ex * ux + ey * uy) + c * uu
                    if value > 1.0:
                        continue
                    key = ci * n_points + iy * nx + ix
                    pos = np.searchsorted(keys, key)
                    if pos < keys.size and keys[pos] == key:
                        hit = True
                        break
                if hit:
                    break
            if hit:
                out[q] = True
                break
    return out


def _as_states(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 4:
        raise ConfigError(
            f"position states must have shape (M, 4) holding (x, y, ẋ, ẏ), got {p.shape}"
        )
    return p


def sample_position_states(
    world_map: WorldMap,
    n: int,
    *,
    footprint_radius: float,
    v_max: float,
    seed: int | np.random.Generator = 0,
) -> FloatArray:
    """Uniform samples of the bounded position state space that coverage is measured on.

    Positions are uniform over the free points of the map with clearance >=
    ``footprint_radius`` (by rejection), velocities uniform in [−v_max, v_max]².

    Parameters
    ----------
    world_map : WorldMap
    n : int
        Number of samples wanted.
    footprint_radius : float
        Robot footprint radius (m).
    v_max : float
        Velocity bound (m/s).
    seed : int or numpy.random.Generator
        Randomness (positions are drawn first, then velocities).

    Returns
    -------
    ndarray, shape (n, 4)
        (x, y, ẋ, ẏ) (m, m/s). Fewer rows only if the free space is so small that
        200 n uniform draws over the map found fewer than n points in it.

    Raises
    ------
    MapError
        If no draw falls in free space with enough clearance.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    (x0, y0), (x1, y1) = world_map.bounds
    got: list[FloatArray] = []
    have = drawn = 0
    budget = 200 * n
    while have < n and drawn < budget:
        batch = max(2 * (n - have), 1024)
        xy = rng.uniform((x0, y0), (x1, y1), size=(batch, 2))
        drawn += batch
        keep = xy[world_map.is_free(xy) & (world_map.clearance(xy) >= footprint_radius)]
        got.append(keep)
        have += keep.shape[0]
    if have == 0:
        raise MapError(
            f"{world_map.source}: no free position has clearance >= footprint_radius "
            f"{footprint_radius:g} m, so there is nothing to cover; use a map with free space "
            "wider than the robot or a smaller footprint_radius"
        )
    xy = np.concatenate(got)[:n]
    v = rng.uniform(-v_max, v_max, size=(xy.shape[0], 2))
    out: FloatArray = np.concatenate([xy, v], axis=1)
    return out
