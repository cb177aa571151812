"""Verification of motion policies on the 3D model: trajectories from the surface of S
must stay in D'(t) and end in G; domain sizing by bisection."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from gracenav.control import ControllerGains, design_gains
from gracenav.params import BallbotParams
from gracenav.policies.domains import sphere_points
from gracenav.policies.options import PushLeanTable, VerificationOptions
from gracenav.policies.policy import MotionPolicy, VerificationReport, flat_position_state
from gracenav.policies.primitive import SampledPrimitive
from gracenav.policies.shape import DomainShape, domain_shape
from gracenav.sim import position_state, simulate_batch, state_from_position

__all__ = ["combined_report", "size_policy", "verify_placements", "verify_policy"]


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
            from gracenav.primitives.references import flat_output_lengths

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
    placements: tuple[int, ...] = (0, 1),
) -> VerificationReport:
    """Verify a policy at every placement instantiation uses (``push_leans`` and
    ``boundary_points`` as in :func:`verify_policy`).

    Instantiation places policies at 0°, 90°, 180° and 270°; 180° is an exact
    symmetry of the 3D model, so the 0° and 90° placements cover all four. Returns
    the combined report (passes only if both pass). ``placements`` (quarter turns)
    narrows this for a policy that only ever runs in its own frame, ``(0,)``: one
    designed where it runs (:mod:`gracenav.execution.launch`).
    """
    reports = [
        verify_policy(
            replace(policy, primitive=policy.primitive.rotated(k)),
            options,
            params=params,
            push_leans=push_leans,
            boundary_points=boundary_points,
        )
        for k in placements
    ]
    return combined_report(*reports)


def size_policy(
    primitive: SampledPrimitive,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    *,
    shape: DomainShape | None = None,
    progress: Callable[[], None] | None = None,
    fits: Callable[[MotionPolicy], bool] | None = None,
    placements: tuple[int, ...] = (0, 1),
    largest_fit_first: bool = False,
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
    fits : callable, optional
        A test a size must also pass, monotone in the size (a larger S fails where a
        smaller one does), checked before the size's verification: e.g. that the swept
        D' is clear of a map. A size that fails it is treated as one that fails
        verification, without running it.
    placements : tuple of int
        Quarter turns it is verified at (:func:`verify_placements`).
    largest_fit_first : bool
        With ``fits``: run the same bisection on ``fits`` alone first (no
        verification) and verify only the size it ends on; if that passes, it is the
        result, the one the bisection with verification gives wherever verification
        passes at every size it tries (sizes that fit rarely fail it: the maneuvers
        designed online). Otherwise the bisection with verification runs as without it
        (each size is verified at most once).

    Returns
    -------
    MotionPolicy
        With ``report.passed`` False if even S = G fails (or does not fit: then
        ``report`` is None).
    """
    options = options if options is not None else VerificationOptions()
    gains = gains if gains is not None else design_gains()
    shape = shape if shape is not None else domain_shape(gains, horizon=options.shape_horizon)
    goal = shape.radii(options.goal_position_extent)
    factors = (options.outer_position_factor, options.outer_velocity_factor)

    def policy(scale: float) -> MotionPolicy:
        return MotionPolicy(primitive, gains, goal.scaled(scale), goal, factors, shape.correlation)

    tried: dict[float, MotionPolicy] = {}

    def attempt(scale: float) -> MotionPolicy:
        """The policy of S = scale G, verified if it fits (once per scale)."""
        if scale not in tried:
            pol = policy(scale)
            if fits is None or fits(pol):
                pol = replace(pol, report=verify_placements(pol, options, placements=placements))
                if progress is not None:
                    progress()
            tried[scale] = pol
        return tried[scale]

    def verified(scale: float) -> bool:
        report = attempt(scale).report
        return report is not None and report.passed

    if fits is not None and largest_fit_first:
        size = _largest_scale(lambda scale: fits(policy(scale)), options)
        if size is None:
            return attempt(1.0)  # not even S = G fits: no verification
        if verified(size):
            return attempt(size)
    size = _largest_scale(verified, options)
    return attempt(1.0 if size is None else size)


def _largest_scale(passes: Callable[[float], bool], options: VerificationOptions) -> float | None:
    """The bisection of :func:`size_policy` on a test of the scale S/G: None if 1 fails,
    ``options.max_scale`` if it passes, else the largest passing midpoint found in
    ``options.bisection_steps`` halvings (1 if none), trying 1, the top, then the
    midpoints in that order."""
    if not passes(1.0):
        return None
    if passes(options.max_scale):
        return options.max_scale
    lo, hi = 1.0, options.max_scale
    for _ in range(options.bisection_steps):
        mid = 0.5 * (lo + hi)
        if passes(mid):
            lo = mid
        else:
            hi = mid
    return lo
