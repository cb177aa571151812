"""Position states and model states: the ball's position and velocity r (θ + φ),
r (θ̇ + φ̇) of the 3D model's state, and back (upright, or at a given lean)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["position_state", "state_from_position"]

FloatArray = NDArray[np.float64]


def position_state(states: ArrayLike, radius: float) -> FloatArray:
    """Position states [x, y, ẋ, ẏ] (m, m/s) of model states, shape (..., 4)."""
    s = np.asarray(states, dtype=float)
    return radius * np.concatenate([s[..., 0:2] + s[..., 2:4], s[..., 4:6] + s[..., 6:8]], axis=-1)


def state_from_position(
    p: ArrayLike, radius: float, lean: ArrayLike = (0.0, 0.0), lean_rate: ArrayLike = (0.0, 0.0)
) -> FloatArray:
    """Model state (..., 8) with position state ``p`` (..., 4), lean (rad) and lean rate (rad/s)."""
    p = np.asarray(p, dtype=float)
    lean = np.broadcast_to(np.asarray(lean, dtype=float), (*p.shape[:-1], 2))
    rate = np.broadcast_to(np.asarray(lean_rate, dtype=float), (*p.shape[:-1], 2))
    return np.concatenate(
        [p[..., 0:2] / radius - lean, lean, p[..., 2:4] / radius - rate, rate], axis=-1
    )
