"""What a library is made of: the policy types (one row per palette policy and
orientation), instantiated policies, the quarter turns of the plane."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError
from gracenav.model.indices import PHI, PHI_X_DOT, PHI_Y_DOT
from gracenav.model.rotation import QUARTER_TURNS, quarter_turn, rotate_pairs
from gracenav.palette import Palette
from gracenav.policies import MotionPolicy, PrimitiveKind
from gracenav.policies.domains import EllipsoidalDomain
from gracenav.policies.placement import placed_positions

__all__ = [
    "ORIENTATIONS",
    "InstantiatedPolicy",
    "InstantiationIteration",
    "PolicyTypes",
    "quarter_turn",
]

FloatArray = NDArray[np.float64]

IntArray = NDArray[np.int64]

BoolArray = NDArray[np.bool_]

#: Orientations of instantiation: k · 90° for k = 0..3.
ORIENTATIONS = 4

_QUARTER_TURNS = QUARTER_TURNS

_CHUNK = 1 << 19  # clearance queries evaluated at once

_LATTICE_EPS = 1e-9  # relative slack when counting lattice points across the map


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
    """Rotate (..., 2) vectors by k · 90° (:func:`gracenav.model.rotation.rotate_pairs`)."""
    return rotate_pairs(vectors, k)


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
        bisection, its larger-domain variants and its fine copies. Instantiation keeps,
        per group and point, only the largest start domain whose swept D' fits, so a
        fine copy is placed only where the unscaled policy does not fit.
    fine_factor : ndarray, shape (T,)
        λ of a fine copy (:attr:`gracenav.policies.VerificationOptions.fine_scales`): its
        G over the palette's; 1 for every other policy.
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
    fine_factor: FloatArray

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
        # λ of the fine copies: their G over the palette's (every other policy has it).
        goal_extent = palette.options.goal_position_extent
        fine = np.array([min(1.0, p.goal_radii.position / goal_extent) for p in pols], dtype=float)
        fine = np.where(np.isclose(fine, 1.0, rtol=1e-9, atol=0.0), 1.0, fine)

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
            "fine_factor": per_type(fine),
        }
        return cls(**{k: _readonly(v) for k, v in arrays.items()})

    def boundary(self, which: str) -> FloatArray:
        """Reference boundary states at ``which`` = "start" or "end": velocity,
        acceleration, lean, lean rate, shape (T, 8) (m/s, m/s², rad, rad/s)."""
        if which not in ("start", "end"):
            raise ConfigError(f"boundary must be 'start' or 'end', got {which!r}")
        names = ("velocity", "acceleration", "lean", "lean_rate")
        return np.concatenate([getattr(self, f"{which}_{n}") for n in names], axis=1)


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
        out = placed_positions(self.policy.primitive.position, self.orientation, self.start_xy)
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
