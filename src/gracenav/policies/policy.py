"""Motion policies (paper Sec. IV-B): a primitive, the Fig. 2 tracking law and the
verified time-varying domains D(t), D'(t) with S = D(0) and G = D(t_f)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from gracenav.control import ControllerGains
from gracenav.errors import ConfigError
from gracenav.params import BallbotParams
from gracenav.policies.domains import EllipsoidalDomain, correlated_shape
from gracenav.policies.options import DomainRadii
from gracenav.policies.primitive import FloatArray, SampledPrimitive
from gracenav.sim import (
    Disturbance,
    SimulationOptions,
    SimulationResult,
    simulate,
    state_from_position,
)
from gracenav.sim.plant import PlantKind

__all__ = [
    "MotionPolicy",
    "VerificationReport",
    "capture_point",
    "flat_position_state",
    "run_policy",
]


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
    still_report : VerificationReport or None
        For a policy that starts at rest (not a rest trim, not a capture policy): its
        verification at both placements from the corners of the still band
        (:attr:`CatchOptions.still_lean` around the plan lean, along the motion), None
        when not verified so. When it passed (:attr:`starts_from_still_band`), the
        hybrid controller may start it from a hold before the hold ends.
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
    still_report: VerificationReport | None = None

    @property
    def name(self) -> str:
        """The label of a scaled variant, else the primitive's name."""
        return self.label or self.primitive.name

    @property
    def starts_from_still_band(self) -> bool:
        """Whether the policy passed verification from the still band
        (:attr:`still_report`): a hold may hand over to it once its S holds the state
        and the lean is within that band."""
        return self.still_report is not None and self.still_report.passed

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
    from gracenav.primitives.references import flat_output_lengths

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
    from gracenav.primitives.references import flat_output_gain, flat_output_lengths

    omega = np.sqrt(flat_output_gain(params) / flat_output_lengths(params))
    y = np.asarray(flat_state, dtype=float)
    return np.asarray(y[..., 0:2] + y[..., 2:4] / omega, dtype=float)


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
