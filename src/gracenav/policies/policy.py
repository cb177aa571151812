"""Motion policies, their verified domains, and the motion policy palette.

A motion policy Φ (paper Sec. III-B) is a motion primitive σ(t), the
time-varying tracking control law φ(t) of the Fig. 2 architecture, and a
time-varying domain D(t) with an outer domain D'(t) ⊃ D(t), all in the 4D
position state space (x, y, ẋ, ẏ). S = D(0) is the start domain and
G = D(t_f) the goal domain.

Domain shape. Along each axis a domain couples position and velocity
deviations: Σ = [[e_p², r e_p e_v], [r e_p e_v, e_v²]] ⊗ I₂ with extents e_p
(m), e_v (m/s) and correlation r (:func:`gracenav.policies.domains.correlated_shape`),
so it is invariant under the 90° rotations of instantiation. The ratio
e_v/e_p and r are the same for every policy and come from the closed loop
(:func:`domain_shape`): the ellipse that the linearised closed loop, started
with the lean at its planned value, contracts the most over the shortest trim
(1 s). A round domain (r = 0, e_v = e_p·1/s) is not contracted at all in 1 s
by this non-minimum-phase robot: its worst boundary point is still at 1.17×
the radius, so trims could not be chained; the coupled ellipse shrinks to
0.28× in the same time.

Every policy of a palette shares one goal size G
(``VerificationOptions.goal_position_extent``), and its start size S >= G is
the largest that verification on the 3D model accepts (bisection on the
scale S/G). D(t) shrinks geometrically from S to G; D'(t) is D(t) stretched
by fixed factors in position and in velocity (the non-minimum-phase start of
every correction briefly doubles a velocity error). Because S >= G for every
verified policy and all share one shape, condition (i) of the gracefully
prepares relation, G₁ ⊂ S₂, holds for every pair whose primitives connect.

Verification (paper Sec. III-B) simulates the closed loop on the 3D model
from points on the surface of S (every axis extreme plus a quasi-uniform set;
the shape at its planned value) and requires for every run: inside D'(t) at
every control tick, inside G at t_f, |lean| within the balancing controller's
domain, and torque within the limit (no saturation).
"""

from __future__ import annotations

import enum
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import CONTROL_RATE, ControllerGains, design_gains
from gracenav.errors import ConfigError
from gracenav.params import BallbotParams
from gracenav.policies.domains import EllipsoidalDomain, correlated_shape, sphere_points
from gracenav.sim import (
    Disturbance,
    Reference,
    SimulationOptions,
    SimulationResult,
    position_state,
    simulate,
    simulate_batch,
    state_from_position,
)
from gracenav.sim.plant import PlantKind

__all__ = [
    "BrakingOptions",
    "CatchOptions",
    "DomainRadii",
    "DomainShape",
    "MotionPolicy",
    "PrimitiveKind",
    "PushLeanTable",
    "RegulatorOptions",
    "SampledPrimitive",
    "VerificationOptions",
    "VerificationReport",
    "capture_point",
    "combined_report",
    "domain_shape",
    "flat_position_state",
    "push_lean_table",
    "regulator_label",
    "regulator_policies",
    "rotate_pairs_by",
    "run_policy",
    "scaled_variants",
    "size_policy",
    "variant_label",
    "verify_placements",
    "verify_policy",
]

FloatArray = NDArray[np.float64]


class _Sample(Protocol):
    @property
    def states(self) -> FloatArray: ...
    @property
    def accelerations(self) -> FloatArray: ...
    @property
    def inputs(self) -> FloatArray: ...
    @property
    def position(self) -> FloatArray: ...


class PrimitiveLike(Protocol):
    """What :meth:`SampledPrimitive.from_primitive` needs of a motion primitive."""

    @property
    def name(self) -> str: ...
    @property
    def duration(self) -> float: ...
    @property
    def is_trim(self) -> bool: ...
    @property
    def displacement(self) -> FloatArray: ...
    @property
    def start_velocity(self) -> FloatArray: ...
    @property
    def end_velocity(self) -> FloatArray: ...
    def sample(self, timepts: ArrayLike) -> _Sample: ...


class PrimitiveKind(enum.Enum):
    """Trim primitives (rest or constant velocity) and maneuvers (paper Sec. III-A)."""

    REST = "rest"
    CRUISE = "cruise"
    MANEUVER = "maneuver"


@dataclass(frozen=True)
class SampledPrimitive:
    """A motion primitive sampled at the control ticks: what a policy executes.

    Attributes
    ----------
    name : str
    kind : PrimitiveKind
    duration : float
        t_f (s); a whole number of control periods.
    dt : float
        Control period (s).
    displacement : ndarray, shape (2,)
        Net (Δx, Δy) (m).
    start_velocity, end_velocity : ndarray, shape (2,)
        Reference ball velocity at t = 0 and t_f (m/s).
    states : ndarray, shape (T + 1, 8)
        Reference model states at the ticks, in the primitive's own frame.
    accelerations : ndarray, shape (T + 1, 4)
        Reference q̈ at the ticks (rad/s²).
    inputs : ndarray, shape (T + 1, 2)
        Feed-forward torques (N m), including the planned friction.
    position : ndarray, shape (T + 1, 6)
        Ball x, y, ẋ, ẏ, ẍ, ÿ (m, m/s, m/s²) at the ticks, starting at (0, 0).
    """

    name: str
    kind: PrimitiveKind
    duration: float
    dt: float
    displacement: FloatArray
    start_velocity: FloatArray
    end_velocity: FloatArray
    states: FloatArray
    accelerations: FloatArray
    inputs: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        n = self.states.shape[0]
        if (
            self.states.shape != (n, 8)
            or self.accelerations.shape != (n, 4)
            or self.inputs.shape != (n, 2)
            or self.position.shape != (n, 6)
        ):
            raise ConfigError(f"primitive {self.name}: inconsistent sample shapes")
        if abs((n - 1) * self.dt - self.duration) > 1e-9:
            raise ConfigError(
                f"primitive {self.name}: duration {self.duration} s is not {n - 1} control periods"
            )

    @property
    def is_trim(self) -> bool:
        """Whether this is a trim primitive."""
        return self.kind is not PrimitiveKind.MANEUVER

    @property
    def num_ticks(self) -> int:
        """Number of control periods T."""
        return int(self.states.shape[0] - 1)

    @classmethod
    def from_primitive(
        cls, primitive: PrimitiveLike, *, control_rate: float = CONTROL_RATE
    ) -> SampledPrimitive:
        """Sample a :class:`gracenav.primitives.MotionPrimitive` at the control ticks.

        The primitive's duration must be a whole number of control periods.
        """
        p = primitive
        dt = 1.0 / control_rate
        duration = float(p.duration)
        n = round(duration / dt)
        if abs(n * dt - duration) > 1e-9:
            raise ConfigError(
                f"primitive {p.name} lasts {duration} s, not a whole number of control "
                f"periods of {dt} s"
            )
        s = p.sample(np.arange(n + 1, dtype=np.float64) * np.float64(dt))
        if p.is_trim:
            moving = bool(np.any(np.asarray(p.end_velocity) != 0.0))
            kind = PrimitiveKind.CRUISE if moving else PrimitiveKind.REST
        else:
            kind = PrimitiveKind.MANEUVER
        return cls(
            name=str(p.name),
            kind=kind,
            duration=n * dt,
            dt=dt,
            displacement=np.asarray(p.displacement, dtype=np.float64),
            start_velocity=np.asarray(p.start_velocity, dtype=np.float64),
            end_velocity=np.asarray(p.end_velocity, dtype=np.float64),
            states=np.ascontiguousarray(s.states, dtype=np.float64),
            accelerations=np.ascontiguousarray(s.accelerations, dtype=np.float64),
            inputs=np.ascontiguousarray(s.inputs, dtype=np.float64),
            position=np.ascontiguousarray(s.position, dtype=np.float64),
        )

    def rotated(self, k: int) -> SampledPrimitive:
        """The samples rotated by k·90° about the start (exact relabelling of the pairs).

        180° is an exact symmetry of the 3D model; 90° is not quite (I_xx ≠ I_yy and
        the lean's Euler order), so the rotated feed-forward torque is off by up to
        ≈0.2 N m. Verification therefore checks the 0° and the 90° placement.
        """
        if k % 4 == 0:
            return self
        return replace(
            self,
            displacement=rotate_pairs(self.displacement, k),
            start_velocity=rotate_pairs(self.start_velocity, k),
            end_velocity=rotate_pairs(self.end_velocity, k),
            states=rotate_pairs(self.states, k),
            accelerations=rotate_pairs(self.accelerations, k),
            inputs=rotate_pairs(self.inputs, k),
            position=rotate_pairs(self.position, k),
        )

    def rotated_by(self, angle: float) -> SampledPrimitive:
        """The samples rotated by ``angle`` (rad) about the start (:func:`rotate_pairs_by`;
        like :meth:`rotated`, not an exact symmetry of the 3D model, so policies placed
        at any heading are verified at several)."""
        return replace(
            self,
            displacement=rotate_pairs_by(self.displacement, angle),
            start_velocity=rotate_pairs_by(self.start_velocity, angle),
            end_velocity=rotate_pairs_by(self.end_velocity, angle),
            states=rotate_pairs_by(self.states, angle),
            accelerations=rotate_pairs_by(self.accelerations, angle),
            inputs=rotate_pairs_by(self.inputs, angle),
            position=rotate_pairs_by(self.position, angle),
        )

    def reference(self) -> Reference:
        """The reference for the closed loop, in the primitive's own frame."""
        return Reference(self.states, self.inputs, self.dt)

    def coarse(self, stride: int) -> tuple[FloatArray, FloatArray]:
        """States (M, 8) and accelerations (M, 4) at every ``stride``-th tick: enough to
        rebuild the primitive with :meth:`from_coarse` (the number of ticks must be a
        multiple of ``stride``)."""
        if self.num_ticks % stride:
            raise ConfigError(
                f"primitive {self.name}: {self.num_ticks} ticks not a multiple of {stride}"
            )
        return self.states[::stride].copy(), self.accelerations[::stride].copy()

    @classmethod
    def from_coarse(
        cls,
        states: FloatArray,
        accelerations: FloatArray,
        stride: int,
        *,
        name: str,
        kind: PrimitiveKind,
        dt: float,
        displacement: FloatArray,
        start_velocity: FloatArray,
        end_velocity: FloatArray,
        params: BallbotParams,
    ) -> SampledPrimitive:
        """Rebuild the samples at every tick from every ``stride``-th one.

        q, q̇ and q̈ between stored ticks come from the quintic Hermite interpolant
        (:mod:`gracenav._util.hermite`) of (q, q̇, q̈) at both ends (error ~h⁶ q⁽⁶⁾, below
        1e-10 rad for these smooth trajectories); the torques are recomputed from the 3D
        equations of motion so the rebuilt samples satisfy them. See :meth:`from_coarse_many`.
        """
        meta = {
            "name": name,
            "kind": kind,
            "dt": dt,
            "displacement": displacement,
            "start_velocity": start_velocity,
            "end_velocity": end_velocity,
        }
        (out,) = cls.from_coarse_many([(states, accelerations, stride, meta)], params)
        return out

    @classmethod
    def from_coarse_many(
        cls,
        items: Sequence[tuple[FloatArray, FloatArray, int, dict[str, Any]]],
        params: BallbotParams,
    ) -> list[SampledPrimitive]:
        """:meth:`from_coarse` for many primitives at once (one interpolation per
        stride and one evaluation of the equations of motion for all samples).

        ``items``: (states, accelerations, stride, meta) with ``meta`` holding the
        keyword arguments name, kind, dt, displacement, start_velocity, end_velocity.
        """
        from gracenav._kernels import rebuild_fine
        from gracenav._util.hermite import quintic_hermite_basis
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.model.friction import friction_constants

        intervals = np.array([it[0].shape[0] - 1 for it in items], dtype=np.int64)
        strides = np.array([int(it[2]) for it in items], dtype=np.int64)
        rows = intervals * strides + 1
        ffirst = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64)
        total = int(rows.sum())
        st = np.empty((total, 8))
        acc = np.empty((total, 4))
        tau = np.empty((total, 2))
        pos = np.empty((total, 6))
        c = Ballbot3D(params).constants()
        fr = friction_constants(params)
        by_step: dict[tuple[int, float], list[int]] = {}
        for k, (_, _, stride, meta) in enumerate(items):
            by_step.setdefault((int(stride), float(meta["dt"])), []).append(k)
        for (stride, dt), ks in by_step.items():
            coarse = [np.asarray(items[k][0], dtype=np.float64) for k in ks]
            cfirst = np.concatenate([[0], np.cumsum([a.shape[0] for a in coarse])[:-1]])
            rebuild_fine(
                np.ascontiguousarray(np.concatenate(coarse)),
                np.ascontiguousarray(np.concatenate([items[k][1] for k in ks]), dtype=np.float64),
                cfirst.astype(np.int64),
                ffirst[ks],
                intervals[ks],
                np.ascontiguousarray(quintic_hermite_basis(np.arange(stride) / stride)),
                stride * dt,
                c,
                fr,
                float(params.ball_radius),
                st,
                acc,
                tau,
                pos,
            )
        out = []
        for k, (_, _, _, meta) in enumerate(items):
            sl = slice(int(ffirst[k]), int(ffirst[k] + rows[k]))
            out.append(
                cls(
                    duration=(int(rows[k]) - 1) * float(meta["dt"]),
                    states=st[sl],
                    accelerations=acc[sl],
                    inputs=tau[sl],
                    position=pos[sl],
                    **meta,
                )
            )
        return out

    def position_state(self, t: ArrayLike) -> FloatArray:
        """Reference position state (x, y, ẋ, ẏ) at times ``t`` (s), linear between ticks
        and clamped to [0, t_f]. Shape (..., 4)."""
        tt: FloatArray = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.duration)
        k = tt / self.dt
        i = np.clip(np.floor(k).astype(np.int64), 0, max(self.num_ticks - 1, 0))
        w = np.clip(k - i, 0.0, 1.0)[..., None]
        a = self.position[i, :4]
        b = self.position[np.minimum(i + 1, self.num_ticks), :4]
        out: FloatArray = (1.0 - w) * a + w * b
        return out


@dataclass(frozen=True)
class DomainRadii:
    """Extents of a domain: largest position deviation (m) and velocity deviation (m/s)
    along an axis. Of two concentric domains of one shape (:func:`domain_shape`), the
    one with the larger extents contains the other."""

    position: float
    velocity: float

    def __post_init__(self) -> None:
        if not (self.position > 0 and self.velocity > 0):
            raise ConfigError(f"domain radii must be positive, got {self!r}")

    def scaled(self, factor: float) -> DomainRadii:
        """Both radii multiplied by ``factor``."""
        return DomainRadii(self.position * factor, self.velocity * factor)

    def contains(self, other: DomainRadii) -> bool:
        """Whether a concentric domain of radii ``other`` lies inside one of these radii."""
        return other.position <= self.position * (1 + 1e-12) and other.velocity <= self.velocity * (
            1 + 1e-12
        )


@dataclass(frozen=True)
class RegulatorOptions:
    """Capture regulators: policies that catch a moving robot and bring it to rest.

    A capture regulator holds a rest reference at its instantiation point p_c for
    ``duration`` (s). Its start domain S is centred on (p_c, 0) with its own shape
    (velocity extent ``velocity_per_position`` × position extent, correlation
    ``correlation`` < 0: the rest point lies ahead of a robot moving toward it), so one
    policy catches robots moving in any direction; its goal domain is the palette's G.
    Its outer domain D' does not shrink: uncorrelated, centred on the reference, with
    extents ``outer_position_factor`` e_p(S) and ``outer_velocity_factor`` e_v(S) (the
    error a push leaves does not decay geometrically while the lean settles). It is
    verified at each size of ``position_extents`` from ``boundary_points`` states on
    the surface of S, each started with the reference's lean and with the lean and
    lean rate a push leaves ``push_times`` after the impulse (:func:`push_lean_table`).

    Parameters
    ----------
    duration : float
        t_f (s).
    velocity_per_position : float
        e_v / e_p of S (1/s).
    correlation : float
        Position-velocity correlation r of S.
    position_extents : tuple of float
        Sizes e_p of S to verify (m), ascending; each that passes becomes a palette
        policy and instantiation places the largest whose swept D' fits.
    outer_position_factor, outer_velocity_factor : float
        D' extents over S extents.
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    push_impulses : tuple of float
        Impulses (N s) of the push table, along one axis on the robot at rest.
    push_times : tuple of float
        Times after the impulse (s) whose lean and lean rate start verification runs.
    """

    duration: float = 4.0
    velocity_per_position: float = 0.8
    correlation: float = -0.8
    position_extents: tuple[float, ...] = (0.2, 0.35, 0.55, 0.75, 0.9)
    outer_position_factor: float = 1.1
    outer_velocity_factor: float = 3.0
    boundary_points: int = 128
    push_impulses: tuple[float, ...] = (4.0, 8.0, 12.0, 16.0, 20.0, 24.0, 28.0, 32.0, 40.0)
    push_times: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3)

    def __post_init__(self) -> None:
        for name in ("position_extents", "push_impulses", "push_times"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        ext = self.position_extents
        ascending = all(b > a for a, b in itertools.pairwise(ext))
        if not ext or any(not v > 0 for v in ext) or not ascending:
            raise ConfigError(f"regulator position_extents must ascend and be > 0, got {ext}")
        if not (self.duration > 0 and self.velocity_per_position > 0):
            raise ConfigError("regulator duration and velocity_per_position must be positive")
        if not -1.0 < self.correlation < 1.0:
            raise ConfigError(f"regulator correlation must lie in (-1, 1), got {self.correlation}")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("regulator outer factors must be >= 1")
        if self.boundary_points < 8:
            raise ConfigError("regulator boundary_points must be >= 8 (the axis extremes)")
        if any(t < 0 for t in self.push_times) or any(v <= 0 for v in self.push_impulses):
            raise ConfigError("regulator push_times must be >= 0 and push_impulses > 0")

    def start_radii(self, position_extent: float) -> DomainRadii:
        """Extents of S of the regulator of size ``position_extent`` (m)."""
        return DomainRadii(position_extent, position_extent * self.velocity_per_position)

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> RegulatorOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})  # type: ignore[arg-type]


@dataclass(frozen=True)
class BrakingOptions:
    """The palette's braking maneuvers (see :mod:`gracenav.primitives.braking`).

    Parameters
    ----------
    speeds : tuple of float
        Nominal initial speeds (m/s), ascending.
    directions : tuple of (int, int)
        Lattice directions (i, j) of the first quadrant; instantiation adds the other
        three by rotation.
    lattice_divisions : int
        The stopping distance is a whole multiple of d / lattice_divisions along the
        direction's lattice vector (so the rest point is an instantiation point once
        the lattice is refined that far).
    max_lean : float
        Largest planned body tilt (rad).
    min_duration, max_duration : float
        Bounds of the deceleration time T (s).
    tail : float
        Rest held after the deceleration (s).
    scales : tuple of float
        Start domain sizes S/G, ascending; the palette keeps the largest that verifies.
    outer_position_factor, outer_position_floor : float
        D' position extent: max(factor e_p(S), floor) (m).
    outer_velocity_factor, outer_velocity_floor : float
        D' velocity extent: max(factor e_v(S), floor) (m/s). The error a push leaves
        is mostly in velocity (a lean that settles); the velocity extent costs nothing
        near obstacles, the position extent does.
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    """

    speeds: tuple[float, ...] = (0.2, 0.35, 0.5, 0.65, 0.8)
    directions: tuple[tuple[int, int], ...] = ((1, 0), (2, 1), (1, 1), (1, 2))
    lattice_divisions: int = 2
    max_lean: float = math.radians(4.5)
    min_duration: float = 1.0
    max_duration: float = 6.0
    tail: float = 1.0
    scales: tuple[float, ...] = (2.0, 3.0)
    outer_position_factor: float = 1.1
    outer_position_floor: float = 0.32
    outer_velocity_factor: float = 3.0
    outer_velocity_floor: float = 1.2
    boundary_points: int = 64

    def __post_init__(self) -> None:
        object.__setattr__(self, "speeds", tuple(float(v) for v in self.speeds))
        object.__setattr__(self, "scales", tuple(float(v) for v in self.scales))
        object.__setattr__(self, "directions", tuple((int(i), int(j)) for i, j in self.directions))
        if not self.speeds or any(not v > 0 for v in self.speeds):
            raise ConfigError(f"braking speeds must be positive, got {self.speeds}")
        if any(i < 0 or j < 0 or i == j == 0 for i, j in self.directions):
            raise ConfigError(
                f"braking directions must be non-zero first-quadrant lattice vectors, got "
                f"{self.directions}"
            )
        if not self.scales or any(s < 1 for s in self.scales):
            raise ConfigError(f"braking scales must be >= 1 (S ⊇ G), got {self.scales}")
        if self.lattice_divisions < 1:
            raise ConfigError("braking lattice_divisions must be >= 1")
        if not (0 < self.min_duration <= self.max_duration and self.tail > 0):
            raise ConfigError("braking durations must be positive, min <= max")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("braking outer factors must be >= 1")
        if self.boundary_points < 8:
            raise ConfigError("braking boundary_points must be >= 8 (the axis extremes)")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BrakingOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples)."""
        out = dict(data)
        out["speeds"] = tuple(out["speeds"])
        out["scales"] = tuple(out["scales"])
        out["directions"] = tuple(tuple(d) for d in out["directions"])
        return cls(**out)


@dataclass(frozen=True)
class CatchOptions:
    """The palette's catches and shifts: capture at the robot's own state (see
    :mod:`gracenav.policies.catches`).

    Parameters
    ----------
    speeds : tuple of float
        Speeds (m/s) of the catches of both lean classes, ascending; 0 is a rest hold.
    settled_speeds : tuple of float
        Further speeds (m/s) with a settled catch only: the settled class acts near
        walls, where a catch planned for a speed closer to the state's stops shorter.
    max_lean : float
        Largest planned body tilt of a catch or shift (rad).
    min_duration, max_duration : float
        Bounds of a catch's deceleration time (s).
    ramps : tuple of float
        Rise times (s) of the smooth trapezoidal decelerations
        (:class:`~gracenav.primitives.shape_planner.BrakeReference`) planned for each catch
        besides the nonic smooth step and the shortest-reach braking
        (:class:`~gracenav.primitives.shape_planner.ShortestBrakeReference`, one per torque
        share); the candidates are verified in the order of how far ahead their path
        reaches, and the first that verifies is kept.
    pushed_torque_shares, settled_torque_shares : tuple of float
        Largest planned torques of a class's shortest-reach and trapezoidal catches, as
        shares of the torque limit (one candidate per share, and per ramp and share):
        the rest is left to the feedback (a short ramp otherwise saturates the motor
        once a push's lean is corrected).
    max_candidates : int
        Candidates verified per size, shortest reach first.
    tail : float
        Rest held after a catch's deceleration and after a shift (s).
    scales : tuple of float
        Sizes S/G of a pushed catch's start domain, tried from the largest; the first
        that verifies is kept.
    settled_scales : tuple of float
        The same for a settled catch.
    headings : int
        Placements verified, evenly spaced over [0°, 180°) (180° is an exact symmetry).
    boundary_points : int
        Initial states on the surface of S per lean variant and placement.
    grid_divisions : int
        Catches end on the grid of spacing d / grid_divisions, anchored where the
        library's lattice is; shifts move between that grid and the lattice.
    pushed_outer : tuple of float
        D' extents of a catch verified with the lean a push leaves: position along and
        across the motion (m), velocity (m/s); the hybrid controller uses such a catch
        whatever the measured lean. Its S holds the flat output's position state
        (:attr:`MotionPolicy.flat_start`), so a push's lean variants start with the
        flat output, not the ball, on S's boundary.
    settled_outer : tuple of float
        The same for a catch verified with the lean within ``settled_lean`` of the plan's.
    settled_max_lean : float
        Largest planned body tilt of a settled catch (rad): shorter stops, as the lean
        left for feedback is not taken by a push.
    settled_lean : tuple of float
        Largest lean (rad) and lean rate (rad/s) deviation from the plan's of a settled
        catch (verified at the corners of that band, along the motion).
    shift_radius : float
        Largest shift (m): at least the distance from a grid point to the nearest
        point of the unhalved lattice (d/√2 = 0.354 m at d = 0.5 m), since rest
        trims on the other sub-lattices of a halved lattice cannot reach every goal.
    shift_scale : float
        S/G of a shift (S ⊇ G, so a shift placed at a catch's end contains its G).
    shift_outer : tuple of float
        Least D' position (m) and velocity (m/s) extents of a shift (round), verified
        from the plan lean and the settled band; D' is also at least 1.1 and 3 times S's
        (0.11 m at ``shift_scale`` 1.25).
    still_speeds : tuple of float
        Speeds (m/s) of the catches of the *still* class: verified from a small S
        (``still_scale``) with the lean within ``still_lean`` of the plan's, so that
        their D' (``still_outer``) is about half the settled one. They serve states
        whose lean is the plan's (starts, and the position states coverage counts),
        near walls.
    still_max_lean : float
        Largest planned body tilt of a still catch (rad): the tight band leaves the
        feedback little to correct.
    still_torque_shares : tuple of float
        Largest planned torques of the still class's shortest-reach and trapezoidal
        catches, as shares of the torque limit: a larger share than the settled
        class's leans the body back sooner, so the path reaches less far ahead.
    still_scale : float
        S and G of a still catch, as a share of the palette's G (in (0, 1]).
    still_outer : tuple of float
        D' position (m) and velocity (m/s) extents of a still catch (round); also at
        least 1.1 and 3 times S's. From the tight band the tracking error never grows
        beyond where it starts on S's boundary, so D' is S's floor (1.1 × 0.04 m).
    still_lean : tuple of float
        Largest lean (rad) and lean rate (rad/s) deviation from the plan's of a still
        catch or shift (verified at the corners of that band).
    still_shift_scale : float
        S/G of a still shift, at least ``still_scale`` (its S ⊇ a still catch's G); the
        same shifts, verified from that S and the still band, with D' ``still_shift_outer``.
    still_shift_outer : tuple of float
        Least D' position (m) and velocity (m/s) extents of a still shift (round):
        also just above S's floor (1.1 × 0.048 m), for the same reason.
    """

    speeds: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2)
    settled_speeds: tuple[float, ...] = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
    max_lean: float = math.radians(4.5)
    min_duration: float = 0.5
    max_duration: float = 6.0
    ramps: tuple[float, ...] = (0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
    pushed_torque_shares: tuple[float, ...] = (0.75, 0.65)
    settled_torque_shares: tuple[float, ...] = (0.8,)
    max_candidates: int = 4
    tail: float = 1.0
    scales: tuple[float, ...] = (1.5, 1.0)
    settled_scales: tuple[float, ...] = (1.0,)
    headings: int = 6
    boundary_points: int = 48
    grid_divisions: int = 16
    pushed_outer: tuple[float, float, float] = (0.24, 0.14, 1.0)
    settled_outer: tuple[float, float, float] = (0.10, 0.10, 0.5)
    settled_max_lean: float = math.radians(6.0)
    settled_lean: tuple[float, float] = (math.radians(0.5), math.radians(3.0))
    shift_radius: float = 0.375
    shift_scale: float = 1.25
    shift_outer: tuple[float, float] = (0.10, 0.5)
    still_speeds: tuple[float, ...] = (
        0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6,
    )  # fmt: skip
    still_max_lean: float = math.radians(7.5)
    still_torque_shares: tuple[float, ...] = (0.9, 0.8)
    still_scale: float = 0.5
    still_outer: tuple[float, float] = (0.044, 0.5)
    still_lean: tuple[float, float] = (math.radians(0.1), math.radians(0.5))
    still_shift_scale: float = 0.6
    still_shift_outer: tuple[float, float] = (0.053, 0.5)

    def __post_init__(self) -> None:
        for name in (
            "speeds",
            "settled_speeds",
            "ramps",
            "pushed_torque_shares",
            "settled_torque_shares",
            "scales",
            "settled_scales",
            "pushed_outer",
            "settled_outer",
            "settled_lean",
            "shift_outer",
            "still_speeds",
            "still_torque_shares",
            "still_outer",
            "still_lean",
            "still_shift_outer",
        ):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if not self.speeds or any(v < 0 for v in self.speeds):
            raise ConfigError(f"catch speeds must be >= 0, got {self.speeds}")
        if any(r <= 0 for r in self.ramps):
            raise ConfigError(f"catch ramps must be > 0 s, got {self.ramps}")
        for lean in (self.max_lean, self.settled_max_lean, self.still_max_lean):
            if not 0 < lean < math.pi / 2:
                raise ConfigError(f"catch plan leans must be in (0, π/2) rad, got {lean}")
        for shares in (
            self.pushed_torque_shares,
            self.settled_torque_shares,
            self.still_torque_shares,
        ):
            if not all(0 < f <= 1 for f in shares):
                raise ConfigError(f"catch torque shares must be in (0, 1], got {shares}")
        if any(v <= 0 for v in self.settled_speeds):
            raise ConfigError(f"catch settled_speeds must be > 0, got {self.settled_speeds}")
        if self.max_candidates < 1:
            raise ConfigError(f"catch max_candidates must be >= 1, got {self.max_candidates}")
        for scales in (self.scales, self.settled_scales):
            if not scales or any(s < 1 for s in scales):
                raise ConfigError(f"catch scales must be >= 1 (S ⊇ G), got {scales}")
        if self.headings < 1 or self.grid_divisions < 1 or self.boundary_points < 1:
            raise ConfigError("catch headings, grid_divisions and boundary_points must be >= 1")
        for outer in (self.pushed_outer, self.settled_outer):
            if len(outer) != 3 or not 0 < outer[1] <= outer[0] or not outer[2] > 0:
                raise ConfigError(
                    f"catch outer extents must be (along, across <= along, velocity) > 0, "
                    f"got {outer}"
                )
        if not self.shift_scale >= 1:
            raise ConfigError(f"shift_scale must be >= 1 (S ⊇ G), got {self.shift_scale}")
        if any(v < 0 for v in self.still_speeds):
            raise ConfigError(f"catch still_speeds must be >= 0, got {self.still_speeds}")
        if not 0 < self.still_scale <= 1 or not self.still_shift_scale >= self.still_scale:
            raise ConfigError(
                "catch still_scale must be in (0, 1] and still_shift_scale at least it "
                f"(a still shift's S ⊇ a still catch's G), got {self.still_scale} and "
                f"{self.still_shift_scale}"
            )
        for pair in (self.still_outer, self.still_lean, self.still_shift_outer):
            if len(pair) != 2 or not all(v > 0 for v in pair):
                raise ConfigError(
                    f"catch still extents and band must be two values > 0, got {pair}"
                )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CatchOptions:
        """Inverse of :func:`dataclasses.asdict` (lists become tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})  # type: ignore[arg-type]


@dataclass(frozen=True)
class PushLeanTable:
    """Lean and lean rate a push leaves, tabulated by the ball speed it causes.

    The robot at rest, regulated to its position, is pushed along +x; ``speed``,
    ``lean`` and ``lean_rate`` are sampled ``times`` after the impulse, one row per
    impulse. Along the push direction: lean φ (rad, positive leaning forward),
    lean rate (rad/s).

    Attributes
    ----------
    times : ndarray, shape (K,)
    speed, lean, lean_rate : ndarray, shape (J, K)
    """

    times: FloatArray
    speed: FloatArray
    lean: FloatArray
    lean_rate: FloatArray

    def lean_at(
        self, k: int, speed: ArrayLike, *, flat_length: float | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Lean (rad) and lean rate (rad/s) along the motion ``times[k]`` after a push,
        for ball speeds ``speed`` (m/s): linear in speed through (0, 0, 0), held beyond
        the fastest entry. With ``flat_length`` L (m), ``speed`` is that of the flat
        output instead, the ball's plus L times the lean rate."""
        v = np.asarray(speed, dtype=float)
        table = self.speed[:, k]
        if flat_length is not None:
            table = table + flat_length * self.lean_rate[:, k]
        order = np.argsort(table)
        sv = np.concatenate([[0.0], table[order]])
        lean = np.concatenate([[0.0], self.lean[order, k]])
        rate = np.concatenate([[0.0], self.lean_rate[order, k]])
        return np.interp(v, sv, lean), np.interp(v, sv, rate)


def push_lean_table(
    gains: ControllerGains,
    impulses: Sequence[float],
    times: Sequence[float],
    *,
    params: BallbotParams | None = None,
) -> PushLeanTable:
    """Push the regulated robot at rest along +x with each impulse (N s) and sample its
    speed, lean and lean rate ``times`` (s) after the push (see :class:`PushLeanTable`).
    """
    from gracenav.sim import Push, simulate

    plant = params if params is not None else gains.params
    r = gains.params.ball_radius
    dt = 1.0 / CONTROL_RATE
    t = np.asarray(times, dtype=float)
    ticks = np.round(t / dt).astype(int)
    ref = Reference.hold((0.0, 0.0), float(t.max(initial=0.0)) + 0.25, params=gains.params)
    rows = []
    for imp in impulses:
        res = simulate(np.zeros(8), ref, gains, params=plant, disturbances=[Push(0.0, (imp, 0.0))])
        ps = position_state(res.states, r)
        rows.append((ps[ticks, 2], res.states[ticks, 2], res.states[ticks, 6]))
    speed, lean, rate = (np.array([row[i] for row in rows]) for i in range(3))
    return PushLeanTable(t, speed, lean, rate)


@dataclass(frozen=True)
class VerificationOptions:
    """Options of policy verification and sizing.

    Parameters
    ----------
    boundary_points : int
        Initial states on the surface of S (>= 64 recommended; the first 8 are the axis
        extremes).
    goal_position_extent : float
        Position extent e_p of the goal domain G shared by every policy (m); its
        velocity extent follows from :func:`domain_shape`.
    outer_position_factor, outer_velocity_factor : float
        D'(t) extents over D(t) extents.
    lean_limit : float
        The balancing controller's domain: largest |φ_x|, |φ_y| allowed (rad).
    max_scale : float
        Upper end of the bisection on the start domain's size S/G.
    bisection_steps : int
        Bisection iterations on S's size.
    shape_horizon : float
        Time (s) over which :func:`domain_shape` maximises the contraction: the
        shortest trim.
    scale_ladder : tuple of float
        Larger start domain sizes S/G, ascending, each > ``max_scale``, at which a
        policy is verified again after its bisection (:func:`scaled_variants`).
        Instantiation places the largest verified size whose swept D' fits the map:
        large domains in open space, the bisected size near walls.
    regulator : RegulatorOptions or None
        The palette's capture regulators (None: none).
    braking : BrakingOptions or None
        The palette's braking maneuvers (None, the default: none; see
        :mod:`gracenav.primitives.braking` for what they add and what they cost).
    catch : CatchOptions or None
        The palette's catches and shifts, placed at the robot's own state
        (:mod:`gracenav.policies.catches`); None: none.
    """

    boundary_points: int = 64
    goal_position_extent: float = 0.08
    outer_position_factor: float = 1.6
    outer_velocity_factor: float = 3.2
    lean_limit: float = float(np.deg2rad(8.0))
    max_scale: float = 2.0
    bisection_steps: int = 6
    shape_horizon: float = 1.0
    scale_ladder: tuple[float, ...] = (3.0, 4.0, 6.0, 8.0)
    regulator: RegulatorOptions | None = field(default_factory=RegulatorOptions)
    braking: BrakingOptions | None = None
    catch: CatchOptions | None = field(default_factory=CatchOptions)

    def __post_init__(self) -> None:
        if isinstance(self.regulator, dict):
            object.__setattr__(self, "regulator", RegulatorOptions.from_dict(self.regulator))
        if isinstance(self.braking, dict):
            object.__setattr__(self, "braking", BrakingOptions.from_dict(self.braking))
        if isinstance(self.catch, dict):
            object.__setattr__(self, "catch", CatchOptions.from_dict(self.catch))
        ladder = tuple(float(v) for v in self.scale_ladder)
        object.__setattr__(self, "scale_ladder", ladder)
        if any(not b > a for a, b in zip((self.max_scale, *ladder), ladder, strict=False)):
            raise ConfigError(
                f"scale_ladder must ascend from above max_scale {self.max_scale:g}, got {ladder}"
            )
        if self.boundary_points < 8:
            raise ConfigError("boundary_points must be >= 8 (the axis extremes)")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("outer domain factors must be >= 1 (D(t) ⊂ D'(t))")
        if not self.lean_limit > 0:
            raise ConfigError("lean_limit must be positive")
        if not self.goal_position_extent > 0:
            raise ConfigError("goal_position_extent must be positive")
        if not self.max_scale >= 1:
            raise ConfigError("max_scale must be >= 1 (S ⊇ G)")


@dataclass(frozen=True)
class DomainShape:
    """The shape shared by every domain: velocity extent per position extent (1/s) and
    position-velocity correlation r."""

    velocity_per_position: float
    correlation: float

    def radii(self, position_extent: float) -> DomainRadii:
        """Extents of the domain of this shape with the given position extent (m)."""
        return DomainRadii(position_extent, position_extent * self.velocity_per_position)


def domain_shape(gains: ControllerGains, *, horizon: float = 1.0) -> DomainShape:
    """The domain shape the closed loop contracts the most over ``horizon`` (s).

    For each plane the linearised closed loop of the Fig. 2 cascade maps an initial
    position state error (lean at its plan) to the error at ``horizon`` by a 2 × 2
    matrix Φ; the ellipse {eᵀ P e <= 1} minimising ‖P^½ Φ P^-½‖₂ (the worst-case
    shrink factor) is found by Nelder–Mead over the normalised P, for the worse of
    the two planes.
    """
    import scipy.linalg
    import scipy.optimize

    from gracenav.control import planar_to_position_coordinates
    from gracenav.model.planar import PlanarBallbot

    params = gains.params
    t = planar_to_position_coordinates(params.ball_radius)
    phis = []
    for i, plane in enumerate(("x", "y")):
        a, b = PlanarBallbot(params, plane=plane).linearize()  # type: ignore[arg-type]
        acl = t @ a @ np.linalg.inv(t) - (t @ b) @ gains.lqr[i][None, :]
        phis.append(scipy.linalg.expm(acl * horizon)[np.ix_([0, 2], [0, 2])])

    def unit(z: FloatArray) -> FloatArray:
        return np.array([[1.0, z[0]], [z[0], np.exp(z[1])]])

    def shrink(z: FloatArray) -> float:
        p = unit(z)
        if np.linalg.eigvalsh(p)[0] <= 1e-9:
            return 1e6
        ell = np.linalg.cholesky(p)
        return max(float(np.linalg.norm(ell.T @ phi @ np.linalg.inv(ell.T), 2)) for phi in phis)

    grid = [np.array([bb, lc]) for bb in np.linspace(-2, 2, 21) for lc in np.linspace(-3, 3, 13)]
    start = min(grid, key=shrink)
    best = scipy.optimize.minimize(shrink, start, method="Nelder-Mead", options={"xatol": 1e-6})
    cov = np.linalg.inv(unit(best.x))
    return DomainShape(
        velocity_per_position=float(np.sqrt(cov[1, 1] / cov[0, 0])),
        correlation=float(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])),
    )


@dataclass(frozen=True)
class VerificationReport:
    """Outcome of verifying one policy from the surface of its start domain.

    Attributes
    ----------
    passed : bool
    runs : int
        Number of closed-loop runs.
    max_outer_value : float
        Largest (p − c)ᵀ P (p − c) of D'(t) over all runs and ticks (<= 1 passes).
    max_goal_value : float
        Largest value of G at t_f (<= 1 passes).
    max_lean : float
        Largest |lean| (rad).
    max_torque : float
        Largest |τ| commanded (N m).
    saturated_runs : int
        Runs whose torque saturated.
    """

    passed: bool
    runs: int
    max_outer_value: float
    max_goal_value: float
    max_lean: float
    max_torque: float
    saturated_runs: int


@dataclass(frozen=True)
class MotionPolicy:
    """A motion policy Φ = (σ(t), φ(t), D(t)) with its outer domain D'(t).

    Attributes
    ----------
    primitive : SampledPrimitive
        σ(t), in the policy's own frame (starting at the origin).
    gains : ControllerGains
        φ(t): the Fig. 2 cascade (time-invariant gains shared by all policies).
    start_radii, goal_radii : DomainRadii
        Sizes of S and G.
    outer_factors : tuple of float
        D'(t) extents over D(t) extents, (position, velocity).
    correlation : float
        Position-velocity correlation r of every domain (see :func:`domain_shape`).
    report : VerificationReport or None
        Verification outcome, when verified.
    label : str
        Name of a larger-domain variant of the palette's policy for the same primitive
        (see :func:`scaled_variants`), e.g. ``"rest[S=4G]"``, or of a capture
        regulator (:func:`regulator_label`); empty for the policy sized by bisection,
        which is named after its primitive.
    capture : bool
        A capture regulator (:class:`RegulatorOptions`): S has its own correlation
        ``start_correlation`` (and its own e_v/e_p), D'(t) does not shrink (uncorrelated,
        ``outer_factors`` × the extents of S, centred on the reference), and the hybrid
        controller starts it only when no other policy's S contains the state.
    start_correlation : float or None
        Correlation of S when it differs from the other domains' (capture regulators).
    outer_cross : float or None
        For a capture policy whose reference starts moving: the position extent (m) of
        D' across the start velocity; the outer factor then gives the extent along it
        (an ellipse aligned with the motion, rotating with the placement). None: round.
    flat_start : bool
        S holds the position state of the flat output rather than the ball's: the ball
        position state plus L times the deviation of the lean and lean rate from the
        plan's (:func:`flat_position_state`). After a push the ball runs ahead of the
        body and back while the flat output, whose acceleration is κ φ in the
        linearised model, moves on smoothly (its speed swings 4–5 times less);
        verification then starts each lean variant with the flat output on S's
        boundary, and the hybrid controller tests the same state.
    """

    primitive: SampledPrimitive
    gains: ControllerGains
    start_radii: DomainRadii
    goal_radii: DomainRadii
    outer_factors: tuple[float, float] = (1.6, 3.2)
    correlation: float = 0.0
    report: VerificationReport | None = None
    label: str = ""
    capture: bool = False
    start_correlation: float | None = None
    outer_cross: float | None = None
    flat_start: bool = False

    @property
    def name(self) -> str:
        """The label of a scaled variant, else the primitive's name."""
        return self.label or self.primitive.name

    @property
    def scale(self) -> float:
        """Start domain size over goal domain size, S/G (>= 1)."""
        return self.start_radii.position / self.goal_radii.position

    @property
    def duration(self) -> float:
        """t_f (s)."""
        return self.primitive.duration

    def radii(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Position (m) and velocity (m/s) extents of D(t): geometric from S at 0 to G
        at t_f."""
        s = np.clip(np.asarray(t, dtype=float) / self.duration, 0.0, 1.0)
        rp = self.start_radii.position * (self.goal_radii.position / self.start_radii.position) ** s
        rv = self.start_radii.velocity * (self.goal_radii.velocity / self.start_radii.velocity) ** s
        return rp, rv

    @property
    def start_shape_correlation(self) -> float:
        """Correlation of S."""
        return self.correlation if self.start_correlation is None else self.start_correlation

    def domain_correlation(self, t: float) -> float:
        """Correlation of D(t): the shared one, or for a capture regulator linear in t
        from that of S to that of G."""
        s = min(max(float(t) / self.duration, 0.0), 1.0)
        return (1.0 - s) * self.start_shape_correlation + s * self.correlation

    def domain(self, t: float) -> EllipsoidalDomain:
        """D(t), in the policy's own frame."""
        rp, rv = self.radii(t)
        return EllipsoidalDomain(
            self.primitive.position_state(t),
            correlated_shape(float(rp), float(rv), self.domain_correlation(t)),
        )

    def outer_extents(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Position (m) and velocity (m/s) extents of D'(t): the outer factors times
        those of D(t), or for a capture regulator times those of S at every t."""
        cp, cv = self.outer_factors
        if self.capture:
            shape = np.shape(np.asarray(t, dtype=float))
            return (
                np.full(shape, self.start_radii.position * cp),
                np.full(shape, self.start_radii.velocity * cv),
            )
        rp, rv = self.radii(t)
        return np.asarray(rp * cp, dtype=float), np.asarray(rv * cv, dtype=float)

    def _outer_shape(self, position_extent: float, velocity_extent: float) -> FloatArray:
        """Shape matrix of D' with these extents (along the motion, for ``outer_cross``)."""
        corr = 0.0 if self.capture else self.correlation
        shape = correlated_shape(position_extent, velocity_extent, corr)
        v0 = self.primitive.start_velocity
        speed = float(np.hypot(*v0))
        if self.outer_cross is not None and speed > 0:
            u = np.asarray(v0, dtype=float) / speed
            w = np.array([-u[1], u[0]])
            shape[:2, :2] = np.outer(u, u) / position_extent**2 + np.outer(w, w) / (
                self.outer_cross**2
            )
        return shape

    def outer_domain(self, t: float) -> EllipsoidalDomain:
        """D'(t) ⊃ D(t), in the policy's own frame."""
        rp, rv = self.outer_extents(t)
        return EllipsoidalDomain(
            self.primitive.position_state(t), self._outer_shape(float(rp), float(rv))
        )

    @property
    def start_domain(self) -> EllipsoidalDomain:
        """S = D(0)."""
        return self.domain(0.0)

    @property
    def goal_domain(self) -> EllipsoidalDomain:
        """G = D(t_f)."""
        return self.domain(self.duration)

    def outer_monitor(self) -> tuple[FloatArray, FloatArray]:
        """D'(t) at every control tick for the compiled loop: centres (T+1, 4) and
        shape matrices (T+1, 4, 4), in the policy's own frame."""
        t = np.arange(self.primitive.num_ticks + 1) * self.primitive.dt
        rp, rv = self.outer_extents(t)
        # All D'(t) are scaled copies of one shape: P(t) = P(0) · (ρ(0)/ρ(t))².
        base = self._outer_shape(float(rp[0]), float(rv[0]))
        shapes = base[None] * ((rp[0] / rp) ** 2)[:, None, None]
        return np.ascontiguousarray(self.primitive.position[:, :4]), shapes

    def with_start_radii(self, radii: DomainRadii) -> MotionPolicy:
        """A copy with another start domain size (and no verification report)."""
        return replace(self, start_radii=radii, report=None)


def flat_position_state(
    position_state: ArrayLike, lean: ArrayLike, lean_rate: ArrayLike, params: BallbotParams
) -> FloatArray:
    """The flat output's position state (y, ẏ) = (x + L φ, ẋ + L φ̇) per axis, for
    ball position states (..., 4) and leans and lean rates (..., 2) measured from the
    plan's (rad, rad/s); L from :func:`gracenav.primitives.shape_planner.flat_output_lengths`."""
    from gracenav.primitives.shape_planner import flat_output_lengths

    length = flat_output_lengths(params)
    p = np.array(position_state, dtype=float)
    p[..., 0:2] += length * np.asarray(lean, dtype=float)
    p[..., 2:4] += length * np.asarray(lean_rate, dtype=float)
    return p


def capture_point(flat_state: ArrayLike, params: BallbotParams) -> FloatArray:
    """The instantaneous capture point ξ = y + ẏ/ω (m) per axis of flat-output position
    states (..., 4) (:func:`flat_position_state`), shape (..., 2).

    For the linearised model ÿ = κ φ (:func:`~gracenav.primitives.shape_planner.flat_output_gain`)
    and y − x = L φ give ÿ = ω² (y − x), ω = √(κ/L), with x the ball; so ξ̇ = ω (ξ − x).
    A motion that comes to rest keeps ξ bounded, which needs
    ξ(0) = ω ∫₀^∞ e^(−ωt) x(t) dt: a weighted mean of the ball's positions to come.
    Whatever the controller, the ball's path from a state therefore reaches at least
    as far as its capture point along every direction (ξ lies in the path's convex
    hull): a bound on how near an obstacle a moving robot can stop.
    """
    from gracenav.primitives.shape_planner import flat_output_gain, flat_output_lengths

    omega = np.sqrt(flat_output_gain(params) / flat_output_lengths(params))
    y = np.asarray(flat_state, dtype=float)
    return np.asarray(y[..., 0:2] + y[..., 2:4] / omega, dtype=float)


def verify_policy(
    policy: MotionPolicy,
    options: VerificationOptions | None = None,
    *,
    params: BallbotParams | None = None,
    push_leans: PushLeanTable | None = None,
    boundary_points: int | None = None,
) -> VerificationReport:
    """Verify a policy on the 3D model from points on the surface of its start domain.

    Parameters
    ----------
    policy : MotionPolicy
    options : VerificationOptions, optional
    params : BallbotParams, optional
        Plant parameters (default: the controller's nominal ones).
    push_leans : PushLeanTable, optional
        Also start every boundary point with the lean and lean rate a push leaves at
        each of the table's times, at the point's speed and along its velocity (added
        to the reference's), not only with the reference's.
    boundary_points : int, optional
        Default ``options.boundary_points``.

    Returns
    -------
    VerificationReport
    """
    options = options if options is not None else VerificationOptions()
    prim = policy.primitive
    u = sphere_points(boundary_points or options.boundary_points)
    # Map unit-sphere points onto the surface of S: p = c + L u with L Lᵀ = P⁻¹.
    ell = np.linalg.cholesky(np.linalg.inv(policy.start_domain.shape_matrix))
    p0 = prim.position[0, :4] + u @ ell.T
    x_plan = prim.states[0]
    lean = x_plan[2:4]
    rate = x_plan[6:8]
    r = policy.gains.params.ball_radius
    x0 = state_from_position(p0, r, lean=lean, lean_rate=rate)
    if push_leans is not None:
        speed = np.hypot(p0[:, 2], p0[:, 3])
        unit = p0[:, 2:4] / np.maximum(speed, 1e-12)[:, None]
        variants = [x0]
        flat_length = None
        if policy.flat_start:
            from gracenav.primitives.shape_planner import flat_output_lengths

            flat_length = float(np.mean(flat_output_lengths(policy.gains.params)))
        for k in range(push_leans.times.size):
            dl, dr = push_leans.lean_at(k, speed, flat_length=flat_length)
            d_lean, d_rate = unit * dl[:, None], unit * dr[:, None]
            ball = p0
            if policy.flat_start:  # the flat output on S's boundary, the ball off it
                ball = flat_position_state(p0, -d_lean, -d_rate, policy.gains.params)
            variants.append(
                state_from_position(ball, r, lean=lean + d_lean, lean_rate=rate + d_rate)
            )
        x0 = np.concatenate(variants)
    res = simulate_batch(
        x0,
        prim.reference(),
        policy.gains,
        params=params,
        monitor=policy.outer_monitor(),
    )
    final_p = position_state(res.final_states, r)
    goal_values = policy.goal_domain.value(final_p)
    saturated = int(np.count_nonzero(res.saturated_ticks))
    report = VerificationReport(
        passed=bool(
            np.all(res.max_domain_value <= 1.0)
            and np.all(goal_values <= 1.0)
            and np.all(res.max_lean <= options.lean_limit)
            and saturated == 0
        ),
        runs=int(x0.shape[0]),
        max_outer_value=float(np.max(res.max_domain_value)),
        max_goal_value=float(np.max(goal_values)),
        max_lean=float(np.max(res.max_lean)),
        max_torque=float(np.max(res.max_torque)),
        saturated_runs=saturated,
    )
    return report


def combined_report(*reports: VerificationReport) -> VerificationReport:
    """The combined report of several verifications of one policy (passes only if all
    pass; worst values, total runs)."""
    return VerificationReport(
        passed=all(r.passed for r in reports),
        runs=sum(r.runs for r in reports),
        max_outer_value=max(r.max_outer_value for r in reports),
        max_goal_value=max(r.max_goal_value for r in reports),
        max_lean=max(r.max_lean for r in reports),
        max_torque=max(r.max_torque for r in reports),
        saturated_runs=sum(r.saturated_runs for r in reports),
    )


def verify_placements(
    policy: MotionPolicy,
    options: VerificationOptions | None = None,
    *,
    params: BallbotParams | None = None,
    push_leans: PushLeanTable | None = None,
    boundary_points: int | None = None,
) -> VerificationReport:
    """Verify a policy at every placement instantiation uses (``push_leans`` and
    ``boundary_points`` as in :func:`verify_policy`).

    Instantiation places policies at 0°, 90°, 180° and 270°; 180° is an exact
    symmetry of the 3D model, so the 0° and 90° placements cover all four. Returns
    the combined report (passes only if both pass).
    """
    reports = [
        verify_policy(
            replace(policy, primitive=policy.primitive.rotated(k)),
            options,
            params=params,
            push_leans=push_leans,
            boundary_points=boundary_points,
        )
        for k in (0, 1)
    ]
    return combined_report(*reports)


def regulator_label(name: str, position_extent: float) -> str:
    """Name of the capture regulator of primitive ``name`` whose S has position extent
    ``position_extent`` (m), e.g. ``"regulate[ep=0.55m]"``."""
    return f"{name}[ep={position_extent:g}m]"


def regulator_policies(
    primitive: SampledPrimitive,
    gains: ControllerGains,
    options: VerificationOptions,
    goal: DomainRadii,
    goal_correlation: float,
    *,
    push_leans: PushLeanTable | None = None,
    progress: Callable[[], None] | None = None,
) -> tuple[MotionPolicy, ...]:
    """The capture regulators of ``options.regulator``, each verified at both placements.

    Parameters
    ----------
    primitive : SampledPrimitive
        A rest trim lasting the regulator's duration.
    gains : ControllerGains
    options : VerificationOptions
    goal : DomainRadii
        The palette's G (extents) and ``goal_correlation`` its correlation.
    push_leans : PushLeanTable, optional
        Default: :func:`push_lean_table` of the regulator options.
    progress : callable, optional
        Called after each size.

    Returns
    -------
    tuple of MotionPolicy
        One per size, ascending, each with its report (passed or not).
    """
    reg = options.regulator
    if reg is None:
        return ()
    if push_leans is None:
        push_leans = push_lean_table(gains, reg.push_impulses, reg.push_times)
    out = []
    for extent in reg.position_extents:
        pol = MotionPolicy(
            primitive,
            gains,
            reg.start_radii(extent),
            goal,
            (reg.outer_position_factor, reg.outer_velocity_factor),
            goal_correlation,
            label=regulator_label(primitive.name, extent),
            capture=True,
            start_correlation=reg.correlation,
        )
        report = verify_placements(
            pol, options, push_leans=push_leans, boundary_points=reg.boundary_points
        )
        out.append(replace(pol, report=report))
        if progress is not None:
            progress()
    return tuple(out)


def size_policy(
    primitive: SampledPrimitive,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    *,
    shape: DomainShape | None = None,
    progress: Callable[[], None] | None = None,
) -> MotionPolicy:
    """Build the policy of ``primitive`` with the largest start domain that verifies.

    Bisection on the scale S/G between 1 and ``options.max_scale``.

    Parameters
    ----------
    primitive : SampledPrimitive
    gains : ControllerGains, optional
    options : VerificationOptions, optional
    shape : DomainShape, optional
        Default: :func:`domain_shape` of ``gains``.
    progress : callable, optional
        Called after each verification.

    Returns
    -------
    MotionPolicy
        With ``report.passed`` False if even S = G fails.
    """
    options = options if options is not None else VerificationOptions()
    gains = gains if gains is not None else design_gains()
    shape = shape if shape is not None else domain_shape(gains, horizon=options.shape_horizon)
    goal = shape.radii(options.goal_position_extent)
    factors = (options.outer_position_factor, options.outer_velocity_factor)

    def attempt(scale: float) -> MotionPolicy:
        pol = MotionPolicy(primitive, gains, goal.scaled(scale), goal, factors, shape.correlation)
        report = verify_placements(pol, options)
        if progress is not None:
            progress()
        return replace(pol, report=report)

    best = attempt(1.0)
    if best.report is None or not best.report.passed:
        return best
    top = attempt(options.max_scale)
    if top.report is not None and top.report.passed:
        return top
    lo, hi = 1.0, options.max_scale
    for _ in range(options.bisection_steps):
        mid = 0.5 * (lo + hi)
        cand = attempt(mid)
        if cand.report is not None and cand.report.passed:
            best, lo = cand, mid
        else:
            hi = mid
    return best


def variant_label(name: str, scale: float) -> str:
    """Name of the variant of policy ``name`` whose start domain is ``scale`` × G."""
    return f"{name}[S={scale:g}G]"


def scaled_variants(
    policy: MotionPolicy,
    options: VerificationOptions | None = None,
    *,
    progress: Callable[[], None] | None = None,
) -> tuple[MotionPolicy, ...]:
    """Larger-domain variants of a verified policy: the paper's scaled domains (Sec. VI).

    The start domain is enlarged to each size S = s·G of ``options.scale_ladder``
    above the policy's own, keeping G (so every graceful connection G₁ ⊂ S₂ still
    holds), and each is verified at both placements like the policy itself. The
    ladder stops at the first size that fails.

    Returns
    -------
    tuple of MotionPolicy
        The verified variants, ascending in size, labelled by :func:`variant_label`.
    """
    options = options if options is not None else VerificationOptions()
    out: list[MotionPolicy] = []
    for scale in options.scale_ladder:
        if scale <= policy.scale * (1 + 1e-12):
            continue
        cand = replace(
            policy,
            start_radii=policy.goal_radii.scaled(scale),
            report=None,
            label=variant_label(policy.primitive.name, scale),
        )
        report = verify_placements(cand, options)
        if progress is not None:
            progress()
        if not report.passed:
            break
        out.append(replace(cand, report=report))
    return tuple(out)


def rotate_pairs(a: ArrayLike, k: int) -> FloatArray:
    """Rotate every consecutive (x, y) pair of the last axis of ``a`` by k·90° (exact).

    Model states [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y], torques [τ_x, τ_y] and
    position states [x, y, ẋ, ẏ, (ẍ, ÿ)] all consist of such pairs.
    """
    arr = np.asarray(a, dtype=np.float64)
    k %= 4
    c = (1.0, 0.0, -1.0, 0.0)[k]
    s = (0.0, 1.0, 0.0, -1.0)[k]
    rot = np.array([[c, -s], [s, c]])
    pairs = arr.reshape(*arr.shape[:-1], arr.shape[-1] // 2, 2)
    out: FloatArray = (pairs @ rot.T).reshape(arr.shape)
    return out


def rotate_pairs_by(a: ArrayLike, angle: float) -> FloatArray:
    """Rotate every consecutive (x, y) pair of the last axis of ``a`` by ``angle`` (rad),
    counter-clockwise: :func:`rotate_pairs` for any angle. For model states the lean
    pair is rotated like a vector, which is exact for the position state and first
    order in the lean (see :meth:`SampledPrimitive.rotated`)."""
    arr = np.asarray(a, dtype=np.float64)
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    pairs = arr.reshape(*arr.shape[:-1], arr.shape[-1] // 2, 2)
    out: FloatArray = (pairs @ rot.T).reshape(arr.shape)
    return out


def instantiated_reference(
    primitive: SampledPrimitive, k: int, origin: ArrayLike, radius: float
) -> tuple[Reference, FloatArray]:
    """A primitive placed on the map: rotated by k·90° about its start, start moved to
    ``origin`` (x, y) (m).

    Returns
    -------
    Reference
        World-frame reference states and feed-forward torques at the ticks.
    position : ndarray, shape (T + 1, 6)
        World-frame x, y, ẋ, ẏ, ẍ, ÿ of the reference.
    """
    o = np.asarray(origin, dtype=np.float64)
    states = rotate_pairs(primitive.states, k)
    states[:, 0:2] += o / radius
    position = rotate_pairs(primitive.position, k)
    position[:, 0:2] += o
    return Reference(states, rotate_pairs(primitive.inputs, k), primitive.dt), position


@dataclass(frozen=True)
class SwitchJump:
    """Commanded torque at a graceful switch from ``first`` to ``second`` (rotated by
    ``rotation``·90°): the jump at the switch tick and, for scale, the largest
    tick-to-tick change elsewhere in the run (N m)."""

    first: str
    second: str
    rotation: int
    jump: float
    largest_other_step: float


def switch_torque_jumps(
    policies: Sequence[MotionPolicy], *, params: BallbotParams | None = None
) -> list[SwitchJump]:
    """Simulate every connecting pair Φ₁ ⪰ Φ₂ (σ₁(t_f) = σ₂(0) through acceleration,
    after rotating Φ₂) from the centre of S₁ and measure the commanded torque jump at
    the switch (paper Sec. III-C (iii): φ₁(t_f1) = φ₂(0) makes it continuous)."""
    from gracenav.sim import simulate

    out = []
    for a in policies:
        end = a.primitive.position[-1]
        for b in policies:
            if b.gains is not a.gains and not np.array_equal(b.gains.lqr, a.gains.lqr):
                continue
            for k in range(4):
                start = rotate_pairs(b.primitive.position[0], k)
                if not np.allclose(start[2:], end[2:], rtol=0.0, atol=1e-9):
                    continue
                r = a.gains.params.ball_radius
                ref_b, _ = instantiated_reference(b.primitive, k, end[:2], r)
                ref_a = a.primitive.reference()
                joined = Reference(
                    np.concatenate([ref_a.states, ref_b.states[1:]]),
                    np.concatenate([ref_a.inputs, ref_b.inputs[1:]]),
                    ref_a.dt,
                )
                res = simulate(ref_a.states[0], joined, a.gains, params=params)
                steps = np.max(np.abs(np.diff(res.inputs, axis=0)), axis=1)
                n = a.primitive.num_ticks
                jump = float(steps[n]) if n < steps.size else 0.0
                other = float(np.max(np.delete(steps, n))) if steps.size > 1 else 0.0
                out.append(SwitchJump(a.name, b.name, k, jump, other))
    return out


def run_policy(
    policy: MotionPolicy,
    p0: ArrayLike,
    plant: PlantKind = "model3d",
    *,
    params: BallbotParams | None = None,
    disturbances: Sequence[Disturbance] = (),
    options: SimulationOptions | None = None,
) -> SimulationResult:
    """Simulate one motion policy (in its own frame) from the position state ``p0``.

    The body starts with the lean and lean rate its primitive plans at t = 0 (as in
    verification) and the policy's control law tracks its primitive for its duration;
    D'(t) is monitored (``max_domain_value``) but the run does not stop on exit.

    Parameters
    ----------
    policy : MotionPolicy
    p0 : array_like, shape (4,)
        Initial position state (x, y, ẋ, ẏ) (m, m/s).
    plant : {"model3d", "mujoco"}
    params : BallbotParams, optional
        Plant parameters (default: the policy's nominal ones).
    disturbances : sequence of Disturbance
    options : SimulationOptions, optional

    Returns
    -------
    SimulationResult
        ``time`` (N,), ``states`` (N, 8), ``position_state`` (N, 4), ...
    """
    p = np.asarray(p0, dtype=float)
    if p.shape != (4,):
        raise ConfigError(f"p0 must be a position state (x, y, xdot, ydot), got shape {p.shape}")
    prim = policy.primitive
    x0 = state_from_position(
        p, policy.gains.params.ball_radius, lean=prim.states[0, 2:4], lean_rate=prim.states[0, 6:8]
    )
    return simulate(
        x0,
        prim.reference(),
        policy.gains,
        params=params,
        plant=plant,
        disturbances=disturbances,
        options=options,
        monitor=policy.outer_monitor(),
    )
