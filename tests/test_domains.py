"""Ellipsoidal domains: containment, projection, transformation, boundary samples."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav import ConfigError
from gracenav.policies.domains import EllipsoidalDomain, isotropic_shape, rotation_4d, sphere_points


def test_contains_and_value() -> None:
    d = EllipsoidalDomain(np.array([1.0, 2.0, 0.5, 0.0]), isotropic_shape(0.2, 0.4))
    assert d.contains([1.0, 2.0, 0.5, 0.0])
    assert d.contains([1.2, 2.0, 0.5, 0.0])  # boundary included
    assert not d.contains([1.21, 2.0, 0.5, 0.0])
    assert d.value([1.0, 2.0, 0.9, 0.0]) == pytest.approx(1.0)
    pts = np.zeros((3, 5, 4))
    assert d.contains(pts).shape == (3, 5)


def test_contains_domain_against_sampling() -> None:
    rng = np.random.default_rng(0)
    refuted = confirmed = 0
    for _ in range(200):
        a = rng.normal(size=(4, 4))
        big = EllipsoidalDomain(rng.normal(size=4) * 0.1, a @ a.T + 0.5 * np.eye(4))
        b = rng.normal(size=(4, 4))
        small = EllipsoidalDomain(
            big.center + rng.normal(size=4) * 0.2, (b @ b.T + 0.5 * np.eye(4)) * rng.uniform(1, 30)
        )
        exact = big.contains_domain(small)
        # Dense boundary sampling of `small` can only find violations, never prove containment.
        u = rng.normal(size=(20000, 4))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        pts = small.center + u @ np.linalg.cholesky(np.linalg.inv(small.shape_matrix)).T
        sampled = bool(np.all(big.contains(pts)))
        if sampled is False:
            assert exact is False
            refuted += 1
        margin = np.max(big.value(pts))
        if margin < 0.98:
            assert exact is True
            confirmed += 1
    # Both outcomes occur often enough for the comparison to mean something.
    assert refuted >= 20 and confirmed >= 20, (refuted, confirmed)


def test_concentric_isotropic_containment() -> None:
    c = np.array([0.5, 0.5, 0.3, 0.0])
    s = EllipsoidalDomain(c, isotropic_shape(0.3, 0.3))
    g = EllipsoidalDomain(c, isotropic_shape(0.15, 0.15))
    assert s.contains_domain(g) and not g.contains_domain(s)
    assert s.contains_domain(EllipsoidalDomain(c, isotropic_shape(0.3, 0.3)))
    assert not s.contains_domain(EllipsoidalDomain(c, isotropic_shape(0.31, 0.1)))


def test_xy_projection_of_a_correlated_ellipsoid() -> None:
    rng = np.random.default_rng(1)
    a = rng.normal(size=(4, 4))
    d = EllipsoidalDomain(np.zeros(4), a @ a.T + np.eye(4))
    q = d.xy_projection()
    # Support function along direction n: max nᵀp over the ellipsoid is sqrt(nᵀ P⁻¹ n).
    pinv = np.linalg.inv(d.shape_matrix)
    for ang in np.linspace(0, np.pi, 7):
        n = np.array([np.cos(ang), np.sin(ang)])
        assert np.sqrt(n @ np.linalg.inv(q) @ n) == pytest.approx(
            np.sqrt(n @ pinv[:2, :2] @ n), rel=1e-12
        )


def test_transformed_rotates_and_translates() -> None:
    d = EllipsoidalDomain(np.array([1.0, 0.0, 0.5, 0.0]), np.diag([100.0, 25.0, 4.0, 1.0]))
    t = d.transformed(np.pi / 2, (2.0, 3.0))
    np.testing.assert_allclose(t.center, [2.0, 4.0, 0.0, 0.5], atol=1e-12)
    p = np.array([1.05, 0.1, 0.6, -0.2])
    assert d.value(p) == pytest.approx(t.value(rotation_4d(np.pi / 2) @ p + [2, 3, 0, 0]))


def test_sphere_points() -> None:
    pts = sphere_points(64)
    assert pts.shape == (64, 4)
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_array_equal(pts[:8], np.concatenate([np.eye(4), -np.eye(4)]))
    # Quasi-uniform: the mean is near the origin and the nearest-neighbour gaps are even.
    assert np.linalg.norm(pts.mean(axis=0)) < 0.1
    with pytest.raises(ConfigError, match="axis extreme"):
        sphere_points(5)


def test_bad_domains() -> None:
    with pytest.raises(ConfigError, match="positive"):
        isotropic_shape(0.0, 1.0)
    with pytest.raises(ConfigError, match="symmetric"):
        EllipsoidalDomain(np.zeros(4), np.triu(np.ones((4, 4))))
