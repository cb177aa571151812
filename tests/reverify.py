"""Verified domains checked again from points their verification did not choose."""

from __future__ import annotations

import dataclasses

import numpy as np

from gracenav.policies import (
    MotionPolicy,
    PushLeanTable,
    VerificationOptions,
    run_policy,
    verify_placements,
)


def assert_holds_from_unchosen_points(
    pol: MotionPolicy,
    options: VerificationOptions,
    *,
    boundary_points: int,
    interior: int,
    seed: int,
    push_leans: PushLeanTable | None = None,
    placements: tuple[int, ...] = (0, 1),
) -> None:
    """``pol`` verified again on the 3D model from ``boundary_points`` on the surface
    of its S (another set than its own) at both placements, or at ``placements``
    (each also started with the leans of ``push_leans``), and run from ``interior``
    random states inside S (uniform in the ellipsoid): every run stays in D' and ends
    in G."""
    rep = verify_placements(
        pol,
        dataclasses.replace(options, boundary_points=boundary_points),
        push_leans=push_leans,
        placements=placements,
    )
    assert rep.passed, rep
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(interior, 4))
    u *= (rng.uniform(size=(interior, 1)) ** 0.25) / np.linalg.norm(u, axis=1, keepdims=True)
    ell = np.linalg.cholesky(np.linalg.inv(pol.start_domain.shape_matrix))
    for p0 in pol.start_domain.center + u @ ell.T:
        res = run_policy(pol, p0)
        assert res.max_domain_value <= 1.0
        assert pol.goal_domain.value(res.position_state[-1]) <= 1.0
