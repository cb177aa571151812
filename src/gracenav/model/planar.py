"""Planar ballbot model (IJRR 2014, eqs. 1-5).

Configuration q = [θ, φ]: θ is the ball angle *relative to the body* (what
the motor encoders read) and φ the body lean from vertical, both in rad.
The ball position along the plane is x = r_w (θ + φ). The input torque enters
only the first equation:

    M(q) q̈ + C(q, q̇) + G(q) + D(q̇) = [τ, 0]ᵀ

All functions accept arrays with any leading batch shape: ``q`` and ``qd``
have shape (..., 2) and ``tau`` shape (...).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError
from gracenav.model.friction import friction_constants, friction_torque
from gracenav.params import BallbotParams

__all__ = ["PlanarBallbot"]

FloatArray = NDArray[np.float64]


class PlanarBallbot:
    """The ballbot restricted to one vertical plane.

    Parameters
    ----------
    params : BallbotParams
        Physical parameters.
    plane : {"x", "y"}
        Direction of motion. Motion along x leans the body about the y axis
        and uses ``params.body_inertia_y``; motion along y uses
        ``params.body_inertia_x``.
    """

    def __init__(self, params: BallbotParams | None = None, plane: Literal["x", "y"] = "x"):
        if plane not in ("x", "y"):
            raise ConfigError(f"plane must be 'x' or 'y', got {plane!r}")
        self.params = params if params is not None else BallbotParams()
        self.plane = plane
        p = self.params
        self.body_inertia = p.body_inertia_y if plane == "x" else p.body_inertia_x
        self.alpha = p.alpha()
        self.beta = p.beta()
        self.gamma = p.gamma(self.body_inertia)

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """Mass matrix M(q), shape (..., 2, 2)."""
        q = np.asarray(q, dtype=float)
        bc = self.beta * np.cos(q[..., 1])
        m = np.empty((*q.shape[:-1], 2, 2))
        m[..., 0, 0] = self.alpha
        m[..., 0, 1] = self.alpha + bc
        m[..., 1, 0] = self.alpha + bc
        m[..., 1, 1] = self.alpha + self.gamma + 2.0 * bc
        return m

    def bias(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Coriolis/centrifugal plus gravity terms C(q, q̇) + G(q), shape (..., 2)."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        s = np.sin(q[..., 1])
        cor = -self.beta * s * qd[..., 1] ** 2
        grav = -self.beta * self.params.gravity * s / self.params.ball_radius
        return np.stack([cor, cor + grav], axis=-1)

    def friction(self, qd: ArrayLike) -> FloatArray:
        """Friction torque on θ, D_c tanh(θ̇/ε) + D_v θ̇ (N m), shape (...)."""
        thd = np.asarray(qd, dtype=float)[..., 0]
        out: FloatArray = friction_torque(friction_constants(self.params), thd)
        return out

    def accelerations(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> FloatArray:
        """Solve the equations of motion for q̈ (rad/s²), shape (..., 2)."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        tau = np.asarray(tau, dtype=float)
        m = self.mass_matrix(q)
        rhs = -self.bias(q, qd)
        rhs[..., 0] += tau - self.friction(qd)
        det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
        a0 = (m[..., 1, 1] * rhs[..., 0] - m[..., 0, 1] * rhs[..., 1]) / det
        a1 = (m[..., 0, 0] * rhs[..., 1] - m[..., 1, 0] * rhs[..., 0]) / det
        return np.stack([a0, a1], axis=-1)

    def energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Total mechanical energy T + V (J), potential zero with the body COM at ball height."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        m = self.mass_matrix(q)
        kinetic = 0.5 * np.einsum("...i,...ij,...j->...", qd, m, qd)
        potential = self.params.body_mass * self.params.gravity * self.params.body_com_height
        return kinetic + potential * np.cos(q[..., 1])

    def ball_position(self, q: ArrayLike) -> FloatArray:
        """Ball position along the plane, x = r_w (θ + φ) (m)."""
        q = np.asarray(q, dtype=float)
        return self.params.ball_radius * (q[..., 0] + q[..., 1])

    def linearize(self, *, viscous: bool = False) -> tuple[FloatArray, FloatArray]:
        """Linearise about upright rest.

        Parameters
        ----------
        viscous : bool
            Include viscous friction. Coulomb friction is never included
            (it is not differentiable at rest; controllers feed it forward).

        Returns
        -------
        A : ndarray, shape (4, 4)
            State matrix for x = [θ, φ, θ̇, φ̇].
        B : ndarray, shape (4, 1)
            Input matrix for the torque τ.
        """
        m0 = self.mass_matrix(np.zeros(2))
        dg = np.array(
            [[0.0, 0.0], [0.0, -self.beta * self.params.gravity / self.params.ball_radius]]
        )
        dd = np.zeros((2, 2))
        if viscous:
            dd[0, 0] = self.params.viscous_friction
        minv = np.linalg.inv(m0)
        a = np.zeros((4, 4))
        a[:2, 2:] = np.eye(2)
        a[2:, :2] = -minv @ dg
        a[2:, 2:] = -minv @ dd
        b = np.zeros((4, 1))
        b[2:, 0] = minv[:, 0]
        return a, b

    def flat_output_length(self) -> float:
        """L = r_w (γ + β)/(α + β) (m): y = x + L φ is flat for the linearised model."""
        return self.params.ball_radius * (self.gamma + self.beta) / (self.alpha + self.beta)
