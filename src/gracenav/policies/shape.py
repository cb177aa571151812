"""The shape of the policies' domains: correlated position-velocity ellipsoids from the
closed loop's error dynamics."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from gracenav.control import ControllerGains
from gracenav.params import BallbotParams
from gracenav.policies.options import DomainRadii
from gracenav.policies.primitive import FloatArray

__all__ = ["DomainShape", "domain_shape"]


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

    The result depends only on the gains' ``lqr`` and ``params`` and on ``horizon``,
    and is kept for the last few of them (the maneuvers designed online ask for it at
    every sizing, 16 ms each).
    """
    return _domain_shape(np.asarray(gains.lqr, dtype=float).tobytes(), gains.params, float(horizon))


@functools.lru_cache(maxsize=8)
def _domain_shape(lqr_bytes: bytes, params: BallbotParams, horizon: float) -> DomainShape:
    import scipy.linalg
    import scipy.optimize

    from gracenav.control import planar_to_position_coordinates
    from gracenav.model.planar import PlanarBallbot

    lqr = np.frombuffer(lqr_bytes, dtype=float).reshape(2, 4)
    t = planar_to_position_coordinates(params.ball_radius)
    phis = []
    for i, plane in enumerate(("x", "y")):
        a, b = PlanarBallbot(params, plane=plane).linearize()  # type: ignore[arg-type]
        acl = t @ a @ np.linalg.inv(t) - (t @ b) @ lqr[i][None, :]
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
