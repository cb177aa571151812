"""Capture regulators and scaled variants of the palette's policies."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace

from gracenav.control import ControllerGains
from gracenav.policies.options import (
    DomainRadii,
    PushLeanTable,
    VerificationOptions,
    push_lean_table,
)
from gracenav.policies.policy import MotionPolicy
from gracenav.policies.primitive import SampledPrimitive
from gracenav.policies.verification import verify_placements

__all__ = [
    "fine_label",
    "fine_variants",
    "regulator_label",
    "regulator_policies",
    "scaled_variants",
    "variant_label",
]


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


def variant_label(name: str, scale: float) -> str:
    """Name of the variant of policy ``name`` whose start domain is ``scale`` × G."""
    return f"{name}[S={scale:g}G]"


def fine_label(name: str, factor: float) -> str:
    """Name of the fine copy of policy ``name`` whose domains are ``factor`` times its
    own, e.g. ``"cruise_x[x0.5]"``."""
    return f"{name}[x{factor:g}]"


def fine_variants(
    policy: MotionPolicy,
    options: VerificationOptions | None = None,
    *,
    progress: Callable[[], None] | None = None,
) -> tuple[MotionPolicy, ...]:
    """Fine copies of a verified policy: S, G and D'(t) scaled by each factor of
    ``options.fine_scales``, the reference and control law unchanged.

    Each copy is verified again at both placements from the surface of its own S,
    like the policy itself (the closed loop is not linear: the copy is not verified
    by scaling). The factors are tried in order and stop at the first that fails, so
    that each level hands over to the next (see
    :attr:`~gracenav.policies.VerificationOptions.fine_scales`).

    Returns
    -------
    tuple of MotionPolicy
        The verified copies, largest first, labelled by :func:`fine_label`.
    """
    options = options if options is not None else VerificationOptions()
    return _verified_until_one_fails(
        (
            replace(
                policy,
                start_radii=policy.start_radii.scaled(factor),
                goal_radii=policy.goal_radii.scaled(factor),
                report=None,
                label=fine_label(policy.primitive.name, factor),
            )
            for factor in options.fine_scales
        ),
        options,
        progress,
    )


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
    return _verified_until_one_fails(
        (
            replace(
                policy,
                start_radii=policy.goal_radii.scaled(scale),
                report=None,
                label=variant_label(policy.primitive.name, scale),
            )
            for scale in options.scale_ladder
            if scale > policy.scale * (1 + 1e-12)
        ),
        options,
        progress,
    )


def _verified_until_one_fails(
    candidates: Iterable[MotionPolicy],
    options: VerificationOptions,
    progress: Callable[[], None] | None,
) -> tuple[MotionPolicy, ...]:
    """Verify ``candidates`` in turn at both placements, with their reports, up to the
    first that fails (left out, and the rest not tried)."""
    out: list[MotionPolicy] = []
    for cand in candidates:
        report = verify_placements(cand, options)
        if progress is not None:
            progress()
        if not report.passed:
            break
        out.append(replace(cand, report=report))
    return tuple(out)
