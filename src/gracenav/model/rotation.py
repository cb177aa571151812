"""Rotations of the plane: the dynamics are invariant under them, so a primitive, a
policy or a domain turned by a quarter turn (the lattice's orientations) or by any
angle (catches placed at the state) is the same motion turned.

Quarter turns are exact: the matrix entries are 0 and ±1, so rotated states compare
exactly. Every rotation of the package is one of these functions."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["QUARTER_TURNS", "quarter_turn", "rotate_pairs", "rotate_pairs_by"]

FloatArray = NDArray[np.float64]


def quarter_turn(k: int) -> FloatArray:
    """Exact rotation matrix by k · 90° counter-clockwise, shape (2, 2)."""
    k = int(k) % 4
    c = (1.0, 0.0, -1.0, 0.0)[k]
    s = (0.0, 1.0, 0.0, -1.0)[k]
    return np.array([[c, -s], [s, c]])


#: The four quarter turns, shape (4, 2, 2) (read-only): ``QUARTER_TURNS[k]`` is
#: :func:`quarter_turn` ``(k)``.
QUARTER_TURNS: FloatArray = np.stack([quarter_turn(k) for k in range(4)])
QUARTER_TURNS.setflags(write=False)


def rotate_pairs(a: ArrayLike, k: int, *, out: FloatArray | None = None) -> FloatArray:
    """Rotate every consecutive (x, y) pair of the last axis of ``a`` by k·90° (exact).

    Model states [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y], torques [τ_x, τ_y] and
    position states [x, y, ẋ, ẏ, (ẍ, ÿ)] all consist of such pairs; (..., 2) vectors
    are one pair. ``out``: an array of ``a``'s shape to write the result into (not
    ``a`` itself).
    """
    arr = np.asarray(a, dtype=np.float64)
    result = np.empty_like(arr) if out is None else out
    if result.shape != arr.shape:
        raise ValueError(f"out has shape {result.shape}, not the input's {arr.shape}")
    if out is not None and np.may_share_memory(out, arr):
        raise ValueError("out must not overlap the input (a pair is read after it is written)")
    pairs = arr.reshape(*arr.shape[:-1], arr.shape[-1] // 2, 2)
    turned = result.reshape(pairs.shape)
    x, y = pairs[..., 0], pairs[..., 1]
    k = int(k) % 4  # (x, y) -> (c x - s y, s x + c y) with c, s in {0, ±1}: swaps and signs
    if k == 0:
        turned[...] = pairs
    elif k == 1:
        np.negative(y, out=turned[..., 0])
        turned[..., 1] = x
    elif k == 2:
        np.negative(x, out=turned[..., 0])
        np.negative(y, out=turned[..., 1])
    else:
        turned[..., 0] = y
        np.negative(x, out=turned[..., 1])
    return result


def rotate_pairs_by(a: ArrayLike, angle: float) -> FloatArray:
    """Rotate every consecutive (x, y) pair of the last axis of ``a`` by ``angle`` (rad),
    counter-clockwise: :func:`rotate_pairs` for any angle. For model states the lean
    pair is rotated like a vector, which is exact for the position state and first
    order in the lean (see :meth:`gracenav.policies.SampledPrimitive.rotated`)."""
    arr = np.asarray(a, dtype=np.float64)
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    pairs = arr.reshape(*arr.shape[:-1], arr.shape[-1] // 2, 2)
    out: FloatArray = (pairs @ rot.T).reshape(arr.shape)
    return out
