"""Full 3D ballbot model: a rigid body on a rolling ball, without yaw and without slip.

Configuration q = [θ_x, θ_y, φ_x, φ_y] (rad), velocities q̇ (rad/s), state
x = [q, q̇]; inputs τ = [τ_x, τ_y] (N m), the generalised forces on θ_x and
θ_y. The equations of motion are

    M(q) q̈ + h(q, q̇) = [τ_x − D_x(θ̇_x), τ_y − D_y(θ̇_y), 0, 0]ᵀ,

with h = C(q, q̇) q̇ + G(q) and friction D_i = D_c tanh(θ̇_i/ε) + D_v θ̇_i.
Every coordinate, axis and sign is fixed in docs/design/conventions.md ("3D model"); the
terms M, h, the energy and the body kinematics are generated from a symbolic
derivation by ``tools/derive_ballbot3d.py`` into
:mod:`gracenav.model._ballbot3d_generated`.

Motion in one plane (the other plane's coordinates and rates zero) is exactly
:class:`~gracenav.model.PlanarBallbot` of that plane, and the linearisation
about upright is the two planar linearisations, decoupled.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.model import _ballbot3d_generated as _gen
from gracenav.model.friction import friction_constants, friction_torque
from gracenav.model.indices import NQ, NU, NX
from gracenav.params import BallbotParams

__all__ = ["Ballbot3D"]

FloatArray = NDArray[np.float64]


def _vectors(value: ArrayLike, size: int, name: str) -> FloatArray:
    """``value`` as a float array of shape (..., size), or a ValueError naming it."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {arr.shape}")
    return arr


class Ballbot3D:
    """The 3D ballbot without yaw: four configuration coordinates, two inputs.

    All methods are vectorised over any leading batch shape ``...``: ``q`` and
    ``qd`` have shape (..., 4) and ``tau`` shape (..., 2), broadcast against
    each other where several are given. An array whose last axis has the
    wrong length raises ValueError.

    Parameters
    ----------
    params : BallbotParams, optional
        Physical parameters; the CMU ballbot's (IJRR 2014, Table I) by default.

    Attributes
    ----------
    params : BallbotParams
        The physical parameters.
    """

    def __init__(self, params: BallbotParams | None = None) -> None:
        self.params = params if params is not None else BallbotParams()
        self._c = self.constants()

    def constants(self) -> FloatArray:
        """Constants vector of the generated model code.

        Returns
        -------
        ndarray, shape (9,)
            [r_w (m), m_w (kg), I_w (kg m²), m_b (kg), ℓ_b (m), I_xx, I_yy,
            I_zz (kg m²), g (m/s²)], the argument ``c`` of every function in
            :mod:`gracenav.model._ballbot3d_generated`.
        """
        p = self.params
        return np.array(
            [
                p.ball_radius,
                p.ball_mass,
                p.ball_inertia,
                p.body_mass,
                p.body_com_height,
                p.body_inertia_x,
                p.body_inertia_y,
                p.body_inertia_z,
                p.gravity,
            ]
        )

    def mass_matrix(self, q: ArrayLike) -> FloatArray:
        """Mass matrix M(q).

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration [θ_x, θ_y, φ_x, φ_y] (rad).

        Returns
        -------
        ndarray, shape (..., 4, 4)
            Symmetric positive definite mass matrix (kg m²).
        """
        qa = _vectors(q, NQ, "q")
        out = np.empty((NQ, NQ, *qa.shape[:-1]))
        _gen.mass_matrix(self._c, np.moveaxis(qa, -1, 0), out)
        return np.moveaxis(out, (0, 1), (-2, -1))

    def bias(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Coriolis, centrifugal and gravity terms h = C(q, q̇) q̇ + G(q).

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).
        qd : array_like, shape (..., 4)
            Generalised velocities q̇ (rad/s).

        Returns
        -------
        ndarray, shape (..., 4)
            Generalised forces h (N m), friction not included.
        """
        qa, qda = np.broadcast_arrays(_vectors(q, NQ, "q"), _vectors(qd, NQ, "qd"))
        out = np.empty((NQ, *qa.shape[:-1]))
        _gen.bias(self._c, np.moveaxis(qa, -1, 0), np.moveaxis(qda, -1, 0), out)
        return np.moveaxis(out, 0, -1)

    def friction(self, qd: ArrayLike) -> FloatArray:
        """Smooth friction torques on θ_x and θ_y.

        Parameters
        ----------
        qd : array_like, shape (..., 4)
            Generalised velocities (rad/s); only θ̇_x, θ̇_y are used.

        Returns
        -------
        ndarray, shape (..., 2)
            [D_x, D_y] with D_i = D_c tanh(θ̇_i/ε) + D_v θ̇_i (N m) and
            ε = ``params.friction_smoothing``.
        """
        thd = _vectors(qd, NQ, "qd")[..., :NU]
        out: FloatArray = friction_torque(friction_constants(self.params), thd)
        return out

    def accelerations(self, q: ArrayLike, qd: ArrayLike, tau: ArrayLike) -> FloatArray:
        """Solve the equations of motion for q̈, friction included.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).
        qd : array_like, shape (..., 4)
            Generalised velocities (rad/s).
        tau : array_like, shape (..., 2)
            Drive torques [τ_x, τ_y] (N m).

        Returns
        -------
        ndarray, shape (..., 4)
            Generalised accelerations q̈ (rad/s²).
        """
        qa = _vectors(q, NQ, "q")
        qda = _vectors(qd, NQ, "qd")
        taua = _vectors(tau, NU, "tau")
        batch = np.broadcast_shapes(qa.shape[:-1], qda.shape[:-1], taua.shape[:-1])
        qa = np.broadcast_to(qa, (*batch, NQ))
        qda = np.broadcast_to(qda, (*batch, NQ))
        rhs = -self.bias(qa, qda)
        rhs[..., :NU] += taua - self.friction(qda)
        qdd = np.linalg.solve(self.mass_matrix(qa), rhs[..., None])[..., 0]
        return np.asarray(qdd, dtype=np.float64)

    def energy(self, q: ArrayLike, qd: ArrayLike) -> FloatArray:
        """Total mechanical energy T + V.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).
        qd : array_like, shape (..., 4)
            Generalised velocities (rad/s).

        Returns
        -------
        ndarray, shape (...)
            Energy (J); the potential is zero with the body COM at ball-centre
            height, V = m_b g ℓ_b cos φ_x cos φ_y.
        """
        qa, qda = np.broadcast_arrays(_vectors(q, NQ, "q"), _vectors(qd, NQ, "qd"))
        e = _gen.energy(self._c, np.moveaxis(qa, -1, 0), np.moveaxis(qda, -1, 0))
        return np.asarray(e, dtype=float)

    def ball_position(self, q: ArrayLike) -> FloatArray:
        """Ball position on the floor.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).

        Returns
        -------
        ndarray, shape (..., 2)
            [x, y] = r_w [θ_x + φ_x, θ_y + φ_y] (m), the ball centre's
            horizontal position (the ball centre is at height r_w).
        """
        qa = _vectors(q, NQ, "q")
        return self.params.ball_radius * (qa[..., :2] + qa[..., 2:])

    def body_axis(self, q: ArrayLike) -> FloatArray:
        """Unit vector from the ball centre toward the body centre of mass.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).

        Returns
        -------
        ndarray, shape (..., 3)
            R ẑ = (sin φ_x cos φ_y, sin φ_y, cos φ_x cos φ_y) in world axes
            (dimensionless).
        """
        qa = _vectors(q, NQ, "q")
        px, py = qa[..., 2], qa[..., 3]
        cy = np.cos(py)
        return np.stack([np.sin(px) * cy, np.sin(py), np.cos(px) * cy], axis=-1)

    def com_position(self, q: ArrayLike) -> FloatArray:
        """Body centre of mass in the world frame.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).

        Returns
        -------
        ndarray, shape (..., 3)
            [x, y, z] (m); z = r_w + ℓ_b cos φ_x cos φ_y above the floor.
        """
        qa = _vectors(q, NQ, "q")
        out = np.empty((3, *qa.shape[:-1]))
        _gen.com_position(self._c, np.moveaxis(qa, -1, 0), out)
        return np.moveaxis(out, 0, -1)

    def com_jacobian(self, q: ArrayLike) -> FloatArray:
        """Jacobian of the body centre of mass with respect to q.

        Parameters
        ----------
        q : array_like, shape (..., 4)
            Configuration (rad).

        Returns
        -------
        ndarray, shape (..., 3, 4)
            ∂p_C/∂q (m/rad); the COM velocity is ``com_jacobian(q) @ qd`` and a
            world force F on the COM has generalised force ``com_jacobian(q).T @ F``.
        """
        qa = _vectors(q, NQ, "q")
        out = np.empty((3, NQ, *qa.shape[:-1]))
        _gen.com_jacobian(self._c, np.moveaxis(qa, -1, 0), out)
        return np.moveaxis(out, (0, 1), (-2, -1))

    def linearize(self, *, viscous: bool = False) -> tuple[FloatArray, FloatArray]:
        """Linearise about upright rest (q = 0, q̇ = 0, τ = 0).

        Parameters
        ----------
        viscous : bool
            Include viscous friction. Coulomb friction is never included (it
            is not differentiable at rest; controllers feed it forward).

        Returns
        -------
        A : ndarray, shape (8, 8)
            State matrix for x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y]
            (1/s and 1/s²).
        B : ndarray, shape (8, 2)
            Input matrix for τ = [τ_x, τ_y] (rad/(s² N m) in the rate rows).

        Notes
        -----
        Coriolis terms are quadratic in q̇ and vanish to first order, and
        ∂G/∂q at upright is diag(0, 0, −m_b g ℓ_b, −m_b g ℓ_b), so the result
        is the two planar linearisations in the rows and columns of their
        planes.
        """
        p = self.params
        m0 = self.mass_matrix(np.zeros(NQ))
        stiffness = np.zeros((NQ, NQ))
        stiffness[2, 2] = stiffness[3, 3] = -p.body_mass * p.gravity * p.body_com_height
        damping = np.zeros((NQ, NQ))
        if viscous:
            damping[0, 0] = damping[1, 1] = p.viscous_friction
        minv = np.linalg.inv(m0)
        a = np.zeros((NX, NX))
        a[:NQ, NQ:] = np.eye(NQ)
        a[NQ:, :NQ] = -minv @ stiffness
        a[NQ:, NQ:] = -minv @ damping
        b = np.zeros((NX, NU))
        b[NQ:, :] = minv[:, :NU]
        return a, b
