"""Automatic instantiation of motion policies: the motion policy library L(Π, M).

Paper Sec. IV-A. The dynamics of the ballbot are invariant to translations and
rotations of its position variables, so every policy of the palette Π can be
placed anywhere on the map M in any orientation. Instantiation points are the
nodes of a square lattice of spacing d (the palette's distance parameter) along
X and Y, anchored at the map's minimum corner; each palette policy is placed at
each point in the four orientations k · 90° (k = 0..3, counter-clockwise about
the policy's start). An instantiation is kept iff its outer domain D'(t),
projected on the XY plane and swept over [0, t_f], grown by the robot's
footprint, is obstacle free and inside the map.

Coverage is the fraction of uniformly sampled position states of the bounded
position state space (free positions with clearance >= footprint, velocities
uniform in [-v_max, v_max]², v_max the largest trim speed of the palette) that
lie in at least one instantiated start domain S. Below the target, the lattice
spacing is halved (d/2, d/4, ...) and instantiation repeats, up to a limit.

Library data are columnar numpy arrays, one row per instantiated policy, in
*type* order: type t = 4 p + k (palette policy p at orientation k), then
instantiation point (row-major on the lattice). Orientation k rotates
positions, velocities, accelerations and the body lean (a vector toward the
direction of motion) by the exact quarter-turn matrix :func:`quarter_turn`.
Domains have shape matrices M ⊗ I₂ in (x, y, ẋ, ẏ) (per-axis 2 × 2 M coupling
position and velocity, the same for x and y), which are invariant under
rotations of the plane: they rotate trivially, and the XY projection of D'(t)
is a disc of radius (outer position factor) × (position extent of D(t)).
"""

from __future__ import annotations

import math
import os
import time
import weakref
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from gracenav.errors import ConfigError, MapError
from gracenav.model.indices import PHI, PHI_X_DOT, PHI_Y_DOT
from gracenav.palette import Palette
from gracenav.policies import MotionPolicy, PrimitiveKind
from gracenav.policies.domains import EllipsoidalDomain
from gracenav.world import WorldMap

# The compiled sweep check runs in parallel. numba's default layer here is GNU OpenMP,
# which aborts any process that forks after using it (worker pools fork: palette
# builds, campaigns, benchmarks), so a fork-safe layer is chosen unless the user
# chose one (environment variable NUMBA_THREADING_LAYER).
_numba_config: Any = numba.config
if _numba_config.THREADING_LAYER == "default" and "NUMBA_THREADING_LAYER" not in os.environ:
    _numba_config.THREADING_LAYER = "forksafe"

__all__ = [
    "DEFAULT_COVERAGE_SAMPLES",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_SPEED_CLEARANCE",
    "MAX_SPEED_CLEARANCE",
    "ORIENTATIONS",
    "POLICY_BYTES",
    "InstantiatedPolicy",
    "InstantiationIteration",
    "PolicyLibrary",
    "PolicyTypes",
    "build_library",
    "estimate_library_size",
    "max_trim_speed",
    "quarter_turn",
    "sample_position_states",
    "sweep_samples",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Orientations of instantiation: k · 90° for k = 0..3.
ORIENTATIONS = 4
#: Default number of position states sampled to estimate coverage (standard error
#: below 0.5 percentage points).
DEFAULT_COVERAGE_SAMPLES = 10_000

_QUARTER_TURNS = np.array(
    [
        [[1.0, 0.0], [0.0, 1.0]],
        [[0.0, -1.0], [1.0, 0.0]],
        [[-1.0, 0.0], [0.0, -1.0]],
        [[0.0, 1.0], [-1.0, 0.0]],
    ]
)
_QUARTER_TURNS.setflags(write=False)
#: Peak memory per library policy (bytes) of building the library, its graph with the
#: edges generated from the lattice and one search, measured on a 100 m open hall
#: (6.28 M policies, 1.56 GiB peak of which 0.31 GiB before the library).
POLICY_BYTES = 208
#: Default memory limit (bytes) of :func:`build_library`: 4 GiB.
DEFAULT_MEMORY_LIMIT = 4 * 2**30
#: Default stopping allowance of :func:`build_library` (s): extra clearance per m/s of
#: reference speed toward an obstacle. With it every one of 900 seeded pushes (0–16 N s
#: on the 5 m room, bench/bench_pushes.py) is caught by a verified policy, against 97.0–
#: 98.7 % without; the unpushed run there takes 1 % longer. Larger allowances cut off
#: narrow passages: of 400 random rest-to-rest pairs on the cluttered 6 m room, 131 are
#: possible without, 130 with 0.1 s, 118 with 0.2 s and 104 with 0.3 s; on a 50 m office
#: with 1 m doors the corridors' strongly connected part loses 30 % of its policies.
DEFAULT_SPEED_CLEARANCE = 0.1
#: Largest stopping allowance accepted (s).
MAX_SPEED_CLEARANCE = 2.0
_GROUP = 8  # checked sweep samples per bounding disc of the hierarchical sweep check
_CHUNK = 1 << 19  # clearance queries evaluated at once
_LATTICE_EPS = 1e-9  # relative slack when counting lattice points across the map


def quarter_turn(k: int) -> FloatArray:
    """Exact rotation matrix by k · 90° counter-clockwise, shape (2, 2).

    Entries are exactly 0 and ±1, so rotated states compare exactly.
    """
    return np.array(_QUARTER_TURNS[int(k) % ORIENTATIONS])


def _readonly(a: NDArray[Any]) -> NDArray[Any]:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def _ramp(counts: IntArray) -> IntArray:
    """0, 1, ..., c_i − 1 for each count c_i, concatenated (shape (sum(counts),))."""
    total = int(counts.sum())
    starts = np.cumsum(counts) - counts
    out: IntArray = np.arange(total, dtype=np.int64) - np.repeat(starts, counts)
    return out


def _rotate(vectors: FloatArray, k: int) -> FloatArray:
    """Rotate (..., 2) vectors by k · 90°."""
    out: FloatArray = vectors @ _QUARTER_TURNS[k].T
    return out


# --------------------------------------------------------------------------------------
# The palette at every orientation
# --------------------------------------------------------------------------------------


def _axis_shapes(radii: FloatArray, correlation: FloatArray) -> FloatArray:
    """Per-axis shape matrices M (P, 2, 2) of domains with extents ``radii`` (P, 2)
    (position m, velocity m/s) and position-velocity correlations ``correlation`` (P,):
    M = Σ⁻¹ for Σ = [[e_p², r e_p e_v], [r e_p e_v, e_v²]] (the domain's shape matrix is
    M ⊗ I₂, see :func:`gracenav.policies.domains.correlated_shape`)."""
    ep, ev, r = radii[:, 0], radii[:, 1], correlation
    det = (ep * ev) ** 2 * (1.0 - r**2)
    out = np.empty((radii.shape[0], 2, 2))
    out[:, 0, 0] = ev**2 / det
    out[:, 1, 1] = ep**2 / det
    out[:, 0, 1] = out[:, 1, 0] = -r * ep * ev / det
    return out


@dataclass(frozen=True)
class PolicyTypes:
    """The palette's policies at the four orientations: 4 P *types*, t = 4 p + k.

    Every vector is in the world orientation of the type (rotated by k · 90°) and
    relative to the instantiation point.

    Attributes
    ----------
    palette_index, orientation : ndarray of int, shape (T,)
        p and k of each type.
    start_velocity, end_velocity : ndarray, shape (T, 2)
        Reference ball velocity at t = 0 and t_f (m/s).
    start_acceleration, end_acceleration : ndarray, shape (T, 2)
        Reference ball acceleration at t = 0 and t_f (m/s²).
    start_lean, end_lean : ndarray, shape (T, 2)
        Reference body lean (φ_x, φ_y) at t = 0 and t_f (rad).
    start_lean_rate, end_lean_rate : ndarray, shape (T, 2)
        Reference lean rate at t = 0 and t_f (rad/s).
    end_offset : ndarray, shape (T, 2)
        Reference ball position at t_f minus the one at t = 0 (m).
    start_radii, goal_radii : ndarray, shape (T, 2)
        (position (m), velocity (m/s)) extents of S and G.
    start_shape, goal_shape : ndarray, shape (T, 2, 2)
        Per-axis shape matrix M of S and G: the domain is {z : zᵀ (M ⊗ I₂) z <= 1} for
        z = (x, y, ẋ, ẏ) minus the centre (M in 1/m², 1/(m·m/s), 1/(m/s)²). Such
        domains are invariant under rotations of the plane.
    start_xy_radius : ndarray, shape (T,)
        Radius of the XY projection of S (m).
    duration : ndarray, shape (T,)
        t_f (s).
    path_length : ndarray, shape (T,)
        XY length of the reference path (m).
    is_trim : ndarray of bool, shape (T,)
    is_capture : ndarray of bool, shape (T,)
        Capture regulators (:class:`gracenav.policies.RegulatorOptions`).
    scale_group : ndarray of int, shape (T,)
        Types of one primitive at one orientation share a group: the policy sized by
        bisection and its larger-domain variants. Instantiation keeps, per group and
        point, only the largest start domain whose swept D' fits.
    """

    palette_index: IntArray
    orientation: IntArray
    start_velocity: FloatArray
    end_velocity: FloatArray
    start_acceleration: FloatArray
    end_acceleration: FloatArray
    start_lean: FloatArray
    end_lean: FloatArray
    start_lean_rate: FloatArray
    end_lean_rate: FloatArray
    end_offset: FloatArray
    start_radii: FloatArray
    goal_radii: FloatArray
    start_shape: FloatArray
    goal_shape: FloatArray
    start_xy_radius: FloatArray
    duration: FloatArray
    path_length: FloatArray
    is_trim: BoolArray
    is_capture: BoolArray
    scale_group: IntArray

    def __len__(self) -> int:
        return int(self.palette_index.shape[0])

    @classmethod
    def from_palette(cls, palette: Palette) -> PolicyTypes:
        """Tabulate ``palette``'s policies at the four orientations."""
        pols = palette.policies
        n = len(pols)
        first = np.array([p.primitive.position[0] for p in pols]).reshape(n, 6)
        last = np.array([p.primitive.position[-1] for p in pols]).reshape(n, 6)
        st0 = np.array([p.primitive.states[0] for p in pols]).reshape(n, 8)
        st1 = np.array([p.primitive.states[-1] for p in pols]).reshape(n, 8)
        rate = [PHI_X_DOT, PHI_Y_DOT]
        corr = np.array([p.correlation for p in pols], dtype=float)
        corr_start = np.array([p.start_shape_correlation for p in pols], dtype=float)
        r_start = np.array([[p.start_radii.position, p.start_radii.velocity] for p in pols])
        r_goal = np.array([[p.goal_radii.position, p.goal_radii.velocity] for p in pols])
        m_start = _axis_shapes(r_start.reshape(n, 2), corr_start)
        m_goal = _axis_shapes(r_goal.reshape(n, 2), corr)
        lengths = np.array(
            [np.sum(np.hypot(*np.diff(p.primitive.position[:, :2], axis=0).T)) for p in pols]
        )
        rot = _QUARTER_TURNS  # (4, 2, 2)
        first_of: dict[str, int] = {}
        primitive_id = np.array(
            [first_of.setdefault(p.primitive.name, len(first_of)) for p in pols], dtype=np.int64
        )

        def turn(v: FloatArray) -> FloatArray:
            """(P, 2) vectors at the 4 orientations, type-major: shape (4 P, 2)."""
            out: FloatArray = np.einsum("kij,pj->pki", rot, v).reshape(-1, 2)
            return out

        def per_type(v: NDArray[Any]) -> NDArray[Any]:
            return np.repeat(v, ORIENTATIONS, axis=0)

        arrays: dict[str, NDArray[Any]] = {
            "palette_index": per_type(np.arange(n, dtype=np.int64)),
            "orientation": np.tile(np.arange(ORIENTATIONS, dtype=np.int64), n),
            "start_velocity": turn(first[:, 2:4]),
            "end_velocity": turn(last[:, 2:4]),
            "start_acceleration": turn(first[:, 4:6]),
            "end_acceleration": turn(last[:, 4:6]),
            "start_lean": turn(st0[:, PHI]),
            "end_lean": turn(st1[:, PHI]),
            "start_lean_rate": turn(st0[:, rate]),
            "end_lean_rate": turn(st1[:, rate]),
            "end_offset": turn(last[:, :2] - first[:, :2]),
            "start_radii": per_type(r_start).reshape(-1, 2),
            "goal_radii": per_type(r_goal).reshape(-1, 2),
            "start_shape": per_type(m_start).reshape(-1, 2, 2),
            "goal_shape": per_type(m_goal).reshape(-1, 2, 2),
            "start_xy_radius": per_type(
                1.0 / np.sqrt(m_start[:, 0, 0] - m_start[:, 0, 1] ** 2 / m_start[:, 1, 1])
            ),
            "duration": per_type(np.array([p.duration for p in pols], dtype=float)),
            "path_length": per_type(lengths),
            "is_trim": per_type(np.array([p.primitive.is_trim for p in pols], dtype=bool)),
            "is_capture": per_type(np.array([p.capture for p in pols], dtype=bool)),
            "scale_group": ORIENTATIONS * per_type(primitive_id)
            + np.tile(np.arange(ORIENTATIONS, dtype=np.int64), n),
        }
        return cls(**{k: _readonly(v) for k, v in arrays.items()})

    def boundary(self, which: str) -> FloatArray:
        """Reference boundary states at ``which`` = "start" or "end": velocity,
        acceleration, lean, lean rate, shape (T, 8) (m/s, m/s², rad, rad/s)."""
        if which not in ("start", "end"):
            raise ConfigError(f"boundary must be 'start' or 'end', got {which!r}")
        names = ("velocity", "acceleration", "lean", "lean_rate")
        return np.concatenate([getattr(self, f"{which}_{n}") for n in names], axis=1)


# --------------------------------------------------------------------------------------
# Instantiated policies and iterations
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class InstantiationIteration:
    """One pass of instantiation at one lattice spacing.

    Attributes
    ----------
    spacing : float
        Lattice spacing (m): d / 2^h at halving h.
    size : int
        Number of valid instantiations (library policies).
    coverage : float
        Estimated fraction of the bounded position state space covered by start domains.
    seconds : float
        Wall time of the pass (instantiation and coverage estimate) (s).
    """

    spacing: float
    size: int
    coverage: float
    seconds: float


@dataclass(frozen=True)
class InstantiatedPolicy:
    """A palette policy placed on the map: a view of one library row, in the world frame.

    Attributes
    ----------
    index : int
        Row in the library.
    policy : MotionPolicy
        The palette policy (in its own frame).
    palette_index : int
    orientation : int
        k: the policy is rotated by k · 90° counter-clockwise about its start.
    start_xy : ndarray, shape (2,)
        Instantiation point (m): where the reference starts.
    """

    index: int
    policy: MotionPolicy
    palette_index: int
    orientation: int
    start_xy: FloatArray

    @property
    def name(self) -> str:
        """Palette name, orientation and instantiation point, e.g. ``rest@90°(1, 0.5)``."""
        x, y = self.start_xy
        return f"{self.policy.name}@{90 * self.orientation}°({x:g}, {y:g})"

    @property
    def angle(self) -> float:
        """Orientation (rad), counter-clockwise from the palette's frame."""
        return 0.5 * math.pi * self.orientation

    @property
    def rotation(self) -> FloatArray:
        """Exact rotation (2, 2) from the policy's frame to the world."""
        return quarter_turn(self.orientation)

    @property
    def duration(self) -> float:
        """t_f (s)."""
        return self.policy.duration

    @property
    def kind(self) -> PrimitiveKind:
        """Rest trim, cruise trim or maneuver."""
        return self.policy.primitive.kind

    @property
    def is_trim(self) -> bool:
        """Whether the primitive is a trim."""
        return self.policy.primitive.is_trim

    def _to_world(self, local: FloatArray) -> FloatArray:
        """Position states (..., 4) of the policy's frame in the world frame."""
        r = self.rotation
        out = np.empty_like(local)
        out[..., :2] = local[..., :2] @ r.T + self.start_xy
        out[..., 2:4] = local[..., 2:4] @ r.T
        return out

    def _domain(self, local: EllipsoidalDomain) -> EllipsoidalDomain:
        r4 = np.zeros((4, 4))
        r4[:2, :2] = r4[2:, 2:] = self.rotation
        centre = self._to_world(np.asarray(local.center, dtype=float))
        return EllipsoidalDomain(centre, r4 @ local.shape_matrix @ r4.T)

    def domain(self, t: float) -> EllipsoidalDomain:
        """D(t) in the world frame (t in s, clamped to [0, t_f])."""
        return self._domain(self.policy.domain(t))

    def outer_domain(self, t: float) -> EllipsoidalDomain:
        """D'(t) in the world frame."""
        return self._domain(self.policy.outer_domain(t))

    @property
    def start_domain(self) -> EllipsoidalDomain:
        """S = D(0) in the world frame."""
        return self.domain(0.0)

    @property
    def goal_domain(self) -> EllipsoidalDomain:
        """G = D(t_f) in the world frame."""
        return self.domain(self.policy.duration)

    def position_state(self, t: ArrayLike) -> FloatArray:
        """Reference position state (x, y, ẋ, ẏ) at times ``t`` (s) in the world frame,
        shape (..., 4) (m, m/s)."""
        return self._to_world(self.policy.primitive.position_state(t))

    @cached_property
    def reference_positions(self) -> FloatArray:
        """Reference x, y, ẋ, ẏ, ẍ, ÿ at the control ticks in the world frame, shape
        (T + 1, 6) (m, m/s, m/s²)."""
        pos = self.policy.primitive.position
        r = self.rotation
        out = np.empty_like(pos)
        out[:, :2] = pos[:, :2] @ r.T + self.start_xy
        out[:, 2:4] = pos[:, 2:4] @ r.T
        out[:, 4:6] = pos[:, 4:6] @ r.T
        out.setflags(write=False)
        return out

    @cached_property
    def reference_lean(self) -> FloatArray:
        """Reference body lean (φ_x, φ_y) and lean rate at the ticks in the world frame,
        shape (T + 1, 4) (rad, rad/s)."""
        st = self.policy.primitive.states
        r = self.rotation
        out = np.concatenate([st[:, PHI] @ r.T, st[:, [PHI_X_DOT, PHI_Y_DOT]] @ r.T], axis=1)
        out.setflags(write=False)
        return out

    @property
    def path_length(self) -> float:
        """XY length of the reference path (m)."""
        pos = self.policy.primitive.position[:, :2]
        return float(np.sum(np.hypot(*np.diff(pos, axis=0).T)))


@dataclass(frozen=True)
class _StartIndex:
    """Spatial hash of start domains: library rows grouped by (start class, lattice point)."""

    class_velocity: FloatArray  # (C, 2) centre velocity of S
    class_shape: FloatArray  # (C, 3) a, b, c of the per-axis shape [[a, b], [b, c]]
    keys: IntArray  # (G,) sorted unique class * n_points + point
    group_start: IntArray  # (G + 1,) into order
    order: IntArray  # (N,) library rows sorted by key


# --------------------------------------------------------------------------------------
# The library
# --------------------------------------------------------------------------------------


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
    ) -> PolicyLibrary:
        """This library with the results of :func:`build_library` recorded; the rows are
        the same, so it keeps the start-domain index already built."""
        out = replace(
            self, coverage=coverage, iterations=iterations, speed_clearance=speed_clearance
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


# --------------------------------------------------------------------------------------
# Swept outer domains
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Sweep:
    """Checked samples of one palette policy's swept D' (policy frame, footprint excluded).

    A sample j at offset c_j needs clearance(q + c_j) >= footprint + reach_j.
    Groups of consecutive samples are bounded by discs (centre, reach).
    """

    offsets: FloatArray  # (K, 2)
    reach: FloatArray  # (K,)
    group_centre: FloatArray  # (Gp, 2)
    group_reach: FloatArray  # (Gp,)
    group_first: IntArray  # (Gp,) first sample
    group_size: IntArray  # (Gp,)
    total_reach: float  # bound around the start point


def sweep_samples(
    policy: MotionPolicy, step: float, lead: float = 0.0
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Samples of a policy's reference path for checking its swept outer domain D'.

    Parameters
    ----------
    policy : MotionPolicy
    step : float
        Largest arc (m) between selected samples (plus one control tick of motion).
    lead : float
        The path is led by this (s) times the reference velocity.

    Returns
    -------
    pos : ndarray, shape (T+1, 2)
        The (led) reference path relative to its start (m), at every tick.
    cum : ndarray, shape (T+1,)
        Its arc length at each tick (m).
    sel : ndarray of int
        The selected ticks, ascending: the first, the last, and ticks at most
        ``step`` of arc (plus one tick) apart.
    """
    prim = policy.primitive
    pos = prim.position[:, :2] - prim.position[0, :2] + lead * prim.position[:, 2:4]
    seg = np.hypot(*np.diff(pos, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n_ticks = pos.shape[0] - 1
    targets = np.arange(int(cum[-1] // step) + 2) * step
    picked = np.clip(np.searchsorted(cum, targets, side="right") - 1, 0, n_ticks)
    sel = np.unique(np.concatenate([[0], picked, [n_ticks]]))
    return pos, cum, sel


def _sweep(
    policy: MotionPolicy,
    step: float,
    samples: tuple[FloatArray, FloatArray, IntArray] | None = None,
    speed_clearance: float = 0.0,
) -> _Sweep:
    """Select samples of the reference path (led by half the stopping allowance times
    the velocity) at most ``step`` of arc (plus one tick) apart and the conservative
    reach of D' around each, plus half the allowance ``speed_clearance`` (s) times the
    reference speed (see :func:`build_library`). ``samples``: :func:`sweep_samples`
    of the policy's primitive with that lead, if already computed."""
    prim = policy.primitive
    half = 0.5 * speed_clearance
    pos, cum, sel = samples if samples is not None else sweep_samples(policy, step, half)
    outer, _ = policy.outer_extents(sel * prim.dt)
    speed = np.hypot(prim.position[:, 2], prim.position[:, 3])
    reach = outer + half * speed[sel]
    if sel.size > 1:
        # The fastest tick from one sample to the next, both included.
        seg_speed = np.maximum(np.maximum.reduceat(speed, sel)[:-1], speed[sel[1:]])
        seg_reach = np.maximum(outer[:-1], outer[1:]) + half * seg_speed + 0.5 * np.diff(cum[sel])
        reach[:-1] = np.maximum(reach[:-1], seg_reach)
        reach[1:] = np.maximum(reach[1:], seg_reach)
    offsets = pos[sel]
    first = np.arange(0, sel.size, _GROUP, dtype=np.int64)
    size = np.minimum(_GROUP, sel.size - first)
    centres = 0.5 * (
        np.minimum.reduceat(offsets, first, axis=0) + np.maximum.reduceat(offsets, first, axis=0)
    )
    own = np.repeat(np.arange(first.size), size)
    greach = np.maximum.reduceat(np.hypot(*(offsets - centres[own]).T) + reach, first)
    total = float(np.max(np.hypot(*offsets.T) + reach))
    return _Sweep(offsets, reach, centres, greach, first, size, total)


#: The palette's types and swept outer domain tables of one sweep step and speed clearance.
_Tables = tuple[PolicyTypes, dict[str, NDArray[Any]]]


class _PaletteTables:
    """Instantiation's tables of each live palette, by sweep step and speed clearance
    (``f"{step!r}-{speed_clearance!r}"``).

    A palette is keyed by identity (it is not hashable) and held weakly: its entry goes
    when it is collected. The tables hold no reference to the palette.
    """

    def __init__(self) -> None:
        self._entries: dict[int, tuple[weakref.ref[Palette], dict[str, _Tables]]]
        self._entries = {}

    def of(self, palette: Palette) -> dict[str, _Tables]:
        """The tables computed so far for ``palette`` (a dict to add to)."""
        key = id(palette)
        got = self._entries.get(key)
        if got is not None and got[0]() is palette:
            return got[1]
        entries = self._entries

        def forget(ref: weakref.ref[Palette]) -> None:
            if key in entries and entries[key][0] is ref:
                del entries[key]

        tables: dict[str, _Tables] = {}
        entries[key] = (weakref.ref(palette, forget), tables)
        return tables


_PALETTE_TABLES = _PaletteTables()


def _palette_tables(palette: Palette, step: float, speed_clearance: float) -> _Tables:
    """The palette's types and swept outer domain tables for sweep step ``step`` and
    ``speed_clearance``: they depend on the palette only, so they are computed once per
    palette, step and speed clearance."""
    cache = _PALETTE_TABLES.of(palette)
    key = f"{step!r}-{speed_clearance!r}"
    cached = cache.get(key)
    if cached is None:
        samples: dict[int, tuple[FloatArray, FloatArray, IntArray]] = {}
        sweeps = []
        for pol in palette.policies:
            got = samples.get(id(pol.primitive))
            if got is None:
                got = samples[id(pol.primitive)] = sweep_samples(pol, step, 0.5 * speed_clearance)
            sweeps.append(_sweep(pol, step, got, speed_clearance))
        cached = cache[key] = (
            PolicyTypes.from_palette(palette),
            _sweep_tables(sweeps),
        )
    return cached


def _lattice(world_map: WorldMap, spacing: float) -> tuple[FloatArray, int, int, FloatArray]:
    """Origin (2,), nx, ny and the points (ny · nx, 2) of the instantiation lattice."""
    (x0, y0), (x1, y1) = world_map.bounds
    nx = math.floor((x1 - x0) / spacing + _LATTICE_EPS) + 1
    ny = math.floor((y1 - y0) / spacing + _LATTICE_EPS) + 1
    origin = np.array([x0, y0])
    ix = np.tile(np.arange(nx), ny)
    iy = np.repeat(np.arange(ny), nx)
    pts = np.column_stack([x0 + ix * spacing, y0 + iy * spacing])
    return origin, nx, ny, pts


def _check_sweeps(
    world_map: WorldMap,
    points: FloatArray,
    pair_type: IntArray,
    pair_point: IntArray,
    tables: dict[str, NDArray[Any]],
    footprint: float,
) -> BoolArray:
    """Validity of undecided (type, point) pairs: group discs first, samples where a
    group disc is not clear (compiled; the clearance is computed as
    :meth:`gracenav.world.WorldMap.clearance` computes it, operation for operation)."""
    valid = np.ones(pair_type.size, dtype=bool)
    if pair_type.size == 0:
        return valid
    _, nearest = world_map._clearance_data()
    (x0, y0), (x1, y1) = world_map.bounds
    _check_sweeps_kernel(
        valid,
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(pair_type, dtype=np.int64),
        np.ascontiguousarray(pair_point, dtype=np.int64),
        tables["type_group_first"],
        tables["type_group_count"],
        tables["group_centre"],
        tables["group_reach"],
        tables["group_sample_first"],
        tables["group_size"],
        tables["sample_offset"],
        tables["sample_reach"],
        float(footprint),
        nearest,
        np.ascontiguousarray(world_map.occupied, dtype=np.bool_),
        float(world_map.origin[0]),
        float(world_map.origin[1]),
        float(world_map.resolution),
        float(x0),
        float(y0),
        float(x1),
        float(y1),
    )
    return valid


@njit(cache=True, nogil=True)
def _clearance_at(
    px: float,
    py: float,
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> float:
    """:meth:`gracenav.world.WorldMap.clearance` of one point, the same operations in
    the same order (so the same value)."""
    ny, nx = occupied.shape
    fx = np.floor((px - ox) / res)
    fy = np.floor((py - oy) / res)
    if not (fx >= 0 and fx < nx and fy >= 0 and fy < ny):
        return 0.0
    iy = int(fy)
    ix = int(fx)
    if occupied[iy, ix]:
        return 0.0
    ky = int(np.floor((py - oy) / res - 0.5)) + 1
    kx = int(np.floor((px - ox) / res - 0.5)) + 1
    best = np.inf
    for k in range(4):
        dyk = k >> 1
        dxk = k & 1
        jy = nearest[0, ky + dyk, kx + dxk] - 1
        jx = nearest[1, ky + dyk, kx + dxk] - 1
        bx0 = ox + jx * res
        by0 = oy + jy * res
        dx = max(max(bx0 - px, px - (bx0 + res)), 0.0)
        dy = max(max(by0 - py, py - (by0 + res)), 0.0)
        best = min(best, np.hypot(dx, dy))
    edge = min(min(px - xmin, xmax - px), min(py - ymin, ymax - py))
    return max(min(best, edge), 0.0)


@njit(cache=True, nogil=True, parallel=True)
def _check_sweeps_kernel(
    valid: Any,
    points: Any,
    pair_type: Any,
    pair_point: Any,
    type_group_first: Any,
    type_group_count: Any,
    group_centre: Any,
    group_reach: Any,
    group_sample_first: Any,
    group_size: Any,
    sample_offset: Any,
    sample_reach: Any,
    footprint: float,
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> None:
    """Mark the pairs whose swept D' is not clear: a pair is valid iff in every group
    either the bounding disc or every sample is clear (see :func:`build_library`)."""
    for a in prange(pair_type.size):  # independent pairs: no shared writes
        t = pair_type[a]
        qx = points[pair_point[a], 0]
        qy = points[pair_point[a], 1]
        g0 = type_group_first[t]
        for g in range(g0, g0 + type_group_count[t]):
            c = _clearance_at(
                qx + group_centre[g, 0],
                qy + group_centre[g, 1],
                nearest,
                occupied,
                ox,
                oy,
                res,
                xmin,
                ymin,
                xmax,
                ymax,
            )
            if c >= footprint + group_reach[g]:
                continue
            s0 = group_sample_first[g]
            for k in range(s0, s0 + group_size[g]):
                c = _clearance_at(
                    qx + sample_offset[k, 0],
                    qy + sample_offset[k, 1],
                    nearest,
                    occupied,
                    ox,
                    oy,
                    res,
                    xmin,
                    ymin,
                    xmax,
                    ymax,
                )
                if c < footprint + sample_reach[k]:
                    valid[a] = False
                    break
            if not valid[a]:
                break


def _sweep_tables(sweeps: list[_Sweep]) -> dict[str, NDArray[Any]]:
    """Concatenate the sweeps of every type (rotated) into flat tables."""
    offs, reach, gc, gr, gsf, gsz, tgf, tgc, total = [], [], [], [], [], [], [], [], []
    n_samples = n_groups = 0
    for sw in sweeps:
        for k in range(ORIENTATIONS):
            offs.append(_rotate(sw.offsets, k))
            reach.append(sw.reach)
            gc.append(_rotate(sw.group_centre, k))
            gr.append(sw.group_reach)
            gsf.append(sw.group_first + n_samples)
            gsz.append(sw.group_size)
            tgf.append(n_groups)
            tgc.append(sw.group_first.size)
            total.append(sw.total_reach)
            n_samples += sw.offsets.shape[0]
            n_groups += sw.group_first.size
    return {
        "sample_offset": np.concatenate(offs),
        "sample_reach": np.concatenate(reach),
        # What the start point's own clearance must exceed (the first sample leads it by
        # half the allowance times the start velocity; clearance is 1-Lipschitz).
        "sample_first_reach": np.array(
            [sw.reach[0] - math.hypot(*sw.offsets[0]) for sw in sweeps for _ in range(4)]
        ),
        "group_centre": np.concatenate(gc),
        "group_reach": np.concatenate(gr),
        "group_sample_first": np.concatenate(gsf).astype(np.int64),
        "group_size": np.concatenate(gsz).astype(np.int64),
        "type_group_first": np.array(tgf, dtype=np.int64),
        "type_group_count": np.array(tgc, dtype=np.int64),
        "type_total_reach": np.array(total),
    }


def _instantiate(
    palette: Palette,
    types: PolicyTypes,
    tables: dict[str, NDArray[Any]],
    world_map: WorldMap,
    spacing: float,
    footprint: float,
    sweep_step: float,
) -> PolicyLibrary:
    origin, nx, ny, points = _lattice(world_map, spacing)
    c0 = world_map.clearance(points)
    n_points = points.shape[0]
    # Start domain sizes from the largest down: a scale group (a policy and its larger
    # variants at one orientation) takes at each point the largest size that fits, so
    # a smaller size is only checked where every larger one failed.
    taken = np.zeros((int(types.scale_group.max(initial=-1)) + 1, n_points), dtype=bool)
    found_t: list[IntArray] = []
    found_q: list[IntArray] = []
    for size in np.unique(types.start_radii[:, 0])[::-1]:
        sure_t: list[IntArray] = []
        sure_q: list[IntArray] = []
        undecided_t: list[IntArray] = []
        undecided_q: list[IntArray] = []
        # A capture regulator is invariant under rotations (rest reference, round
        # domains in the plane): one orientation suffices.
        placed = (types.start_radii[:, 0] == size) & _placed_types(types)
        for t in np.flatnonzero(placed):
            maybe = np.flatnonzero(
                (c0 >= footprint + tables["sample_first_reach"][t]) & ~taken[types.scale_group[t]]
            )
            sure = c0[maybe] >= footprint + tables["type_total_reach"][t]
            sure_q.append(maybe[sure])
            sure_t.append(np.full(int(np.count_nonzero(sure)), t, dtype=np.int64))
            undecided_q.append(maybe[~sure])
            undecided_t.append(np.full(int(np.count_nonzero(~sure)), t, dtype=np.int64))
        ut, uq = np.concatenate(undecided_t), np.concatenate(undecided_q)
        ok = _check_sweeps(world_map, points, ut, uq, tables, footprint)
        lt = np.concatenate([*sure_t, ut[ok]])
        lq = np.concatenate([*sure_q, uq[ok]])
        taken[types.scale_group[lt], lq] = True
        found_t.append(lt)
        found_q.append(lq)
    if found_t:
        all_t, all_q = np.concatenate(found_t), np.concatenate(found_q)
        # Type-major, point-ascending order.
        order = np.lexsort((all_q, all_t))
        typ, pt = all_t[order], all_q[order]
    else:
        typ = pt = np.zeros(0, dtype=np.int64)
    p_idx = types.palette_index[typ]
    k_idx = types.orientation[typ]
    cell = np.column_stack([pt % nx, pt // nx]).astype(np.int64)
    start_xy = points[pt] if pt.size else np.zeros((0, 2))
    start_state = np.concatenate([start_xy, types.start_velocity[typ]], axis=1)
    end_state = np.concatenate([start_xy + types.end_offset[typ], types.end_velocity[typ]], axis=1)
    return PolicyLibrary(
        palette=palette,
        world_map=world_map,
        footprint_radius=footprint,
        spacing=spacing,
        lattice_shape=(ny, nx),
        origin=_readonly(origin),
        types=types,
        palette_index=_readonly(p_idx),
        orientation=_readonly(k_idx),
        start_cell=_readonly(cell),
        start_xy=_readonly(start_xy),
        start_state=_readonly(start_state),
        end_state=_readonly(end_state),
        durations=_readonly(types.duration[typ]),
        path_lengths=_readonly(types.path_length[typ]),
        sweep_step=sweep_step,
    )


# --------------------------------------------------------------------------------------
# Coverage
# --------------------------------------------------------------------------------------


def max_trim_speed(palette: Palette) -> float:
    """v_max: the largest reference speed of the palette's trim policies (m/s); 0 if the
    palette has no cruise trim."""
    speeds = [
        float(np.hypot(*p.primitive.start_velocity))
        for p in palette.policies
        if p.primitive.is_trim
    ]
    return max(speeds, default=0.0)


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


# --------------------------------------------------------------------------------------
# Building
# --------------------------------------------------------------------------------------


def _placed_types(types: PolicyTypes) -> BoolArray:
    """Types instantiated: all but the orientations k > 0 of a rotation-invariant capture
    regulator (rest reference, round domains), for which one orientation suffices."""
    invariant = (
        types.is_capture
        & np.all(types.start_velocity == 0.0, axis=1)
        & np.all(types.end_offset == 0.0, axis=1)
    )
    out: BoolArray = ~(invariant & (types.orientation > 0))
    return out


def estimate_library_size(
    palette: Palette,
    world_map: WorldMap,
    spacing: float,
    *,
    footprint_radius: float = 0.2,
    sweep_step: float | None = None,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
) -> tuple[int, int]:
    """Bounds on the number of policies one pass at ``spacing`` would keep, without
    instantiating: O(P log P) in the lattice points P.

    A scale group (a policy and its larger-domain variants at one orientation) keeps at
    most one policy per lattice point, and exactly one where the clearance of the point
    is at least the footprint plus the reach of a whole swept D' of one of its sizes
    (the instantiation's "sure" test). Points below the footprint plus the reach of the
    first sample cannot hold the group.

    Parameters
    ----------
    palette : Palette
    world_map : WorldMap
    spacing : float
        Lattice spacing (m).
    footprint_radius : float
        Robot footprint radius (m).
    sweep_step : float, optional
        As for :func:`build_library`; default the map resolution.
    speed_clearance : float
        As for :func:`build_library` (s).

    Returns
    -------
    (int, int)
        A lower and an upper bound of the library size.
    """
    step = float(sweep_step) if sweep_step is not None else float(world_map.resolution)
    types, tables = _palette_tables(palette, step, float(speed_clearance))
    _, _, _, points = _lattice(world_map, spacing)
    c0 = np.sort(world_map.clearance(points))
    placed = _placed_types(types)
    groups = types.scale_group[placed]
    fp = float(footprint_radius)

    def count(reach: FloatArray) -> int:
        """Σ over scale groups of the most points any of its types passes."""
        n_ok = c0.size - np.searchsorted(c0, fp + reach[placed], side="left")
        best = np.zeros(int(types.scale_group.max(initial=-1)) + 1, dtype=np.int64)
        np.maximum.at(best, groups, n_ok)
        return int(best.sum())

    return count(tables["type_total_reach"]), count(tables["sample_first_reach"])


def _check_memory(
    palette: Palette,
    world_map: WorldMap,
    spacing: float,
    footprint: float,
    step: float,
    speed_clearance: float,
    limit: float,
    halving: int,
) -> None:
    """Refuse a pass whose library would not fit in ``limit`` bytes (see
    :func:`build_library`)."""
    low, high = estimate_library_size(
        palette,
        world_map,
        spacing,
        footprint_radius=footprint,
        sweep_step=step,
        speed_clearance=speed_clearance,
    )
    need = low * POLICY_BYTES
    if need > limit:
        (x0, y0), (x1, y1) = world_map.bounds
        raise ConfigError(
            f"{world_map.source}: one pass at spacing {spacing:g} m (halving {halving}) on "
            f"this {x1 - x0:g} m × {y1 - y0:g} m map would keep {low:.3g} to {high:.3g} "
            f"policies, needing at least {need / 2**30:.1f} GiB for the library, its graph "
            f"and a search ({POLICY_BYTES} bytes per policy), above memory_limit "
            f"{limit / 2**30:.1f} GiB; plan on a smaller map or region of it, use fewer "
            "halvings, or raise memory_limit"
        )


def _check_inputs(
    palette: Palette,
    world_map: WorldMap,
    footprint_radius: float,
    coverage_target: float,
    max_halvings: int,
    coverage_samples: int,
    sweep_step: float | None,
    memory_limit: float | None,
    speed_clearance: float,
) -> None:
    if not isinstance(palette, Palette):
        raise ConfigError(f"palette must be a Palette, got {type(palette).__name__}")
    if not isinstance(world_map, WorldMap):
        raise ConfigError(
            f"world_map must be a WorldMap (see gracenav.world.load_map), got "
            f"{type(world_map).__name__}"
        )
    if len(palette) == 0:
        raise ConfigError("the palette has no policies; build one with `gracenav palette build`")
    if not (math.isfinite(palette.d) and palette.d > 0):
        raise ConfigError(f"palette distance parameter d must be positive, got {palette.d!r}")
    if not (isinstance(footprint_radius, int | float) and math.isfinite(footprint_radius)):
        raise ConfigError(f"footprint_radius must be a finite number (m), got {footprint_radius!r}")
    if footprint_radius < 0:
        raise ConfigError(
            f"footprint_radius must be >= 0 m, got {footprint_radius:g}; the robot body "
            "needs about 0.2 m"
        )
    if not (isinstance(coverage_target, int | float) and 0.0 <= coverage_target <= 1.0):
        raise ConfigError(f"coverage_target must be a fraction in [0, 1], got {coverage_target!r}")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, int) or max_halvings < 0:
        raise ConfigError(f"max_halvings must be an integer >= 0, got {max_halvings!r}")
    if (
        isinstance(coverage_samples, bool)
        or not isinstance(coverage_samples, int)
        or coverage_samples < 1
    ):
        raise ConfigError(f"coverage_samples must be an integer >= 1, got {coverage_samples!r}")
    if sweep_step is not None and not (
        isinstance(sweep_step, int | float) and math.isfinite(sweep_step) and sweep_step > 0
    ):
        raise ConfigError(f"sweep_step must be a positive length (m), got {sweep_step!r}")
    if not (
        isinstance(speed_clearance, int | float)
        and not isinstance(speed_clearance, bool)
        and 0.0 <= speed_clearance <= MAX_SPEED_CLEARANCE
    ):
        raise ConfigError(
            f"speed_clearance must be a time in [0, {MAX_SPEED_CLEARANCE:g}] s (extra "
            f"clearance per m/s of reference speed), got {speed_clearance!r}"
        )
    if memory_limit is not None and not (
        isinstance(memory_limit, int | float)
        and not isinstance(memory_limit, bool)
        and memory_limit > 0
    ):
        raise ConfigError(
            f"memory_limit must be a positive number of bytes or None, got {memory_limit!r}"
        )
    for pol in palette.policies:
        start = pol.primitive.position[0, :2]
        if np.any(np.abs(start) > 1e-9):
            raise ConfigError(
                f"palette policy {pol.name!r} starts at {tuple(start)} m, not at the origin of "
                "its frame; rebuild the palette"
            )


def build_library(
    palette: Palette,
    world_map: WorldMap,
    *,
    footprint_radius: float = 0.2,
    coverage_target: float = 1.0,
    max_halvings: int = 3,
    seed: int = 0,
    coverage_samples: int = DEFAULT_COVERAGE_SAMPLES,
    sweep_step: float | None = None,
    memory_limit: float | None = DEFAULT_MEMORY_LIMIT,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
) -> PolicyLibrary:
    """Instantiate the palette on a map with coverage-driven lattice refinement.

    Parameters
    ----------
    palette : Palette
        The motion policy palette Π(Σ(d)).
    world_map : WorldMap
        The map M; its minimum corner anchors the lattice of instantiation points
        (so a goal on that lattice is an instantiation point).
    footprint_radius : float
        Robot footprint radius (m), >= 0. The body is 0.37 m across.
    coverage_target : float
        Coverage fraction in [0, 1] at which refinement stops.
    max_halvings : int
        Largest number of spacing halvings (the last lattice spacing is at least
        d / 2^max_halvings).
    seed : int
        Seed of the coverage sampling.
    coverage_samples : int
        Position states sampled to estimate coverage (the same set at every spacing,
        so coverage never decreases from one spacing to the next).
    sweep_step : float, optional
        Largest arc length (m) between the checked samples of a swept outer domain;
        default the map resolution.
    memory_limit : float or None
        Bytes the library, its graph and a search may take (default 4 GiB). Before
        each pass, the lower bound of :func:`estimate_library_size` times
        :data:`POLICY_BYTES` is compared with it and an over-budget pass is refused;
        None turns the check off.
    speed_clearance : float
        Stopping allowance (s): where the reference moves at velocity v, an obstacle
        straight ahead must be this times |v| farther than the swept D' needs; the disc
        checked for it also asks half of that beside the path, nothing behind (0 is the
        paper's instantiation; see the notes).

    Returns
    -------
    PolicyLibrary
        The library at the last spacing tried, with the per-iteration records.

    Raises
    ------
    ConfigError
        For invalid arguments (the message names the argument), and for a pass whose
        estimated memory exceeds ``memory_limit`` (the message gives the estimate).
    MapError
        If no position of the map has clearance >= ``footprint_radius``.

    Notes
    -----
    **Obstacle check.** Instantiation at point q with orientation k is valid iff for
    every t in [0, t_f] the disc of radius f + ρ'(t) around q + R_k σ_xy(t) lies in
    free space inside the map (f the footprint radius, ρ'(t) the XY radius of D'(t):
    outer position factor × position extent of D(t)). It is checked with
    ``world_map.clearance`` (distance to the nearest occupied cell or the map edge,
    0 outside; as exact as the map's rasterisation, within one cell of the true
    obstacles) at reference samples c_0 = 0, ..., c_K = σ_xy(t_f), chosen at most
    ``sweep_step`` of arc apart (plus one control tick of motion). Between samples
    j and j+1, separated by arc length ℓ_j, every reference point is within ℓ_j / 2
    of one of them, and ρ'(t) (geometric in t, hence monotone) is at most
    max(ρ'_j, ρ'_{j+1}). So requiring

        clearance(q + c_j) >= f + max over adjacent intervals i of
                                  (max(ρ'_i, ρ'_{i+1}) + ℓ_i / 2)

    at every sample is sufficient: the allowance for the spacing of samples is
    ℓ/2 <= (sweep_step + one tick of motion) / 2. To be fast the check is
    hierarchical and uses that clearance is a distance (1-Lipschitz): a disc around q
    (then one around each group of 8 samples) that bounds all the required discs is
    tested first, and the samples only where it is not clear. Loops run over
    palette policies × orientations only; all points are handled by numpy.

    **Stopping allowance.** With ``speed_clearance`` κ_v > 0 an obstacle in direction
    u from the reference point at velocity v must also leave κ_v max(0, v · u) more
    room: the full κ_v |v| straight ahead, nothing beside or behind. The disc of radius
    f + ρ'(t) + κ_v |v|/2 centred κ_v v/2 ahead of σ_xy(t) contains that region: with
    R = f + ρ' and a = κ_v |v|/2, its boundary in direction θ from v lies at
    a cos θ + √((R + a)² − a² sin² θ), whose square exceeds that of
    R + 2a max(0, cos θ) by 2aR(1 − |cos θ|) >= 0. So the check above runs on the
    path led by κ_v v/2 with every reach grown by κ_v |v|/2 (the samples take the
    fastest tick between them and their neighbours).
    Verification does not depend on it (D' is unchanged); it keeps policies from
    heading fast at obstacles, so that a push there leaves room for a catch
    (:mod:`gracenav.execution.capture`) to stop the robot: a push of 8–16 N s leaves
    0.8–1.2 m/s, whose shortest verified catch reaches 0.7–1.2 m. Running along a wall
    costs half the allowance beside it. Rest policies (the goals, and the catches'
    ends) are unaffected.

    **Coverage** is the fraction of ``coverage_samples`` position states, uniform
    over free positions with clearance >= f and velocities in [−v_max, v_max]² (v_max
    the largest trim speed; see :func:`sample_position_states` and
    :func:`max_trim_speed`), inside at least one start domain S. Points whose
    clearance is below f + (outer position factor − 1) · ρ_S (ρ_S the XY radius of
    S) cannot be covered: no valid start domain reaches them. On maps with walls
    coverage therefore stays below 1 and a target of 1 uses every halving.
    """
    _check_inputs(
        palette,
        world_map,
        footprint_radius,
        coverage_target,
        max_halvings,
        coverage_samples,
        sweep_step,
        memory_limit,
        speed_clearance,
    )
    footprint = float(footprint_radius)
    allowance = float(speed_clearance)
    step = float(sweep_step) if sweep_step is not None else float(world_map.resolution)
    types, tables = _palette_tables(palette, step, allowance)
    samples = sample_position_states(
        world_map,
        coverage_samples,
        footprint_radius=footprint,
        v_max=max_trim_speed(palette),
        seed=seed,
    )
    iterations: list[InstantiationIteration] = []
    library: PolicyLibrary | None = None
    coverage = 0.0
    for h in range(max_halvings + 1):
        t0 = time.perf_counter()
        spacing = palette.d / 2**h
        if memory_limit is not None:
            _check_memory(
                palette, world_map, spacing, footprint, step, allowance, float(memory_limit), h
            )
        library = _instantiate(palette, types, tables, world_map, spacing, footprint, step)
        coverage = float(np.mean(library.start_domain_covers(samples)))
        iterations.append(
            InstantiationIteration(spacing, len(library), coverage, time.perf_counter() - t0)
        )
        if coverage >= coverage_target:
            break
    assert library is not None
    return library._with_results(
        coverage=coverage, iterations=tuple(iterations), speed_clearance=allowance
    )
