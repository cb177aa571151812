"""Ellipsoidal domains in the 4D position state space (x, y, ẋ, ẏ).

A domain is {p : (p − c)ᵀ P (p − c) <= 1} with centre c (4,) and symmetric
positive definite shape matrix P (4, 4). Motion policy domains D(t), D'(t),
S = D(0) and G = D(t_f) are of this kind (paper Sec. III-B).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError

__all__ = [
    "EllipsoidalDomain",
    "correlated_shape",
    "isotropic_shape",
    "rotation_2d",
    "rotation_4d",
    "sphere_points",
]

FloatArray = NDArray[np.float64]


def isotropic_shape(position_radius: float, velocity_radius: float) -> FloatArray:
    """Shape matrix diag(1/ρ_p², 1/ρ_p², 1/ρ_v², 1/ρ_v²) of a domain that is round in
    position (radius ρ_p, m) and in velocity (radius ρ_v, m/s); invariant under rotations
    of the plane. Shape (4, 4)."""
    if not (position_radius > 0 and velocity_radius > 0):
        raise ConfigError(
            f"domain radii must be positive, got {position_radius!r} m and {velocity_radius!r} m/s"
        )
    rp, rv = 1.0 / position_radius**2, 1.0 / velocity_radius**2
    return np.diag([rp, rp, rv, rv])


def correlated_shape(
    position_extent: float, velocity_extent: float, correlation: float
) -> FloatArray:
    """Shape matrix (4, 4) of a domain with the given extents and position-velocity coupling.

    The domain is {p : pᵀ P p <= 1} with P = (Σ ⊗ I₂)⁻¹ in the ordering
    (x, y, ẋ, ẏ), where Σ = [[e_p², r e_p e_v], [r e_p e_v, e_v²]]: along each axis
    the largest position deviation is e_p (m), the largest velocity deviation e_v
    (m/s), and r ∈ (−1, 1) couples them (r < 0: a state ahead of the centre and
    moving back toward it is inside). The shape is invariant under rotations of
    the plane. ``correlation=0`` gives :func:`isotropic_shape`.
    """
    if not (position_extent > 0 and velocity_extent > 0):
        raise ConfigError(
            f"domain extents must be positive, got {position_extent!r} m and "
            f"{velocity_extent!r} m/s"
        )
    if not -1.0 < correlation < 1.0:
        raise ConfigError(f"domain correlation must lie in (-1, 1), got {correlation!r}")
    cov = np.array(
        [
            [position_extent**2, correlation * position_extent * velocity_extent],
            [correlation * position_extent * velocity_extent, velocity_extent**2],
        ]
    )
    return np.asarray(np.kron(np.linalg.inv(cov), np.eye(2)), dtype=np.float64)


def rotation_2d(angle: float) -> FloatArray:
    """Counter-clockwise rotation matrix by ``angle`` (rad), shape (2, 2)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def rotation_4d(angle: float) -> FloatArray:
    """Rotation of position states (x, y, ẋ, ẏ) by ``angle`` (rad), shape (4, 4)."""
    r = rotation_2d(angle)
    out = np.zeros((4, 4))
    out[:2, :2] = r
    out[2:, 2:] = r
    return out


@dataclass(frozen=True)
class EllipsoidalDomain:
    """{p : (p − c)ᵀ P (p − c) <= 1} in (x, y, ẋ, ẏ) (m, m, m/s, m/s).

    Attributes
    ----------
    center : ndarray, shape (4,)
    shape_matrix : ndarray, shape (4, 4)
        Symmetric positive definite.
    """

    center: FloatArray
    shape_matrix: FloatArray

    def __post_init__(self) -> None:
        c = np.array(self.center, dtype=float)
        p = np.array(self.shape_matrix, dtype=float)
        if c.shape != (4,) or p.shape != (4, 4):
            raise ConfigError(
                f"domain needs centre (4,) and shape (4, 4), got {c.shape}, {p.shape}"
            )
        if not np.allclose(p, p.T, rtol=1e-12, atol=0.0):
            raise ConfigError("domain shape matrix must be symmetric")
        c.setflags(write=False)
        p.setflags(write=False)
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "shape_matrix", p)

    def value(self, p: ArrayLike) -> FloatArray:
        """(p − c)ᵀ P (p − c) for points ``p`` (..., 4); <= 1 inside. Shape (...)."""
        d = np.asarray(p, dtype=float) - self.center
        return np.einsum("...i,ij,...j->...", d, self.shape_matrix, d)

    def contains(self, p: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point of ``p`` (..., 4) is inside (boundary included). Shape (...)."""
        return self.value(p) <= 1.0

    def contains_domain(self, other: EllipsoidalDomain, *, tol: float = 1e-12) -> bool:
        """Whether ``other`` ⊂ self, exactly (S-procedure for two ellipsoids).

        other ⊂ self iff max over other of (p − c)ᵀ P (p − c) <= 1. With
        other = {c' + L u : |u| <= 1}, L Lᵀ = P'⁻¹, the maximum of the convex
        quadratic over the ball is found by a 1D secular-equation search.
        """
        l_mat = np.linalg.cholesky(np.linalg.inv(other.shape_matrix))
        a = l_mat.T @ self.shape_matrix @ l_mat  # quadratic form in u
        b = l_mat.T @ self.shape_matrix @ (other.center - self.center)
        c0 = float((other.center - self.center) @ self.shape_matrix @ (other.center - self.center))
        # maximise uᵀ a u + 2 bᵀ u + c0 over |u| <= 1 (a is PSD: maximum on the sphere).
        w, v = np.linalg.eigh(a)
        bt = v.T @ b
        if np.allclose(bt, 0.0, atol=1e-15):
            return float(w[-1] + c0) <= 1.0 + tol
        # Stationary points: (λ I − a) u = b with λ > max eigenvalue; |u| = 1.
        lo, hi = w[-1] + 1e-15, w[-1] + np.linalg.norm(b) + 1.0
        # Bisection until lo and hi are adjacent doubles (at most ~1100 halvings, in
        # practice ~60); hi always has |u| <= 1, so the bound below stays an upper bound.
        wl = [float(e) for e in w]
        bl = [float(e) for e in bt]
        for _ in range(2200):
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            if sum((bi / (mid - wi)) ** 2 for bi, wi in zip(bl, wl, strict=True)) > 1.0:
                lo = mid
            else:
                hi = mid
        u = bt / (hi - w)
        best = float(u @ (w * u) + 2.0 * bt @ u + c0)
        return best <= 1.0 + tol

    def xy_projection(self) -> FloatArray:
        """Shape matrix (2, 2) of the projection onto (x, y): the Schur complement
        P_xx − P_xv P_vv⁻¹ P_vx, so the projection is {u : (u − c_xy)ᵀ Q (u − c_xy) <= 1}."""
        p = self.shape_matrix
        return p[:2, :2] - p[:2, 2:] @ np.linalg.solve(p[2:, 2:], p[2:, :2])

    def transformed(self, angle: float, offset: ArrayLike) -> EllipsoidalDomain:
        """The domain rotated by ``angle`` (rad, about the origin) then translated by
        ``offset`` (x, y) (m)."""
        r = rotation_4d(angle)
        c = r @ self.center
        c[:2] += np.asarray(offset, dtype=float)
        return EllipsoidalDomain(c, r @ self.shape_matrix @ r.T)


def sphere_points(n: int, dim: int = 4) -> FloatArray:
    """``n`` deterministic points on the unit sphere S^{dim−1}: all 2·dim axis extremes
    first, then a quasi-uniform set (a Halton sequence mapped through the inverse normal
    CDF and normalised). Shape (n, dim)."""
    from scipy.special import ndtri

    if n < 2 * dim:
        raise ConfigError(f"need at least {2 * dim} points to include every axis extreme, got {n}")
    axes = np.concatenate([np.eye(dim), -np.eye(dim)])
    m = n - 2 * dim
    primes = [2, 3, 5, 7, 11, 13, 17, 19][:dim]
    k = np.arange(1, m + 1)
    cols = []
    for base in primes:
        f, x, i = 1.0, np.zeros(m), k.copy()
        while np.any(i > 0):
            f /= base
            x += f * (i % base)
            i //= base
        cols.append(x)
    z = ndtri(np.column_stack(cols)) if m else np.zeros((0, dim))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    return np.concatenate([axes, z])
