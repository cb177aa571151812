"""Obstacle shapes of inline maps: rectangles, circles and simple polygons.

Shapes are exact, closed sets in the world plane (m). Each validates itself on
construction (finite coordinates, positive size, a simple polygon) and answers
point-membership queries on arrays of points of shape (..., 2) holding (x, y) in metres.
Rasterising them onto a grid is :mod:`gracenav.world.occupancy`'s job.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav._util.validate import show
from gracenav.errors import ConfigError, MapError

__all__ = ["MAX_COORDINATE", "MAX_POLYGON_POINTS", "Circle", "Polygon", "Rectangle", "Shape"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

_EPS = 1e-9  # m; points this close to a shape's boundary count as inside (closed shapes)
_PAIR_CHUNK = 1 << 18  # point/edge pairs evaluated at once in polygon tests

#: Largest coordinate or radius magnitude (m) of a shape. Far beyond any map (the cell
#: budget bounds a map's extent), it keeps the geometry's products of coordinates finite.
MAX_COORDINATE = 1e12

#: Most points a polygon lists (a repeated first point at the end included). Checking
#: that a polygon is simple compares every pair of its edges: ≈ 0.4 s and ≈ 65 MiB at
#: 2000 points (tracemalloc), growing with the square of the count.
MAX_POLYGON_POINTS = 2000


def _points_array(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=float)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ConfigError(f"points must have shape (..., 2) holding (x, y) in m, got {p.shape}")
    return p


def _finite_pair(value: Sequence[float], what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise MapError(f"{what} must be a pair of numbers (x, y) in m, got {show(value)}") from None
    except OverflowError:
        x = y = math.inf
    if not (math.isfinite(x) and math.isfinite(y)):
        raise MapError(f"{what} must be finite, got ({x}, {y})")
    if max(abs(x), abs(y)) > MAX_COORDINATE:
        raise MapError(
            f"{what} ({x:g}, {y:g}) is beyond ±{MAX_COORDINATE:g} m; give coordinates in metres"
        )
    return (x, y)


@dataclass(frozen=True)
class Rectangle:
    """Axis-aligned rectangle obstacle, closed: ``[x_min, x_max] × [y_min, y_max]``.

    Attributes
    ----------
    min_corner : tuple of float
        Lower-left corner (x_min, y_min), m.
    max_corner : tuple of float
        Upper-right corner (x_max, y_max), m; strictly greater than ``min_corner``.
    """

    min_corner: tuple[float, float]
    max_corner: tuple[float, float]

    def __post_init__(self) -> None:
        lo = _finite_pair(self.min_corner, "rectangle min")
        hi = _finite_pair(self.max_corner, "rectangle max")
        if not (hi[0] > lo[0] and hi[1] > lo[1]):
            raise MapError(
                f"rectangle max {hi} must exceed min {lo} in both x and y; "
                "give the lower-left corner as min and the upper-right one as max"
            )
        object.__setattr__(self, "min_corner", lo)
        object.__setattr__(self, "max_corner", hi)

    @property
    def area(self) -> float:
        """Area (m²)."""
        return (self.max_corner[0] - self.min_corner[0]) * (self.max_corner[1] - self.min_corner[1])

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Bounding box ((x_min, y_min), (x_max, y_max)), m."""
        return self.min_corner, self.max_corner

    def contains(self, points: ArrayLike) -> BoolArray:
        """Whether each point (..., 2) (m) is inside or on the boundary. Shape (...)."""
        p = _points_array(points)
        (x0, y0), (x1, y1) = self.min_corner, self.max_corner
        x, y = p[..., 0], p[..., 1]
        return (x >= x0 - _EPS) & (x <= x1 + _EPS) & (y >= y0 - _EPS) & (y <= y1 + _EPS)

    def to_dict(self) -> dict[str, Any]:
        """The inline-map description ``{"rectangle": {"min": [x, y], "max": [x, y]}}``."""
        return {"rectangle": {"min": list(self.min_corner), "max": list(self.max_corner)}}


@dataclass(frozen=True)
class Circle:
    """Disc obstacle, closed: ``{p : |p − center| <= radius}``.

    Attributes
    ----------
    center : tuple of float
        Centre (x, y), m.
    radius : float
        Radius (m), > 0.
    """

    center: tuple[float, float]
    radius: float

    def __post_init__(self) -> None:
        c = _finite_pair(self.center, "circle center")
        try:
            r = float(self.radius)
        except (TypeError, ValueError):
            raise MapError(f"circle radius must be a number (m), got {show(self.radius)}") from None
        except OverflowError:
            r = math.inf
        if not (math.isfinite(r) and 0.0 < r <= MAX_COORDINATE):
            raise MapError(
                f"circle radius must be a positive, finite number of metres up to "
                f"{MAX_COORDINATE:g}, got {r:g}"
            )
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "radius", r)

    @property
    def area(self) -> float:
        """Area (m²)."""
        return math.pi * self.radius**2

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Bounding box ((x_min, y_min), (x_max, y_max)), m."""
        (x, y), r = self.center, self.radius
        return (x - r, y - r), (x + r, y + r)

    def contains(self, points: ArrayLike) -> BoolArray:
        """Whether each point (..., 2) (m) is inside or on the boundary. Shape (...)."""
        p = _points_array(points)
        d = np.hypot(p[..., 0] - self.center[0], p[..., 1] - self.center[1])
        return d <= self.radius + _EPS

    def to_dict(self) -> dict[str, Any]:
        """The inline-map description ``{"circle": {"center": [x, y], "radius": r}}``."""
        return {"circle": {"center": list(self.center), "radius": self.radius}}


def _orient(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """Signed doubled area of triangles (a, b, c), arrays (..., 2): > 0 counter-clockwise."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (
        c[..., 0] - a[..., 0]
    )


def _on_segment(a: FloatArray, b: FloatArray, c: FloatArray) -> BoolArray:
    """Whether c, known to be collinear with segment ab, lies within its bounding box."""
    return (
        (np.minimum(a[..., 0], b[..., 0]) <= c[..., 0])
        & (c[..., 0] <= np.maximum(a[..., 0], b[..., 0]))
        & (np.minimum(a[..., 1], b[..., 1]) <= c[..., 1])
        & (c[..., 1] <= np.maximum(a[..., 1], b[..., 1]))
    )


def _segments_intersect(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray) -> BoolArray:
    """Whether closed segments ab and cd (arrays (..., 2)) share a point: a proper crossing
    (each segment's ends strictly on both sides of the other) or a touching / collinear
    overlap."""
    o1, o2 = np.sign(_orient(a, b, c)), np.sign(_orient(a, b, d))
    o3, o4 = np.sign(_orient(c, d, a)), np.sign(_orient(c, d, b))
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    touch = (
        ((o1 == 0) & _on_segment(a, b, c))
        | ((o2 == 0) & _on_segment(a, b, d))
        | ((o3 == 0) & _on_segment(c, d, a))
        | ((o4 == 0) & _on_segment(c, d, b))
    )
    return proper | touch


def _polygon_defect(pts: FloatArray) -> str | None:
    """Why the closed polygon ``pts`` (n, 2) is not simple, or None if it is."""
    n = len(pts)
    nxt = np.roll(pts, -1, axis=0)
    edge = nxt - pts
    short = np.flatnonzero(np.hypot(edge[:, 0], edge[:, 1]) == 0.0)
    if short.size:
        return f"points {short[0]} and {(short[0] + 1) % n} coincide (zero-length edge)"
    # Adjacent edges overlap when the second folds back along the first.
    nxt_edge = np.roll(edge, -1, axis=0)
    cross = edge[:, 0] * nxt_edge[:, 1] - edge[:, 1] * nxt_edge[:, 0]
    dot = np.sum(edge * nxt_edge, axis=1)
    fold = np.flatnonzero((cross == 0.0) & (dot < 0.0))
    if fold.size:
        i = int(fold[0])
        return f"edges {i} and {(i + 1) % n} fold back onto each other"
    # Non-adjacent edges must not meet.
    ii, jj = np.triu_indices(n, k=2)
    keep = ~((ii == 0) & (jj == n - 1))
    ii, jj = ii[keep], jj[keep]
    for s in range(0, len(ii), _PAIR_CHUNK):
        i, j = ii[s : s + _PAIR_CHUNK], jj[s : s + _PAIR_CHUNK]
        hit = np.flatnonzero(_segments_intersect(pts[i], nxt[i], pts[j], nxt[j]))
        if hit.size:
            return f"edges {i[hit[0]]} and {j[hit[0]]} intersect"
    area2 = float(np.sum(pts[:, 0] * nxt[:, 1] - nxt[:, 0] * pts[:, 1]))
    scale = float(np.max(np.abs(pts - pts.mean(axis=0)))) ** 2
    if abs(area2) <= 1e-12 * max(scale, 1e-300):
        return "it has zero area (all points on one line)"
    return None


@dataclass(frozen=True)
class Polygon:
    """Simple (non-self-intersecting) polygon obstacle, closed, vertices in either order.

    Attributes
    ----------
    points : tuple of (float, float)
        Vertices (x, y), m, at least 3; the closing edge from the last to the first vertex
        is implied (a repeated first vertex at the end is dropped).
    """

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        try:
            raw = list(self.points)
        except TypeError:
            raise MapError(
                f"polygon points must be a list of (x, y) pairs, got {show(self.points)}"
            ) from None
        if len(raw) > MAX_POLYGON_POINTS:
            raise MapError(
                f"a polygon has at most {MAX_POLYGON_POINTS} points, got {len(raw)}; split it "
                "into several polygons or simplify its outline"
            )
        pts = [_finite_pair(p, f"polygon point {k}") for k, p in enumerate(raw)]
        if len(pts) > 1 and pts[0] == pts[-1]:
            pts = pts[:-1]
        if len(pts) < 3:
            raise MapError(
                f"a polygon needs at least 3 distinct points, got {len(pts)}; "
                "add vertices or use a circle/rectangle"
            )
        defect = _polygon_defect(np.array(pts))
        if defect is not None:
            raise MapError(
                f"polygon is not simple: {defect}; list the vertices in order around the "
                "boundary without crossing edges, or split it into several polygons"
            )
        object.__setattr__(self, "points", tuple(pts))

    @property
    def vertices(self) -> FloatArray:
        """Vertices as an array, shape (n, 2), m."""
        return np.array(self.points, dtype=float)

    @property
    def area(self) -> float:
        """Area (m²), by the shoelace formula."""
        p = self.vertices
        q = np.roll(p, -1, axis=0)
        return 0.5 * abs(float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])))

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Bounding box ((x_min, y_min), (x_max, y_max)), m."""
        p = self.vertices
        lo, hi = p.min(axis=0), p.max(axis=0)
        return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))

    def contains(self, points: ArrayLike) -> BoolArray:
        """Whether each point (..., 2) (m) is inside or on the boundary (even-odd crossing
        rule; boundary within 1e-9 m). Shape (...)."""
        p = _points_array(points)
        flat = p.reshape(-1, 2)
        v = self.vertices
        w = np.roll(v, -1, axis=0)
        d = w - v
        len2 = np.sum(d * d, axis=1)
        out = np.empty(len(flat), dtype=bool)
        step = max(1, _PAIR_CHUNK // len(v))
        for s in range(0, len(flat), step):
            x = flat[s : s + step, 0:1]
            y = flat[s : s + step, 1:2]
            straddle = (v[:, 1] > y) != (w[:, 1] > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_cross = v[:, 0] + (y - v[:, 1]) * d[:, 0] / d[:, 1]
            inside = np.count_nonzero(straddle & (x < x_cross), axis=1) % 2 == 1
            t = np.clip(((x - v[:, 0]) * d[:, 0] + (y - v[:, 1]) * d[:, 1]) / len2, 0.0, 1.0)
            near = np.hypot(x - v[:, 0] - t * d[:, 0], y - v[:, 1] - t * d[:, 1]) <= _EPS
            out[s : s + step] = inside | near.any(axis=1)
        return out.reshape(p.shape[:-1])

    def to_dict(self) -> dict[str, Any]:
        """The inline-map description ``{"polygon": {"points": [[x, y], ...]}}``."""
        return {"polygon": {"points": [list(q) for q in self.points]}}


Shape: TypeAlias = Rectangle | Circle | Polygon
"""Any obstacle shape of an inline map."""
