"""Motion policies: domain shape, domains, verification, coarse storage, switching."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg
from reverify import assert_holds_from_unchosen_points

from gracenav import BallbotParams, ConfigError
from gracenav.control import design_gains, planar_to_position_coordinates
from gracenav.model import Ballbot3D, PlanarBallbot
from gracenav.policies import (
    SampledPrimitive,
    VerificationOptions,
    domain_shape,
    rotate_pairs,
    size_policy,
    switch_torque_jumps,
    verify_placements,
    verify_policy,
)
from gracenav.policies.domains import correlated_shape

PARAMS = BallbotParams()


def shrink_factor(cov2: np.ndarray, horizon: float, plane: str, row: int) -> float:
    """Worst-case shrink of the ellipse {eᵀ Σ⁻¹ e <= 1} under the linear closed loop."""
    gains = design_gains(PARAMS)
    a, b = PlanarBallbot(PARAMS, plane=plane).linearize()  # type: ignore[arg-type]
    t = planar_to_position_coordinates(PARAMS.ball_radius)
    acl = t @ a @ np.linalg.inv(t) - (t @ b) @ gains.lqr[row][None, :]
    phi = scipy.linalg.expm(acl * horizon)[np.ix_([0, 2], [0, 2])]
    # Boundary points of the ellipse, pushed through Φ, measured in the same ellipse.
    ang = np.linspace(0, 2 * np.pi, 721)
    ell = np.linalg.cholesky(cov2)
    x0 = ell @ np.vstack([np.cos(ang), np.sin(ang)])
    x1 = phi @ x0
    return float(np.sqrt(np.max(np.einsum("in,ij,jn->n", x1, np.linalg.inv(cov2), x1))))


def test_domain_shape_contracts_where_a_round_domain_does_not() -> None:
    shape = domain_shape(design_gains(PARAMS), horizon=1.0)
    k, r = shape.velocity_per_position, shape.correlation
    cov = np.array([[1.0, r * k], [r * k, k * k]])
    for row, plane in enumerate("xy"):
        assert shrink_factor(cov, 1.0, plane, row) < 0.35
        # A round domain (1 m ↔ 1 m/s) is not contracted in 1 s: trims could not chain.
        assert shrink_factor(np.eye(2), 1.0, plane, row) > 1.0
    assert -1.0 < r < 0.0  # ahead and moving back toward the reference is inside


def test_domains_of_a_policy(palette) -> None:
    pol = palette["rest_to_cruise_x_2_0"]
    prim = pol.primitive
    np.testing.assert_allclose(pol.start_domain.center, prim.position[0, :4], atol=1e-12)
    np.testing.assert_allclose(pol.goal_domain.center, prim.position[-1, :4], atol=1e-12)
    for t in np.linspace(0, pol.duration, 9):
        assert pol.outer_domain(t).contains_domain(pol.domain(t))
    # D(t) shrinks geometrically from S to G.
    rp, _ = pol.radii(np.array([0.0, pol.duration / 2, pol.duration]))
    assert rp[1] == pytest.approx(np.sqrt(rp[0] * rp[2]), rel=1e-12)
    # Concentric S ⊇ G of one shape: G₁ ⊂ S₂ whenever the ends meet.
    assert pol.start_radii.contains(pol.goal_radii)
    goal_at_start = dataclasses.replace(pol.goal_domain, center=pol.start_domain.center)
    assert pol.start_domain.contains_domain(goal_at_start)


def test_palette_has_40_verified_primitives_and_larger_variants(palette) -> None:
    base = palette.base_policies
    assert len(base) == 40  # 39 as in the paper, plus the capture trim
    assert palette.duplicates == (("cruise_y", "cruise_x rotated by 90°"),)
    assert len({p.primitive.name for p in base}) == 40
    for pol in palette:
        rep = pol.report
        assert rep is not None and rep.passed and rep.runs >= 128
        assert rep.max_outer_value <= 1.0 and rep.max_goal_value <= 1.0
        assert rep.max_lean <= palette.options.lean_limit
        assert rep.max_torque <= PARAMS.torque_limit
        assert pol.start_radii.position >= pol.goal_radii.position
    by_name = {p.name: p for p in base}
    for pol in palette.policies:
        if not pol.label or pol.capture:  # capture regulators: tests/test_capture.py
            continue
        if pol.name.endswith("]") and "[x" in pol.name:  # fine copies: test_fine_policies.py
            continue
        own = by_name[pol.primitive.name]
        assert pol.primitive is own.primitive  # variants share the primitive
        assert pol.goal_radii == own.goal_radii  # and G: graceful connections are kept
        ladder = np.asarray(palette.options.scale_ladder)
        assert np.min(np.abs(ladder - pol.scale)) <= 1e-12 * pol.scale  # S/G is computed
        assert pol.scale > own.scale
        assert pol.label == f"{own.name}[S={ladder[np.argmin(np.abs(ladder - pol.scale))]:g}G]"
    capture = max((p for p in palette if p.primitive.name == "capture"), key=lambda p: p.scale)
    assert capture.scale >= 4.0
    assert capture.start_radii.velocity >= 0.4  # catches a robot moving at 0.4 m/s


def test_largest_capture_domain_holds_from_points_the_verifier_never_used(palette) -> None:
    """Re-verify the largest capture domain from another boundary set and from random
    interior states on the 3D model (the sizing saw 64 boundary points only)."""
    capture = max((p for p in palette if p.primitive.name == "capture"), key=lambda p: p.scale)
    assert_holds_from_unchosen_points(
        capture, palette.options, boundary_points=101, interior=40, seed=7
    )


@pytest.mark.parametrize("name", ["rest", "cruise_xy", "cruise_x_to_cruise_y_1_1"])
def test_reverification_agrees_with_the_stored_report(palette, name: str) -> None:
    pol = palette[name]
    rep = verify_policy(pol, palette.options)
    assert rep.passed
    assert rep.max_outer_value == pytest.approx(pol.report.max_outer_value, rel=1e-9)


def test_verification_can_fail(palette) -> None:
    pol = palette["rest_to_rest_1_0"]
    # Too tight an outer domain: the non-minimum-phase transient leaves it.
    tight = dataclasses.replace(pol, outer_factors=(1.0, 1.0))
    rep = verify_policy(tight, palette.options)
    assert not rep.passed and rep.max_outer_value > 1.0
    # Too large a start domain: the lean limit is exceeded.
    huge = pol.with_start_radii(pol.start_radii.scaled(4.0))
    rep = verify_policy(huge, dataclasses.replace(palette.options, lean_limit=np.deg2rad(6.0)))
    assert not rep.passed


def test_coarse_storage_rebuilds_a_feasible_trajectory() -> None:
    """The palette stores 1/128 s samples; the rebuilt 1/1024 s samples satisfy the 3D EOM
    (on the nonic palette, whose primitive set is the options' defaults: planned afresh
    in about 2 s, where the limited references take about 25 s)."""
    from gracenav.palette import load_palette
    from gracenav.primitives import primitive_set

    palette = load_palette("nonic")
    model = Ballbot3D(PARAMS)
    for name in ("rest_to_rest_2_1", "cruise_x_to_cruise_nx_0_1"):
        fresh = SampledPrimitive.from_primitive(primitive_set()[name])
        stored = palette[name].primitive
        np.testing.assert_allclose(stored.states, fresh.states, atol=1e-9)
        np.testing.assert_allclose(stored.inputs, fresh.inputs, atol=1e-6)
        np.testing.assert_allclose(stored.position, fresh.position, atol=1e-9)
        q, qd = stored.states[:, :4], stored.states[:, 4:]
        acc = model.accelerations(q, qd, stored.inputs)
        mm = model.mass_matrix(q)
        residual = np.einsum("nij,nj->ni", mm, acc - stored.accelerations)
        assert np.max(np.abs(residual)) < 1e-6


def test_rotate_pairs() -> None:
    x = np.arange(8.0)
    np.testing.assert_array_equal(rotate_pairs(x, 1), [-1, 0, -3, 2, -5, 4, -7, 6])
    np.testing.assert_array_equal(rotate_pairs(x, 4), x)
    np.testing.assert_array_equal(rotate_pairs(rotate_pairs(x, 3), 1), x)
    rng = np.random.default_rng(3)
    states = rng.normal(size=(5, 8))
    for k in range(-1, 6):  # the exact swaps and signs equal the rotation matrix's product
        turn = np.array([[np.cos(k * np.pi / 2), -np.sin(k * np.pi / 2)]])
        turn = np.round(np.vstack([turn, [[-turn[0, 1], turn[0, 0]]]]))
        expect = (states.reshape(5, 4, 2) @ turn.T).reshape(5, 8)
        np.testing.assert_array_equal(rotate_pairs(states, k), expect)
        into = np.empty((5, 8))
        assert rotate_pairs(states, k, out=into) is into
        np.testing.assert_array_equal(into, expect)
    with pytest.raises(ValueError, match="shape"):
        rotate_pairs(states, 1, out=np.empty((5, 6)))
    with pytest.raises(ValueError, match="overlap"):
        rotate_pairs(states, 1, out=states)


def test_graceful_switches_have_no_torque_jump(palette) -> None:
    """φ₁(t_f1) = φ₂(0): the commanded torque is continuous at every graceful switch."""
    names = ["rest", "rest_to_cruise_x_1_0", "cruise_x", "cruise_x_to_cruise_y_1_1"]
    names += ["cruise_x_to_rest_1_0", "cruise_xy", "cruise_xy_to_rest_1_1"]
    jumps = switch_torque_jumps([palette[n] for n in names])
    assert len(jumps) >= 10
    for j in jumps:
        # The jump at the switch is far below the ordinary tick-to-tick change.
        assert j.jump < 0.1, j
        assert j.jump <= 0.2 * j.largest_other_step, j


def test_options_validation() -> None:
    with pytest.raises(ConfigError, match="outer domain factors"):
        VerificationOptions(outer_position_factor=0.5)
    with pytest.raises(ConfigError, match="max_scale"):
        VerificationOptions(max_scale=0.5)
    with pytest.raises(ConfigError, match="correlation"):
        correlated_shape(0.1, 0.1, 1.0)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name", ["cruise3_x", "rest_to_cruise2_x_3_0", "cruise2_x_to_cruise2_y_3_3"]
)
def test_the_speed_palettes_fast_policies_hold_from_points_the_verifier_never_used(
    name: str,
) -> None:
    """The shipped speed palette's policies at 1.0–1.2 m/s (the 1.2 m/s trim needs 59.6
    of the 60 N m) verified again on the 3D model from another boundary set and from
    random interior states of S: the run stays in D' and ends in G."""
    from gracenav.palette import load_palette

    pal = load_palette("speed")
    assert_holds_from_unchosen_points(
        pal[name], pal.options, boundary_points=67, interior=12, seed=11
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    ("palette_name", "name"),
    [
        ("default", "rest_to_cruise_x_1_0"),
        ("default", "rest_to_cruise_xy_1_1[S=6G]"),
        ("speed", "rest_to_cruise2_x_3_0"),
    ],
)
def test_policies_started_from_a_hold_hold_from_the_still_band_at_unchosen_points(
    palette_name: str, name: str
) -> None:
    """Policies that start at rest and passed verification from the still band (the
    hybrid controller may start them from a hold with the lean within it) verified
    again on the 3D model from another boundary set, each point also started at the
    band's four corners, and from random interior states of S."""
    from gracenav.palette import load_palette
    from gracenav.policies.catches import band_leans

    pal = load_palette(palette_name)
    pol = pal[name]
    assert pol.starts_from_still_band
    assert pal.options.catch is not None
    assert_holds_from_unchosen_points(
        pol,
        pal.options,
        boundary_points=67,
        interior=12,
        seed=13,
        push_leans=band_leans(*pal.options.catch.still_lean),
    )


def test_verify_still_start_checks_only_policies_that_start_at_rest(palette) -> None:
    """A maneuver from rest gets a report from the still band's corners at both
    placements (5 starts per boundary point); a trim, a maneuver from cruise, a rest
    trim and a capture regulator are returned unchanged, as is any policy when the
    options have no still band (no catches)."""
    from gracenav.policies.catches import verify_still_start

    opts = dataclasses.replace(palette.options, boundary_points=16)
    pol = dataclasses.replace(palette["rest_to_cruise_x_1_0"], still_report=None)
    checked = verify_still_start(pol, opts)
    assert checked.still_report is not None
    assert checked.still_report.runs == 2 * 16 * 5
    assert checked.starts_from_still_band == checked.still_report.passed
    assert checked.primitive is pol.primitive and checked.report == pol.report
    for name in ("cruise_x", "cruise_x_to_rest_1_0", "rest", "regulate[ep=0.2m]"):
        other = dataclasses.replace(palette[name], still_report=None)
        assert verify_still_start(other, opts) is other
    assert verify_still_start(pol, dataclasses.replace(opts, catch=None)) is pol


def test_sizing_keeps_to_a_size_test_and_one_placement(palette, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``size_policy``'s ``fits``: the largest verified S that also passes the test (a
    bound on S/G here), never a verification of a size that fails it, None where even
    S = G fails it; ``placements=(0,)`` verifies the one frame, half the runs; with
    ``largest_fit_first`` the same policy from fewer verifications."""
    prim = palette["rest_to_rest_1_0"].primitive
    opts = dataclasses.replace(palette.options, boundary_points=16, bisection_steps=4)
    free = size_policy(prim, palette.gains, opts)
    assert free.report is not None and free.report.passed
    tried: list[float] = []

    def small(pol) -> bool:  # type: ignore[no-untyped-def]
        tried.append(pol.scale)
        return bool(pol.scale <= 1.3)

    sized = size_policy(prim, palette.gains, opts, fits=small)
    assert sized.report is not None and sized.report.passed
    assert 1.3 - (opts.max_scale - 1.0) / 2**opts.bisection_steps < sized.scale <= 1.3
    assert sized.scale <= free.scale
    assert len(tried) == opts.bisection_steps + 2
    none = size_policy(prim, palette.gains, opts, fits=lambda pol: False)
    assert none.report is None
    # The size test's bisection first: the same policy, verified once instead of at
    # S = G and at every size that fits.
    runs: list[int] = []
    first = size_policy(
        prim,
        palette.gains,
        opts,
        fits=small,
        largest_fit_first=True,
        progress=lambda: runs.append(1),
    )
    assert first.scale == sized.scale and first.report == sized.report and len(runs) == 1
    assert (
        size_policy(
            prim, palette.gains, opts, fits=lambda pol: False, largest_fit_first=True
        ).report
        is None
    )
    # Where the size the test ends on fails verification (made to fail above 1.2 G
    # here), the bisection with verification runs, as without the option.
    import gracenav.policies.verification as verification

    real = verification.verify_placements

    def shy(pol, *args, **kwargs):  # type: ignore[no-untyped-def]
        report = real(pol, *args, **kwargs)
        return dataclasses.replace(report, passed=report.passed and pol.scale <= 1.2)

    monkeypatch.setattr(verification, "verify_placements", shy)
    runs.clear()
    fallback = size_policy(
        prim,
        palette.gains,
        opts,
        fits=small,
        largest_fit_first=True,
        progress=lambda: runs.append(1),
    )
    plain_runs: list[int] = []
    plain = size_policy(
        prim, palette.gains, opts, fits=small, progress=lambda: plain_runs.append(1)
    )
    assert 1.0 < fallback.scale <= 1.2 and fallback.scale == plain.scale
    assert fallback.report == plain.report and fallback.report.passed
    # The fit's size (1.25 G) is first, and one of the sizes the bisection tries: each
    # size is verified once, so as many verifications as without the option.
    assert len(runs) == len(plain_runs)
    one = verify_placements(sized, opts, placements=(0,))
    both = verify_placements(sized, opts)
    assert one.passed and both.passed and 2 * one.runs == both.runs
    assert one.max_outer_value <= both.max_outer_value
