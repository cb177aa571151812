"""Quintic Hermite interpolation: on each interval, the quintic with given value, first
and second derivative at both ends.

On the unit interval the interpolant is Σ_k H_k(s) e_k with e = (p0, p0', p0'', p1,
p1', p1'') and the basis polynomials H_k of :data:`QUINTIC_HERMITE`; on an interval of
length h the derivatives are scaled, e = (p0, h p0', h² p0'', p1, h p1', h² p1'').

Two evaluations of this one basis:

* :func:`quintic_hermite_basis`: the table of H_k and their derivatives at given points
  of [0, 1], which the compiled rebuild of stored primitives combines
  (:func:`gracenav._kernels.rebuild_fine`, stride fractions j/stride);
* :func:`quintic_hermite`: interpolation of node values at arbitrary times (the shape
  planner's ball angles between integration nodes).

They round differently (the table by a matrix product of powers, the interpolation by
the polynomials written out): both are kept as they are so that the primitives rebuilt
from a palette file and the shape planner's samples stay the same to the last bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["QUINTIC_HERMITE", "quintic_hermite", "quintic_hermite_basis"]

FloatArray = NDArray[np.float64]

#: Coefficients of the quintic Hermite basis on [0, 1]: row k holds H_k(s) = Σ_j c_kj s^j
#: for e_k in (p0, p0', p0'', p1, p1', p1'').
QUINTIC_HERMITE = np.array(
    [
        [1, 0, 0, -10, 15, -6],
        [0, 1, 0, -6, 8, -3],
        [0, 0, 0.5, -1.5, 1.5, -0.5],
        [0, 0, 0, 10, -15, 6],
        [0, 0, 0, -4, 7, -3],
        [0, 0, 0, 0.5, -1, 0.5],
    ]
)
QUINTIC_HERMITE.flags.writeable = False


def quintic_hermite_basis(s: FloatArray) -> FloatArray:
    """The basis H_k at the points ``s`` (N,) of [0, 1]: values, first and second
    derivatives, shape (3, N, 6) (last axis: k as in :data:`QUINTIC_HERMITE`)."""
    c = QUINTIC_HERMITE
    powers = np.arange(6)
    sp = s[:, None] ** powers[None, :]
    d1 = np.zeros_like(sp)
    d1[:, 1:] = powers[1:] * s[:, None] ** (powers[1:] - 1)
    d2 = np.zeros_like(sp)
    d2[:, 2:] = powers[2:] * (powers[2:] - 1) * s[:, None] ** (powers[2:] - 2)
    return np.stack([sp @ c.T, d1 @ c.T, d2 @ c.T])


def quintic_hermite(
    t: FloatArray, h: float, y: FloatArray, yd: FloatArray, ydd: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Interpolate node values at times ``t`` (M,), value and first derivative.

    ``y``, ``yd``, ``ydd`` (N+1, D) are the values and first and second derivatives at
    the nodes k h, k = 0..N; ``t`` lies in [0, N h]. Returns two arrays (M, D); exact
    at the nodes.
    """
    n = y.shape[0] - 1
    k = np.clip(np.floor(t / h).astype(np.int64), 0, max(n - 1, 0))
    u = (t - k * h) / h
    u = u[:, None]
    p0, p1 = y[k], y[np.minimum(k + 1, n)]
    v0, v1 = yd[k] * h, yd[np.minimum(k + 1, n)] * h
    a0, a1 = ydd[k] * h * h, ydd[np.minimum(k + 1, n)] * h * h
    u2 = u * u
    u3 = u2 * u
    u4 = u3 * u
    u5 = u4 * u
    # The rows of QUINTIC_HERMITE written out (h3 is row 5, h5 row 3), and their derivatives
    h0 = 1 - 10 * u3 + 15 * u4 - 6 * u5
    h1 = u - 6 * u3 + 8 * u4 - 3 * u5
    h2 = 0.5 * (u2 - 3 * u3 + 3 * u4 - u5)
    h3 = 0.5 * (u3 - 2 * u4 + u5)
    h4 = -4 * u3 + 7 * u4 - 3 * u5
    h5 = 10 * u3 - 15 * u4 + 6 * u5
    d0 = -30 * u2 + 60 * u3 - 30 * u4
    d1 = 1 - 18 * u2 + 32 * u3 - 15 * u4
    d2 = 0.5 * (2 * u - 9 * u2 + 12 * u3 - 5 * u4)
    d3 = 0.5 * (3 * u2 - 8 * u3 + 5 * u4)
    d4 = -12 * u2 + 28 * u3 - 15 * u4
    d5 = 30 * u2 - 60 * u3 + 30 * u4
    val = h0 * p0 + h1 * v0 + h2 * a0 + h3 * a1 + h4 * v1 + h5 * p1
    rate = (d0 * p0 + d1 * v0 + d2 * a0 + d3 * a1 + d4 * v1 + d5 * p1) / h
    return val, rate
