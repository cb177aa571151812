"""Moving and new obstacles: people and carts, as discs on a path.

A :class:`MovingObstacle` is a disc that is *present* from ``appear`` to ``leave``
(s, episode time) and meanwhile moves along the polyline ``path`` at ``speed`` (m/s)
from its first point, stopping at the last (a single point: it stands still). The robot
does not know it in advance: the hybrid controller learns it when it comes within its
sensing range (:class:`gracenav.planning.repair.ObstacleSensing`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MovingObstacle", "moving_clearance"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MovingObstacle:
    """A disc obstacle that appears, moves along a path and leaves.

    Attributes
    ----------
    radius : float
        (m), > 0.
    path : tuple of (float, float)
        Waypoints (m); the disc's centre starts at the first.
    speed : float
        Along the path (m/s), >= 0; 0 with one waypoint for a standing obstacle.
    appear : float
        Time it appears (s); it starts along the path then.
    leave : float
        Time it disappears (s); ``inf``: never.
    name : str
    """

    radius: float
    path: tuple[tuple[float, float], ...]
    speed: float = 0.0
    appear: float = 0.0
    leave: float = math.inf
    name: str = "obstacle"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0.0):
            raise ValueError(f"radius must be positive and finite, got {self.radius!r}")
        if len(self.path) < 1:
            raise ValueError("path needs at least one point")
        if not (math.isfinite(self.speed) and self.speed >= 0.0):
            raise ValueError(f"speed must be >= 0 and finite, got {self.speed!r}")
        if not self.leave > self.appear:
            raise ValueError(f"leave ({self.leave}) must come after appear ({self.appear})")

    @property
    def _points(self) -> FloatArray:
        return np.asarray(self.path, dtype=float).reshape(-1, 2)

    @property
    def length(self) -> float:
        """Path length (m)."""
        pts = self._points
        return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))

    def present(self, t: ArrayLike) -> NDArray[np.bool_]:
        """Whether the obstacle exists at times ``t`` (s)."""
        t = np.asarray(t, dtype=float)
        return np.asarray((t >= self.appear) & (t < self.leave))

    def position(self, t: ArrayLike) -> FloatArray:
        """Centre (m) at times ``t`` (s), shape (..., 2); defined (clamped to the path's
        ends) also where the obstacle is not present."""
        t = np.asarray(t, dtype=float)
        pts = self._points
        if pts.shape[0] == 1 or self.speed == 0.0:
            return np.broadcast_to(pts[0], (*t.shape, 2)).copy()
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate(([0.0], np.cumsum(seg)))
        s = np.clip((t - self.appear) * self.speed, 0.0, cum[-1])
        x = np.interp(s, cum, pts[:, 0])
        y = np.interp(s, cum, pts[:, 1])
        return np.stack([x, y], axis=-1)

    def velocity(self, t: float) -> FloatArray:
        """Velocity (m/s) at time ``t`` (s): along the current segment, zero before it
        starts, at the end of the path and when absent."""
        if not bool(self.present(t)) or self.speed == 0.0 or len(self.path) < 2:
            return np.zeros(2)
        pts = self._points
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate(([0.0], np.cumsum(seg)))
        s = (t - self.appear) * self.speed
        if s >= cum[-1]:
            return np.zeros(2)
        k = int(np.searchsorted(cum, s, side="right") - 1)
        k = min(max(k, 0), seg.size - 1)
        if seg[k] == 0.0:
            return np.zeros(2)
        return (pts[k + 1] - pts[k]) / seg[k] * self.speed


def moving_clearance(
    obstacles: Sequence[MovingObstacle], xy: ArrayLike, t: ArrayLike
) -> FloatArray:
    """Distance (m) from points ``xy`` (N, 2) at times ``t`` (N,) to the nearest present
    moving obstacle's edge; ``inf`` where none is present. Negative inside one."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    t = np.asarray(t, dtype=float).reshape(-1)
    out = np.full(xy.shape[0], np.inf)
    for ob in obstacles:
        d = np.linalg.norm(xy - ob.position(t), axis=1) - ob.radius
        out = np.where(ob.present(t), np.minimum(out, d), out)
    return out
