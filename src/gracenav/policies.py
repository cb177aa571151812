"""Motion policies, their verified domains, and the motion policy palette.

A motion policy Φ (paper Sec. III-B) is a motion primitive σ(t), the
time-varying tracking control law φ(t) of the Fig. 2 architecture, and a
time-varying domain D(t) with an outer domain D'(t) ⊃ D(t), all in the 4D
position state space (x, y, ẋ, ẏ). S = D(0) is the start domain and
G = D(t_f) the goal domain.

Domains here are round in position and in velocity (shape matrix
diag(1/ρ_p², 1/ρ_p², 1/ρ_v², 1/ρ_v²)), so they are invariant under the 90°
rotations of instantiation. Every policy of a palette shares one goal size
G (``VerificationOptions.goal_radii``), and its start size S >= G is the
largest that verification on the 3D model accepts (bisection on a scale).
D(t) shrinks geometrically from S to G; D'(t) is D(t) enlarged by fixed
factors in position and velocity. Because S >= G for every verified policy,
condition (i) of the gracefully prepares relation, G₁ ⊂ S₂, holds for every
pair whose primitives connect.

Verification (paper Sec. III-B) simulates the closed loop on the 3D model
from points on the surface of S (every axis extreme plus a quasi-uniform set;
the shape at its planned value) and requires for every run: inside D'(t) at
every control tick, inside G at t_f, |lean| within the balancing controller's
domain, and torque within the limit (no saturation).
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.control import ControllerGains, design_gains
from gracenav.domains import EllipsoidalDomain, isotropic_shape, sphere_points
from gracenav.errors import ConfigError
from gracenav.simulate import (
    DEFAULT_CONTROL_RATE,
    Reference,
    simulate_batch,
    state_from_position,
)

__all__ = [
    "DomainRadii",
    "MotionPolicy",
    "PrimitiveKind",
    "SampledPrimitive",
    "VerificationOptions",
    "VerificationReport",
    "size_policy",
    "verify_policy",
]

FloatArray = NDArray[np.float64]


class _Sample(Protocol):
    states: FloatArray
    inputs: FloatArray
    position: FloatArray


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
    def sample(self, timepts: FloatArray) -> _Sample: ...


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
    inputs: FloatArray
    position: FloatArray

    def __post_init__(self) -> None:
        n = self.states.shape[0]
        if (
            self.states.shape != (n, 8)
            or self.inputs.shape != (n, 2)
            or self.position.shape
            != (
                n,
                6,
            )
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
        cls, primitive: PrimitiveLike, *, control_rate: float = DEFAULT_CONTROL_RATE
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
            inputs=np.ascontiguousarray(s.inputs, dtype=np.float64),
            position=np.ascontiguousarray(s.position, dtype=np.float64),
        )

    def reference(self) -> Reference:
        """The reference for the closed loop, in the primitive's own frame."""
        return Reference(self.states, self.inputs, self.dt)

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
    """Radii of a domain that is round in position (m) and in velocity (m/s)."""

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
class VerificationOptions:
    """Options of policy verification and sizing.

    Parameters
    ----------
    boundary_points : int
        Initial states on the surface of S (>= 64 recommended; the first 8 are the axis
        extremes).
    goal_radii : DomainRadii
        The goal domain G shared by every policy (0.1 m, 0.1 m/s).
    velocity_per_position : float
        ρ_v/ρ_p of start domains (1/s).
    outer_position_factor, outer_velocity_factor : float
        D'(t) radii over D(t) radii.
    lean_limit : float
        The balancing controller's domain: largest |φ_x|, |φ_y| allowed (rad).
    max_position_radius : float
        Upper end of the bisection on S's position radius (m).
    bisection_steps : int
        Bisection iterations on S's size.
    """

    boundary_points: int = 64
    goal_radii: DomainRadii = field(default_factory=lambda: DomainRadii(0.1, 0.1))
    velocity_per_position: float = 1.0
    outer_position_factor: float = 1.3
    outer_velocity_factor: float = 2.0
    lean_limit: float = float(np.deg2rad(8.0))
    max_position_radius: float = 0.5
    bisection_steps: int = 7

    def __post_init__(self) -> None:
        if self.boundary_points < 8:
            raise ConfigError("boundary_points must be >= 8 (the axis extremes)")
        if self.outer_position_factor < 1 or self.outer_velocity_factor < 1:
            raise ConfigError("outer domain factors must be >= 1 (D(t) ⊂ D'(t))")
        if not self.lean_limit > 0:
            raise ConfigError("lean_limit must be positive")


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
        D'(t) radii over D(t) radii, (position, velocity).
    report : VerificationReport or None
        Verification outcome, when verified.
    """

    primitive: SampledPrimitive
    gains: ControllerGains
    start_radii: DomainRadii
    goal_radii: DomainRadii
    outer_factors: tuple[float, float] = (1.3, 2.0)
    report: VerificationReport | None = None

    @property
    def name(self) -> str:
        """The primitive's name."""
        return self.primitive.name

    @property
    def duration(self) -> float:
        """t_f (s)."""
        return self.primitive.duration

    def radii(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Position and velocity radii of D(t): geometric from S at 0 to G at t_f."""
        s = np.clip(np.asarray(t, dtype=float) / self.duration, 0.0, 1.0)
        rp = self.start_radii.position * (self.goal_radii.position / self.start_radii.position) ** s
        rv = self.start_radii.velocity * (self.goal_radii.velocity / self.start_radii.velocity) ** s
        return rp, rv

    def domain(self, t: float) -> EllipsoidalDomain:
        """D(t), in the policy's own frame."""
        rp, rv = self.radii(t)
        return EllipsoidalDomain(
            self.primitive.position_state(t), isotropic_shape(float(rp), float(rv))
        )

    def outer_domain(self, t: float) -> EllipsoidalDomain:
        """D'(t) ⊃ D(t), in the policy's own frame."""
        rp, rv = self.radii(t)
        cp, cv = self.outer_factors
        return EllipsoidalDomain(
            self.primitive.position_state(t), isotropic_shape(float(rp) * cp, float(rv) * cv)
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
        rp, rv = self.radii(t)
        cp, cv = self.outer_factors
        shapes = np.zeros((t.size, 4, 4))
        shapes[:, 0, 0] = shapes[:, 1, 1] = 1.0 / (rp * cp) ** 2
        shapes[:, 2, 2] = shapes[:, 3, 3] = 1.0 / (rv * cv) ** 2
        return np.ascontiguousarray(self.primitive.position[:, :4]), shapes

    def with_start_radii(self, radii: DomainRadii) -> MotionPolicy:
        """A copy with another start domain size (and no verification report)."""
        return replace(self, start_radii=radii, report=None)


def verify_policy(
    policy: MotionPolicy,
    options: VerificationOptions | None = None,
    *,
    params: object | None = None,
) -> VerificationReport:
    """Verify a policy on the 3D model from points on the surface of its start domain.

    Parameters
    ----------
    policy : MotionPolicy
    options : VerificationOptions, optional
    params : BallbotParams, optional
        Plant parameters (default: the controller's nominal ones).

    Returns
    -------
    VerificationReport
    """
    options = options if options is not None else VerificationOptions()
    prim = policy.primitive
    u = sphere_points(options.boundary_points)
    scale = np.array(
        [policy.start_radii.position] * 2 + [policy.start_radii.velocity] * 2, dtype=float
    )
    p0 = prim.position[0, :4] + u * scale
    x_plan = prim.states[0]
    lean = x_plan[2:4]
    rate = x_plan[6:8]
    r = policy.gains.params.ball_radius
    x0 = state_from_position(p0, r, lean=lean, lean_rate=rate)
    res = simulate_batch(
        x0,
        prim.reference(),
        policy.gains,
        params=params,  # type: ignore[arg-type]
        monitor=policy.outer_monitor(),
    )
    from gracenav.simulate import position_state

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


def size_policy(
    primitive: SampledPrimitive,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    *,
    progress: Callable[[], None] | None = None,
) -> MotionPolicy:
    """Build the policy of ``primitive`` with the largest start domain that verifies.

    Bisection on the start domain's position radius between the goal's and
    ``options.max_position_radius`` (the velocity radius follows
    ``options.velocity_per_position``, never below the goal's).

    Returns
    -------
    MotionPolicy
        With ``report.passed`` False if even S = G fails.
    """
    options = options if options is not None else VerificationOptions()
    gains = gains if gains is not None else design_gains()
    goal = options.goal_radii
    factors = (options.outer_position_factor, options.outer_velocity_factor)

    def radii_at(rp: float) -> DomainRadii:
        return DomainRadii(rp, max(goal.velocity, rp * options.velocity_per_position))

    def attempt(rp: float) -> MotionPolicy:
        pol = MotionPolicy(primitive, gains, radii_at(rp), goal, factors)
        rep = verify_policy(pol, options)
        if progress is not None:
            progress()
        return replace(pol, report=rep)

    best = attempt(goal.position)
    if best.report is None or not best.report.passed:
        return best
    top = attempt(options.max_position_radius)
    if top.report is not None and top.report.passed:
        return top
    lo, hi = goal.position, options.max_position_radius
    for _ in range(options.bisection_steps):
        mid = 0.5 * (lo + hi)
        cand = attempt(mid)
        if cand.report is not None and cand.report.passed:
            best, lo = cand, mid
        else:
            hi = mid
    return best
