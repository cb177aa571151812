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

Modules: :mod:`~gracenav.policies.domains` (ellipsoids),
:mod:`~gracenav.policies.primitive` (sampled references),
:mod:`~gracenav.policies.options` (design options), :mod:`~gracenav.policies.shape`
(domain shape), :mod:`~gracenav.policies.policy` (the motion policy),
:mod:`~gracenav.policies.verification`, :mod:`~gracenav.policies.regulators`,
:mod:`~gracenav.policies.catches` (catches' and shifts' design),
:mod:`~gracenav.policies.placement` (instantiated references, switch jumps).
"""

from gracenav.policies.options import (
    BrakingOptions,
    CatchOptions,
    DomainRadii,
    PushLeanTable,
    RegulatorOptions,
    VerificationOptions,
    push_lean_table,
)
from gracenav.policies.placement import (
    instantiated_reference,
    switch_torque_jumps,
)
from gracenav.policies.policy import (
    MotionPolicy,
    VerificationReport,
    capture_point,
    flat_position_state,
    run_policy,
)
from gracenav.policies.primitive import (
    PrimitiveKind,
    SampledPrimitive,
    rotate_pairs,
    rotate_pairs_by,
)
from gracenav.policies.regulators import (
    fine_label,
    fine_variants,
    regulator_label,
    regulator_policies,
    scaled_variants,
    variant_label,
)
from gracenav.policies.shape import (
    DomainShape,
    domain_shape,
)
from gracenav.policies.verification import (
    combined_report,
    size_policy,
    verify_placements,
    verify_policy,
)

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
    "fine_label",
    "fine_variants",
    "flat_position_state",
    "instantiated_reference",
    "push_lean_table",
    "regulator_label",
    "regulator_policies",
    "rotate_pairs",
    "rotate_pairs_by",
    "run_policy",
    "scaled_variants",
    "size_policy",
    "switch_torque_jumps",
    "variant_label",
    "verify_placements",
    "verify_policy",
]
