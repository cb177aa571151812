"""The shape dynamics the shape trajectory planner integrates, compiled: the ball's
angles driven by a desired body lean acceleration (3D, planar or linearised model),
and the inverse dynamics giving the torques of a planned trajectory."""

from __future__ import annotations

from typing import Literal

import numpy as np
from numba import njit

from gracenav._kernels import bias as _bias3
from gracenav._kernels import friction as _friction
from gracenav._kernels import mass_matrix as _mm3
from gracenav.model.planar import PlanarBallbot
from gracenav.params import BallbotParams
from gracenav.primitives.references import FloatArray

__all__ = ["ModelName"]

ModelName = Literal["3d", "planar", "linear"]

_KIND = {"3d": 0, "planar": 1, "linear": 2}


def _model_constants(params: BallbotParams, kind: int) -> FloatArray:
    if kind == 0:
        from gracenav.model.ballbot3d import Ballbot3D

        return np.ascontiguousarray(Ballbot3D(params).constants(), dtype=float)
    return np.array(
        [
            params.ball_radius,
            params.alpha(),
            params.beta(),
            PlanarBallbot(params, "x").gamma,
            PlanarBallbot(params, "y").gamma,
            params.gravity,
        ]
    )


# --------------------------------------------------------------------------------------
# Compiled kernels
# --------------------------------------------------------------------------------------
@njit(cache=True)
def _shape_accel(kind, c, q, qd, phdd, wm, wb, out):
    """θ̈ (2,) from the shape rows given q (4,), q̇ (4,) and φ̈ (2,)."""
    if kind == 0:
        _mm3(c, q, wm)
        _bias3(c, q, qd, wb)
        r0 = -(wm[2, 2] * phdd[0] + wm[2, 3] * phdd[1] + wb[2])
        r1 = -(wm[3, 2] * phdd[0] + wm[3, 3] * phdd[1] + wb[3])
        a = wm[2, 0]
        b = wm[2, 1]
        cc = wm[3, 0]
        d = wm[3, 1]
        det = a * d - b * cc
        out[0] = (d * r0 - b * r1) / det
        out[1] = (a * r1 - cc * r0) / det
    else:
        r = c[0]
        alpha = c[1]
        beta = c[2]
        g = c[5]
        for i in range(2):
            ph = q[2 + i]
            phd = qd[2 + i]
            gam = c[3 + i]
            if kind == 1:
                cb = beta * np.cos(ph)
                sb = beta * np.sin(ph)
                out[i] = (sb * g / r + sb * phd * phd - (alpha + gam + 2.0 * cb) * phdd[i]) / (
                    alpha + cb
                )
            else:
                out[i] = (beta * ph * g / r - (alpha + gam + 2.0 * beta) * phdd[i]) / (alpha + beta)


@njit(cache=True, nogil=True)
def _integrate(kind, c, ph, phd, phdd, s0, h, th, thd, thdd):
    """RK4 of (θ, θ̇) under the dynamic constraint.

    ``ph``, ``phd``, ``phdd`` (2N+1, 2) are φ, φ̇, φ̈ at the half-step grid;
    ``s0`` (4,) = [θ_x, θ_y, θ̇_x, θ̇_y] at t = 0; outputs (N+1, 2) at the nodes.
    """
    n = th.shape[0] - 1
    wm = np.empty((4, 4))
    wb = np.empty(4)
    q = np.empty(4)
    qd = np.empty(4)
    a = np.empty(2)
    s = s0.copy()
    st = np.empty(4)
    k1 = np.empty(4)
    k2 = np.empty(4)
    k3 = np.empty(4)
    for k in range(n + 1):
        j = 2 * k
        q[0] = s[0]
        q[1] = s[1]
        q[2] = ph[j, 0]
        q[3] = ph[j, 1]
        qd[0] = s[2]
        qd[1] = s[3]
        qd[2] = phd[j, 0]
        qd[3] = phd[j, 1]
        _shape_accel(kind, c, q, qd, phdd[j], wm, wb, a)
        th[k, 0] = s[0]
        th[k, 1] = s[1]
        thd[k, 0] = s[2]
        thd[k, 1] = s[3]
        thdd[k, 0] = a[0]
        thdd[k, 1] = a[1]
        if k == n:
            break
        k1[0] = s[2]
        k1[1] = s[3]
        k1[2] = a[0]
        k1[3] = a[1]
        # stage 2 and 3 at the half step, stage 4 at the next node
        for stage in range(3):
            jj = j + 1 if stage < 2 else j + 2
            hh = 0.5 * h if stage < 2 else h
            kin = k1 if stage == 0 else (k2 if stage == 1 else k3)
            for i in range(4):
                st[i] = s[i] + hh * kin[i]
            q[0] = st[0]
            q[1] = st[1]
            q[2] = ph[jj, 0]
            q[3] = ph[jj, 1]
            qd[0] = st[2]
            qd[1] = st[3]
            qd[2] = phd[jj, 0]
            qd[3] = phd[jj, 1]
            _shape_accel(kind, c, q, qd, phdd[jj], wm, wb, a)
            if stage == 0:
                k2[0] = st[2]
                k2[1] = st[3]
                k2[2] = a[0]
                k2[3] = a[1]
            elif stage == 1:
                k3[0] = st[2]
                k3[1] = st[3]
                k3[2] = a[0]
                k3[3] = a[1]
            else:
                for i in range(2):
                    s[i] += h * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + st[2 + i]) / 6.0
                for i in range(2):
                    s[2 + i] += h * (k1[2 + i] + 2.0 * k2[2 + i] + 2.0 * k3[2 + i] + a[i]) / 6.0


@njit(cache=True)
def _inverse_dynamics(kind, c, fr, q, qd, phdd, qdd, tau):
    """θ̈ from the shape rows and τ from the position rows (friction included).

    ``q``, ``qd`` (M, 4), ``phdd`` (M, 2); outputs ``qdd`` (M, 4), ``tau`` (M, 2).
    """
    wm = np.empty((4, 4))
    wb = np.empty(4)
    a = np.empty(2)
    for m in range(q.shape[0]):
        _shape_accel(kind, c, q[m], qd[m], phdd[m], wm, wb, a)
        qdd[m, 0] = a[0]
        qdd[m, 1] = a[1]
        qdd[m, 2] = phdd[m, 0]
        qdd[m, 3] = phdd[m, 1]
        if kind == 0:
            # wm, wb hold M and the bias at q[m], qd[m]
            for i in range(2):
                s = wb[i]
                for j in range(4):
                    s += wm[i, j] * qdd[m, j]
                tau[m, i] = s + _friction(fr, qd[m, i])
        else:
            alpha = c[1]
            beta = c[2]
            for i in range(2):
                ph = q[m, 2 + i]
                phd = qd[m, 2 + i]
                if kind == 1:
                    t = alpha * a[i] + (alpha + beta * np.cos(ph)) * phdd[m, i]
                    t -= beta * np.sin(ph) * phd * phd
                else:
                    t = alpha * a[i] + (alpha + beta) * phdd[m, i]
                tau[m, i] = t + _friction(fr, qd[m, i])
