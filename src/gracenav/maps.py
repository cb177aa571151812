"""Maps of the world: occupancy grids from ROS map_server files or from inline geometry.

A :class:`WorldMap` is a 2D occupancy grid (paper Sec. IV-A: motion policies are
instantiated on a map M and kept only where they are obstacle free). It comes from

* a ROS ``map_server`` map: a YAML file naming a PGM (P2/P5, 8 or 16 bit) or PNG image,
  read with map_server's threshold semantics; or
* inline geometry: map bounds and rectangle / circle / polygon obstacles in metres,
  given as a mapping or a YAML/JSON file, rasterised at a chosen resolution (the exact
  shapes are kept for plotting).

Conventions (SI units throughout): ``origin`` is the world position (m) of the lower-left
corner of cell (0, 0); cell (i, j) (row i, column j) covers
``[x0 + j·res, x0 + (j+1)·res) × [y0 + i·res, y0 + (i+1)·res)``, so row 0 is the lowest y.
Image row 0 is the *top* of a ROS map and is flipped on loading. Points are arrays of
shape (..., 2) holding (x, y) in metres.

Unknown cells (neither free nor occupied by map_server's thresholds) count as occupied:
a robot must not plan through space nobody has seen.
"""

from __future__ import annotations

import itertools
import json
import math
import numbers
import os
import re
import struct
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from gracenav._io import atomic_write_bytes, atomic_write_text
from gracenav.errors import ConfigError, MapError

__all__ = [
    "DEFAULT_RESOLUTION",
    "Circle",
    "Polygon",
    "Rectangle",
    "Shape",
    "WorldMap",
    "load_map",
    "office_map",
    "read_pgm",
    "save_ros_map",
    "write_pgm",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

#: Rasterisation resolution (m per cell) of inline maps that do not give one.
DEFAULT_RESOLUTION = 0.05

INLINE = "inline map"
"""Name used in error messages for maps given as a mapping rather than a file."""

_EPS = 1e-9  # m; points this close to a shape's boundary count as inside (closed shapes)
_MAX_CELLS = 100_000_000  # refuse grids that would need gigabytes of memory
_PAIR_CHUNK = 1 << 18  # point/edge pairs evaluated at once in polygon tests

_ROS_REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_ROS_OPTIONAL = ("mode",)
_ROS_MODES = ("trinary", "scale", "raw")
_GEOMETRY_REQUIRED = ("bounds",)
_GEOMETRY_OPTIONAL = ("obstacles", "resolution", "name")
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "rectangle": ("min", "max"),
    "circle": ("center", "radius"),
    "polygon": ("points",),
}


# ----------------------------------------------------------------------------------------
# Shapes
# ----------------------------------------------------------------------------------------


def _points_array(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=float)
    if p.ndim == 0 or p.shape[-1] != 2:
        raise ConfigError(f"points must have shape (..., 2) holding (x, y) in m, got {p.shape}")
    return p


def _finite_pair(value: Sequence[float], what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise MapError(f"{what} must be a pair of numbers (x, y) in m, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise MapError(f"{what} must be finite, got ({x}, {y})")
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
            raise MapError(f"circle radius must be a number (m), got {self.radius!r}") from None
        if not (math.isfinite(r) and r > 0.0):
            raise MapError(f"circle radius must be a positive, finite number of metres, got {r}")
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
                f"polygon points must be a list of (x, y) pairs, got {self.points!r}"
            ) from None
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


# ----------------------------------------------------------------------------------------
# The map
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False, repr=False)
class WorldMap:
    """An occupancy grid of the world, immutable.

    Attributes
    ----------
    origin : ndarray, shape (2,)
        World position (x, y) (m) of the lower-left corner of cell (0, 0).
    resolution : float
        Cell side (m), > 0.
    occupied : ndarray of bool, shape (ny, nx)
        True where the cell is an obstacle or unknown; row 0 is the lowest y, column 0
        the lowest x. Read-only.
    name : str
        Display name (the file's stem, the inline map's ``name`` or ``"map"``).
    source : str
        Where the map came from: a file path or ``"inline map"``.
    shapes : tuple of Shape or None
        The exact obstacles when the map was built from geometry (for plotting), else None.
    unknown : ndarray of bool, shape (ny, nx), or None
        Cells map_server would call unknown (a subset of ``occupied``), or None when the
        map has none by construction. Read-only.

    Notes
    -----
    Maps compare by identity (``eq=False``): grids are large arrays. The clearance field
    is computed on first use and cached on the instance.
    """

    origin: FloatArray
    resolution: float
    occupied: BoolArray
    name: str = "map"
    source: str = INLINE
    shapes: tuple[Shape, ...] | None = None
    unknown: BoolArray | None = None
    _cache: dict[str, Any] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        where = self.source
        origin = np.array(self.origin, dtype=float)
        if origin.shape != (2,) or not np.all(np.isfinite(origin)):
            raise MapError(f"{where}: map origin must be a finite (x, y) pair in m, got {origin}")
        res = self.resolution
        if not _is_real(res) or not (math.isfinite(float(res)) and float(res) > 0.0):
            raise MapError(f"{where}: map resolution must be a positive number of m, got {res!r}")
        occ = np.array(self.occupied, dtype=bool)
        if occ.ndim != 2 or occ.shape[0] < 1 or occ.shape[1] < 1:
            raise MapError(f"{where}: occupancy grid must be 2D and non-empty, got {occ.shape}")
        origin.setflags(write=False)
        occ.setflags(write=False)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "resolution", float(res))
        object.__setattr__(self, "occupied", occ)
        if self.unknown is not None:
            unk = np.array(self.unknown, dtype=bool)
            if unk.shape != occ.shape:
                raise MapError(f"{where}: unknown mask {unk.shape} must match grid {occ.shape}")
            if np.any(unk & ~occ):
                raise MapError(f"{where}: unknown cells must also be marked occupied")
            unk.setflags(write=False)
            object.__setattr__(self, "unknown", unk)
        if self.shapes is not None:
            shapes = tuple(self.shapes)
            bad = [s for s in shapes if not isinstance(s, Rectangle | Circle | Polygon)]
            if bad:
                raise MapError(
                    f"{where}: shapes must be Rectangle, Circle or Polygon, got {bad[0]!r}"
                )
            object.__setattr__(self, "shapes", shapes)

    # -- construction ----------------------------------------------------------------

    @classmethod
    def from_shapes(
        cls,
        bounds: ArrayLike,
        shapes: Sequence[Shape] = (),
        *,
        resolution: float = DEFAULT_RESOLUTION,
        name: str = "map",
        source: str = INLINE,
    ) -> WorldMap:
        """Rasterise obstacles on a grid: a cell is occupied iff its centre is inside (or on
        the boundary of) some shape.

        Parameters
        ----------
        bounds : array_like, shape (2, 2)
            ((x_min, y_min), (x_max, y_max)), m; each side a whole number of cells.
        shapes : sequence of Shape
            Obstacles; each must lie entirely inside ``bounds`` and contain at least one
            cell centre (an obstacle thinner than a cell could otherwise vanish).
        resolution : float
            Cell side (m), > 0.
        name, source : str
            Display name and provenance (used in error messages).

        Raises
        ------
        MapError
            If the bounds, resolution or any shape is invalid.
        """
        where = source
        try:
            b = np.asarray(bounds, dtype=float)
        except (TypeError, ValueError, OverflowError):
            b = np.full(1, np.nan)
        if b.shape != (2, 2) or not np.all(np.isfinite(b)):
            raise MapError(f"{where}: 'bounds' must be [[xmin, ymin], [xmax, ymax]] in m")
        _check_positive(resolution, where, "resolution", "m")
        res = float(resolution)
        if not (b[1, 0] > b[0, 0] and b[1, 1] > b[0, 1]):
            raise MapError(
                f"{where}: 'bounds' max {tuple(b[1])} must exceed min {tuple(b[0])} in x and y; "
                "give [[xmin, ymin], [xmax, ymax]]"
            )
        counts = []
        for axis, label in ((0, "width"), (1, "height")):
            span = b[1, axis] - b[0, axis]
            cells = span / res
            if not cells <= _MAX_CELLS:
                raise MapError(
                    f"{where}: the map would be {cells:g} cells along its {label} (limit "
                    f"{_MAX_CELLS} cells in all); use a coarser 'resolution' or smaller 'bounds'"
                )
            k = round(cells)
            if k < 1 or abs(cells - k) > 1e-6 * max(1.0, cells):
                raise MapError(
                    f"{where}: 'bounds' {label} {span:g} m is not a whole number of cells of "
                    f"'resolution' {res:g} m; adjust the bounds or the resolution"
                )
            counts.append(int(k))
        nx, ny = counts
        if nx * ny > _MAX_CELLS:
            raise MapError(
                f"{where}: the map would have {nx} × {ny} cells (limit {_MAX_CELLS}); "
                "use a coarser 'resolution'"
            )
        shapes = tuple(shapes)
        for k, s in enumerate(shapes):
            if not isinstance(s, Rectangle | Circle | Polygon):
                raise MapError(f"{where}: 'obstacles[{k}]' is not a shape: {s!r}")
            (sx0, sy0), (sx1, sy1) = s.bounds
            tol = _EPS * max(1.0, float(np.max(np.abs(b))))
            if (
                sx0 < b[0, 0] - tol
                or sy0 < b[0, 1] - tol
                or sx1 > b[1, 0] + tol
                or sy1 > b[1, 1] + tol
            ):
                kind = type(s).__name__.lower()
                raise MapError(
                    f"{where}: 'obstacles[{k}]' ({kind} spanning ({sx0:g}, {sy0:g})–({sx1:g}, "
                    f"{sy1:g}) m) extends outside the map bounds ({b[0, 0]:g}, {b[0, 1]:g})–"
                    f"({b[1, 0]:g}, {b[1, 1]:g}) m; move or shrink it, or enlarge 'bounds'"
                )
        occupied, empty = _rasterise(shapes, b[0], res, ny, nx)
        if empty:
            k = empty[0]
            raise MapError(
                f"{where}: 'obstacles[{k}]' ({type(shapes[k]).__name__.lower()}) contains no "
                f"cell centre at 'resolution' {res:g} m, so it would vanish from the map; use "
                "a finer resolution or enlarge the obstacle"
            )
        return cls(b[0].copy(), res, occupied, name=name, source=source, shapes=shapes)

    # -- geometry -----------------------------------------------------------------------

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(ny, nx): number of rows (along y) and columns (along x)."""
        ny, nx = self.occupied.shape
        return int(ny), int(nx)

    @property
    def width(self) -> float:
        """Extent along x (m)."""
        return self.occupied.shape[1] * self.resolution

    @property
    def height(self) -> float:
        """Extent along y (m)."""
        return self.occupied.shape[0] * self.resolution

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x_min, y_min), (x_max, y_max)) of the grid, m."""
        x0, y0 = float(self.origin[0]), float(self.origin[1])
        return (x0, y0), (x0 + self.width, y0 + self.height)

    def cell_centers(self) -> FloatArray:
        """World position (x, y) (m) of every cell centre, shape (ny, nx, 2)."""
        ny, nx = self.grid_shape
        xs = self.origin[0] + (np.arange(nx) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(ny) + 0.5) * self.resolution
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx, gy], axis=-1)

    def _cells(self, p: FloatArray) -> tuple[IntArray, IntArray, BoolArray]:
        """Row, column and inside-the-grid flag of the cell holding each point (N, 2)."""
        ny, nx = self.grid_shape
        with np.errstate(invalid="ignore"):
            fx = np.floor((p[:, 0] - self.origin[0]) / self.resolution)
            fy = np.floor((p[:, 1] - self.origin[1]) / self.resolution)
            inside = (fx >= 0) & (fx < nx) & (fy >= 0) & (fy < ny)
        ix = np.where(inside, fx, 0).astype(np.int64)
        iy = np.where(inside, fy, 0).astype(np.int64)
        return iy, ix, inside

    def is_free(self, points: ArrayLike) -> BoolArray:
        """Whether the cell holding each point is free.

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Positions (x, y), m.

        Returns
        -------
        ndarray of bool, shape (...)
            False for occupied or unknown cells, points outside the map (the grid is
            half-open: x_max and y_max are outside) and non-finite points.
        """
        p = _points_array(points)
        flat = p.reshape(-1, 2)
        iy, ix, inside = self._cells(flat)
        free = inside & ~self.occupied[iy, ix]
        return free.reshape(p.shape[:-1])

    def _clearance_data(self) -> tuple[FloatArray, NDArray[np.int32]]:
        """(clearance at cell centres (ny, nx), nearest-obstacle indices (2, ny+2, nx+2)),
        computed once. The grid is padded with a ring of occupied cells: the map edge
        is an obstacle."""
        cached = self._cache.get("clearance")
        if cached is None:
            ny, nx = self.grid_shape
            padded = np.ones((ny + 2, nx + 2), dtype=bool)
            padded[1:-1, 1:-1] = self.occupied
            nearest = ndimage.distance_transform_edt(
                ~padded, return_distances=False, return_indices=True
            ).astype(np.int32)
            rows = np.arange(1, ny + 1)[:, None]
            cols = np.arange(1, nx + 1)[None, :]
            dr = np.maximum(np.abs(nearest[0, 1:-1, 1:-1] - rows) - 0.5, 0.0)
            dc = np.maximum(np.abs(nearest[1, 1:-1, 1:-1] - cols) - 0.5, 0.0)
            grid = self.resolution * np.hypot(dr, dc)
            grid.setflags(write=False)
            nearest.setflags(write=False)
            cached = (grid, nearest)
            self._cache["clearance"] = cached
        return cached

    @property
    def clearance_grid(self) -> FloatArray:
        """Distance (m) from each cell centre to the nearest occupied cell or the map edge,
        shape (ny, nx); 0 on occupied cells. Read-only."""
        return self._clearance_data()[0]

    def clearance(self, points: ArrayLike) -> FloatArray:
        """Distance from each point to the nearest occupied cell or the map edge.

        For each of the four cells whose centres surround the point, its nearest
        occupied cell (exact Euclidean distance transform of the grid, map edge as an
        obstacle) is found once per map; the returned value is the exact distance from
        the point to the nearest of those cells' squares, or to the map edge if nearer.
        It differs from the distance to the true (unrasterised) obstacles by less than one
        cell.

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Positions (x, y), m.

        Returns
        -------
        ndarray, shape (...)
            Clearance (m); 0 inside occupied or unknown cells, outside the map and for
            non-finite points.
        """
        p = _points_array(points)
        flat = p.reshape(-1, 2)
        _, nearest = self._clearance_data()
        iy, ix, inside = self._cells(flat)
        res = self.resolution
        x = np.where(inside, flat[:, 0], self.origin[0])
        y = np.where(inside, flat[:, 1], self.origin[1])
        # Padded indices of the 2 × 2 cells whose centres surround each point.
        ky = np.floor((y - self.origin[1]) / res - 0.5).astype(np.int64) + 1
        kx = np.floor((x - self.origin[0]) / res - 0.5).astype(np.int64) + 1
        best = np.full(len(flat), np.inf)
        for oy, ox in ((0, 0), (0, 1), (1, 0), (1, 1)):
            jy = nearest[0, ky + oy, kx + ox] - 1  # nearest occupied cell, unpadded index
            jx = nearest[1, ky + oy, kx + ox] - 1
            bx0 = self.origin[0] + jx * res
            by0 = self.origin[1] + jy * res
            dx = np.maximum(np.maximum(bx0 - x, x - (bx0 + res)), 0.0)
            dy = np.maximum(np.maximum(by0 - y, y - (by0 + res)), 0.0)
            best = np.minimum(best, np.hypot(dx, dy))
        (xmin, ymin), (xmax, ymax) = self.bounds
        edge = np.minimum(np.minimum(x - xmin, xmax - x), np.minimum(y - ymin, ymax - y))
        out = np.where(inside & ~self.occupied[iy, ix], np.minimum(best, edge), 0.0)
        return np.maximum(out, 0.0).reshape(p.shape[:-1])

    def __repr__(self) -> str:
        (x0, y0), (x1, y1) = self.bounds
        ny, nx = self.grid_shape
        return (
            f"WorldMap(name={self.name!r}, {nx}×{ny} cells of {self.resolution:g} m, "
            f"bounds=(({x0:g}, {y0:g}), ({x1:g}, {y1:g})) m, "
            f"occupied={int(np.count_nonzero(self.occupied))} cells, source={self.source!r})"
        )


def _rasterise(
    shapes: Sequence[Shape], origin: FloatArray, res: float, ny: int, nx: int
) -> tuple[BoolArray, list[int]]:
    """Occupancy grid (ny, nx), True where a cell centre is inside some shape, and the
    indices of shapes that contain no cell centre."""
    occ = np.zeros((ny, nx), dtype=bool)
    empty = []
    for k, s in enumerate(shapes):
        (x0, y0), (x1, y1) = s.bounds
        # Cells whose centres may fall in the bounding box (one cell of slack each side).
        j0 = max(math.floor((x0 - origin[0]) / res - 0.5), 0)
        j1 = min(math.ceil((x1 - origin[0]) / res + 0.5), nx)
        i0 = max(math.floor((y0 - origin[1]) / res - 0.5), 0)
        i1 = min(math.ceil((y1 - origin[1]) / res + 0.5), ny)
        xs = origin[0] + (np.arange(j0, j1) + 0.5) * res
        ys = origin[1] + (np.arange(i0, i1) + 0.5) * res
        inside = s.contains(np.stack(np.meshgrid(xs, ys), axis=-1))
        if not inside.any():
            empty.append(k)
            continue
        occ[i0:i1, j0:j1] |= inside
    return occ, empty


# ----------------------------------------------------------------------------------------
# Field validation
# ----------------------------------------------------------------------------------------


def _is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _real(value: object, where: str, name: str, unit: str = "") -> float:
    unit_txt = f" ({unit})" if unit else ""
    if not _is_real(value):
        raise MapError(
            f"{where}: field '{name}' must be a number{unit_txt}, got {value!r}; "
            "write a plain number without quotes"
        )
    try:
        x = float(value)  # type: ignore[arg-type]
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise MapError(f"{where}: field '{name}' must be finite, got {x}")
    return x


def _check_positive(value: object, where: str, name: str, unit: str) -> float:
    x = _real(value, where, name, unit)
    if x <= 0.0:
        raise MapError(
            f"{where}: field '{name}' must be > 0 {unit}, got {x:g}; give a positive value"
        )
    return x


def _pair(value: object, where: str, name: str) -> tuple[float, float]:
    if not isinstance(value, Sequence) or isinstance(value, str | bytes) or len(value) != 2:
        raise MapError(f"{where}: field '{name}' must be a pair [x, y] in m, got {value!r}")
    return (_real(value[0], where, f"{name}[0]", "m"), _real(value[1], where, f"{name}[1]", "m"))


def _check_keys(
    doc: Mapping[Any, Any],
    where: str,
    name: str,
    required: Sequence[str],
    optional: Sequence[str] = (),
) -> None:
    allowed = (*required, *optional)
    unknown = [k for k in doc if k not in allowed]
    if unknown:
        raise MapError(
            f"{where}: unknown key {unknown[0]!r} in {name}; allowed keys are "
            f"{', '.join(allowed)}; remove or rename it"
        )
    missing = [k for k in required if k not in doc]
    if missing:
        raise MapError(f"{where}: missing required key '{missing[0]}' in {name}; add it")


# ----------------------------------------------------------------------------------------
# Inline geometry
# ----------------------------------------------------------------------------------------


def _shape_from_doc(item: object, where: str, name: str) -> Shape:
    if not isinstance(item, Mapping) or len(item) != 1:
        raise MapError(
            f"{where}: '{name}' must be a mapping with exactly one of the keys "
            f"rectangle, circle, polygon, got {item!r}"
        )
    ((kind, body),) = item.items()
    if kind not in _SHAPE_KEYS:
        raise MapError(
            f"{where}: '{name}' has unknown shape {kind!r}; use rectangle, circle or polygon"
        )
    field_name = f"{name}.{kind}"
    if not isinstance(body, Mapping):
        raise MapError(f"{where}: '{field_name}' must be a mapping, got {body!r}")
    _check_keys(body, where, f"'{field_name}'", _SHAPE_KEYS[kind])
    try:
        if kind == "rectangle":
            return Rectangle(
                _pair(body["min"], where, f"{field_name}.min"),
                _pair(body["max"], where, f"{field_name}.max"),
            )
        if kind == "circle":
            center = _pair(body["center"], where, f"{field_name}.center")
            radius = _real(body["radius"], where, f"{field_name}.radius", "m")
            if radius <= 0.0:
                raise MapError(
                    f"{where}: field '{field_name}.radius' must be > 0 m, got {radius:g}; "
                    "give the circle a positive radius"
                )
            return Circle(center, radius)
        points = body["points"]
        if not isinstance(points, Sequence) or isinstance(points, str | bytes):
            raise MapError(
                f"{where}: field '{field_name}.points' must be a list of [x, y] pairs, "
                f"got {points!r}"
            )
        pts = tuple(_pair(p, where, f"{field_name}.points[{k}]") for k, p in enumerate(points))
        return Polygon(pts)
    except MapError as exc:
        msg = str(exc)
        if msg.startswith(where):
            raise
        raise MapError(f"{where}: '{field_name}': {msg}") from None


def _map_from_geometry(doc: Mapping[Any, Any], where: str, default_name: str) -> WorldMap:
    _check_keys(doc, where, "the inline map", _GEOMETRY_REQUIRED, _GEOMETRY_OPTIONAL)
    bounds = doc["bounds"]
    if not isinstance(bounds, Sequence) or isinstance(bounds, str | bytes) or len(bounds) != 2:
        raise MapError(
            f"{where}: field 'bounds' must be [[xmin, ymin], [xmax, ymax]] in m, got {bounds!r}"
        )
    lo = _pair(bounds[0], where, "bounds[0]")
    hi = _pair(bounds[1], where, "bounds[1]")
    res = _check_positive(doc.get("resolution", DEFAULT_RESOLUTION), where, "resolution", "m")
    name = doc.get("name", default_name)
    if not isinstance(name, str):
        raise MapError(f"{where}: field 'name' must be a string, got {name!r}")
    obstacles = doc.get("obstacles")
    if obstacles is None:
        obstacles = []
    if not isinstance(obstacles, Sequence) or isinstance(obstacles, str | bytes):
        raise MapError(f"{where}: field 'obstacles' must be a list of shapes, got {obstacles!r}")
    shapes = [_shape_from_doc(item, where, f"obstacles[{k}]") for k, item in enumerate(obstacles)]
    return WorldMap.from_shapes([lo, hi], shapes, resolution=res, name=name, source=where)


# ----------------------------------------------------------------------------------------
# Images: PGM and PNG
# ----------------------------------------------------------------------------------------

_WHITESPACE = b" \t\r\n\v\f"


def _pgm_header(data: bytes, where: str) -> tuple[bytes, int, int, int, int]:
    """(magic, width, height, maxval, offset of the pixel data)."""
    magic = data[:2]
    if magic not in (b"P2", b"P5"):
        raise MapError(
            f"{where}: not a PGM image (magic {magic!r}, expected P2 or P5); "
            "convert it to a grayscale PGM or PNG"
        )
    pos = 2
    values: list[int] = []
    names = ("width", "height", "maxval")
    while len(values) < 3:
        while pos < len(data):
            c = data[pos : pos + 1]
            if c in _WHITESPACE and c:
                pos += 1
            elif c == b"#":
                while pos < len(data) and data[pos : pos + 1] not in (b"\n", b"\r"):
                    pos += 1
            else:
                break
        start = pos
        while pos < len(data) and data[pos : pos + 1] not in _WHITESPACE + b"#":
            pos += 1
        token = data[start:pos]
        if not token:
            raise MapError(
                f"{where}: truncated PGM header (no {names[len(values)]}); the file is "
                "corrupt, re-export the image"
            )
        if not token.isdigit() or len(token) > 9:
            raise MapError(
                f"{where}: corrupt PGM header: {names[len(values)]} is {token[:20]!r}, "
                "expected a positive integer; re-export the image"
            )
        values.append(int(token))
    if pos >= len(data) or data[pos : pos + 1] not in _WHITESPACE:
        raise MapError(f"{where}: truncated PGM: no pixel data after the header; re-export it")
    width, height, maxval = values
    if width < 1 or height < 1:
        raise MapError(f"{where}: PGM has zero width or height ({width} × {height})")
    if not 1 <= maxval <= 65535:
        raise MapError(f"{where}: PGM maxval must be in 1..65535, got {maxval}")
    if width * height > _MAX_CELLS:
        raise MapError(f"{where}: PGM of {width} × {height} pixels is too large")
    return magic, width, height, maxval, pos + 1


def read_pgm(path: str | os.PathLike[str]) -> tuple[NDArray[np.uint16], int]:
    """Read a PGM image (binary P5 or ASCII P2, 8 or 16 bit).

    Parameters
    ----------
    path : str or path-like
        The image file.

    Returns
    -------
    image : ndarray of uint16, shape (height, width)
        Gray values, row 0 the top of the image.
    maxval : int
        The white level (1..65535).

    Raises
    ------
    MapError
        If the file is missing, corrupt, truncated or its size does not match its header.
    """
    p = Path(path)
    return _decode_pgm(_read_bytes(p, str(p)), str(p))


def _decode_pgm(data: bytes, where: str) -> tuple[NDArray[np.uint16], int]:
    magic, w, h, maxval, off = _pgm_header(data, where)
    n = w * h
    if magic == b"P5":
        nbytes = 1 if maxval < 256 else 2
        body = data[off:]
        need = n * nbytes
        if len(body) < need:
            raise MapError(
                f"{where}: truncated PGM: the header says {w} × {h} pixels ({need} bytes) but "
                f"only {len(body)} bytes follow; the file is corrupt, re-export it"
            )
        if body[need:].strip(_WHITESPACE):
            raise MapError(
                f"{where}: PGM has {len(body) - need} bytes beyond the {w} × {h} pixels its "
                "header declares; the image dimensions are inconsistent, re-export it"
            )
        dtype = np.dtype(np.uint8) if nbytes == 1 else np.dtype(">u2")
        img = np.frombuffer(body, dtype=dtype, count=n).astype(np.uint16)
    else:
        text = b"\n".join(line.split(b"#", 1)[0] for line in data[off:].splitlines())
        tokens = text.split()
        if len(tokens) != n:
            what = "truncated" if len(tokens) < n else "inconsistent"
            raise MapError(
                f"{where}: {what} PGM: the header says {w} × {h} = {n} pixels but {len(tokens)} "
                "values follow; fix the header or re-export the image"
            )
        bad = next((t for t in tokens if not t.isdigit() or len(t) > 5), None)
        if bad is not None:
            raise MapError(
                f"{where}: corrupt PGM: pixel value {bad[:20]!r} is not an integer in "
                f"0..{maxval}; re-export the image"
            )
        img = np.array([int(t) for t in tokens], dtype=np.int64)
        if np.any(img > maxval):
            raise MapError(
                f"{where}: corrupt PGM: pixel values exceed maxval {maxval}; re-export the image"
            )
        img = img.astype(np.uint16)
    if np.any(img > maxval):
        raise MapError(
            f"{where}: corrupt PGM: pixel values exceed maxval {maxval}; re-export the image"
        )
    return img.reshape(h, w), maxval


def write_pgm(
    path: str | os.PathLike[str],
    image: ArrayLike,
    *,
    maxval: int | None = None,
    binary: bool = True,
) -> None:
    """Write a grayscale PGM image atomically.

    Parameters
    ----------
    path : str or path-like
        Output file.
    image : array_like of int, shape (height, width)
        Gray values in ``0..maxval``; row 0 is the top of the image.
    maxval : int, optional
        White level (1..65535); default 255, or 65535 if a value exceeds 255.
    binary : bool
        P5 (binary, big-endian for 16 bit) if True, else P2 (ASCII).
    """
    img = np.asarray(image)
    if img.ndim != 2 or img.size == 0 or not np.issubdtype(img.dtype, np.integer):
        raise ConfigError(f"PGM image must be a non-empty 2D integer array, got {img.shape}")
    if maxval is None:
        maxval = 255 if int(img.max()) <= 255 else 65535
    if not 1 <= maxval <= 65535 or int(img.min()) < 0 or int(img.max()) > maxval:
        raise ConfigError(f"PGM values must lie in 0..maxval with maxval in 1..65535 ({maxval})")
    h, w = img.shape
    header = f"{'P5' if binary else 'P2'}\n# gracenav map\n{w} {h}\n{maxval}\n".encode("ascii")
    if binary:
        body = img.astype(np.uint8 if maxval < 256 else ">u2").tobytes()
    else:
        body = "\n".join(" ".join(str(int(v)) for v in row) for row in img).encode() + b"\n"
    atomic_write_bytes(Path(path), header + body)


# PNG: decoded here with zlib and numpy instead of matplotlib.image.imread. imread (via
# Pillow, a dependency we do not take) returns normalised floats and, in matplotlib 3.11,
# mis-scales 2- and 4-bit grayscale images (values come back > 1); map thresholds need
# the exact integer gray levels. The decoder handles every non-interlaced PNG: gray,
# gray+alpha, RGB, RGBA and palette, 1–16 bit, all five row filters. The filters are
# undone along anti-diagonals (each pixel depends on its left, upper and upper-left
# neighbours only), so a 1000 × 1000 image takes ~2000 vectorised steps.

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}


def _png_unfilter(
    filtered: NDArray[np.uint8], ftype: NDArray[np.uint8], bpp: int
) -> NDArray[np.uint8]:
    """Undo PNG row filters. ``filtered`` (h, stride) bytes, ``ftype`` (h,), ``bpp`` bytes
    per pixel (>= 1); returns the reconstructed bytes (h, stride)."""
    h, stride = filtered.shape
    if not np.any(ftype):
        return filtered.copy()
    npx = stride // bpp
    f = filtered.reshape(h, npx, bpp).astype(np.int16)
    rec = np.zeros((h + 1, npx + 1, bpp), dtype=np.int16)  # zero row/column of padding
    ft = ftype.astype(np.int16)
    for d in range(h + npx - 1):
        r = np.arange(max(0, d - npx + 1), min(h, d + 1))
        c = d - r
        a = rec[r + 1, c]  # left
        b = rec[r, c + 1]  # up
        cc = rec[r, c]  # up-left
        pa, pb, pc = np.abs(b - cc), np.abs(a - cc), np.abs(a + b - 2 * cc)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, cc))
        t = ft[r][:, None]
        pred = np.select([t == 1, t == 2, t == 3, t == 4], [a, b, (a + b) >> 1, paeth], 0)
        rec[r + 1, c + 1] = (f[r, c] + pred) & 0xFF
    return rec[1:, 1:].reshape(h, stride).astype(np.uint8)


def _decode_png(data: bytes, where: str) -> tuple[NDArray[np.uint16], int, bool]:
    """Pixels (h, w, channels) as RGB(A)/gray(+alpha), maxval, and whether the last
    channel is alpha."""
    pos = len(_PNG_SIGNATURE)
    ihdr: bytes | None = None
    plte: bytes | None = None
    idat: list[bytes] = []
    while True:
        if pos + 8 > len(data):
            raise MapError(f"{where}: truncated PNG (no IEND chunk); re-export the image")
        length, ctype = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 12 + length
        if end > len(data):
            raise MapError(f"{where}: truncated PNG ({ctype!r} chunk cut short); re-export it")
        body = data[pos + 8 : pos + 8 + length]
        if zlib.crc32(ctype + body) != int.from_bytes(data[end - 4 : end], "big"):
            raise MapError(f"{where}: corrupt PNG (bad CRC in {ctype!r} chunk); re-export it")
        if ctype == b"IHDR":
            ihdr = body
        elif ctype == b"PLTE":
            plte = body
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            break
        pos = end
    if ihdr is None or len(ihdr) != 13 or not idat:
        raise MapError(f"{where}: corrupt PNG (missing IHDR or IDAT chunk); re-export it")
    w, h, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", ihdr)
    if color not in _PNG_CHANNELS or depth not in _PNG_DEPTHS[color] or comp or filt:
        raise MapError(
            f"{where}: corrupt PNG header (bit depth {depth}, colour type {color}); re-export it"
        )
    if interlace:
        raise MapError(
            f"{where}: interlaced (Adam7) PNG is not supported; save it without interlacing"
        )
    if w < 1 or h < 1 or w * h > _MAX_CELLS:
        raise MapError(f"{where}: PNG size {w} × {h} is empty or too large")
    channels = _PNG_CHANNELS[color]
    bits = depth * channels
    stride = (w * bits + 7) // 8
    expected = h * (stride + 1)
    try:
        inflater = zlib.decompressobj()
        raw = inflater.decompress(b"".join(idat), expected + 1)
    except zlib.error as exc:
        raise MapError(f"{where}: corrupt PNG image data ({exc}); re-export it") from None
    if len(raw) != expected:
        what = "truncated" if len(raw) < expected else "inconsistent"
        raise MapError(
            f"{where}: {what} PNG: {w} × {h} pixels need {expected} bytes of image data, "
            f"found {'more' if len(raw) > expected else len(raw)}; re-export the image"
        )
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(h, stride + 1)
    ftype = rows[:, 0]
    if np.any(ftype > 4):
        raise MapError(f"{where}: corrupt PNG (unknown row filter type); re-export it")
    rec = _png_unfilter(rows[:, 1:], ftype, max(1, bits // 8))
    if depth == 16:
        values = rec.view(">u2").astype(np.uint16)
    elif depth == 8:
        values = rec.astype(np.uint16)
    else:
        bitplanes = np.unpackbits(rec, axis=1).reshape(h, -1, depth)
        weights = (1 << np.arange(depth - 1, -1, -1)).astype(np.uint16)
        values = (bitplanes.astype(np.uint16) * weights).sum(axis=2, dtype=np.uint16)
    pixels = values[:, : w * channels].reshape(h, w, channels)
    maxval = (1 << depth) - 1
    if color == 3:
        if plte is None or len(plte) % 3 or not plte:
            raise MapError(f"{where}: corrupt PNG (palette image without a valid PLTE chunk)")
        palette = np.frombuffer(plte, dtype=np.uint8).reshape(-1, 3).astype(np.uint16)
        index = pixels[..., 0]
        if int(index.max()) >= len(palette):
            raise MapError(f"{where}: corrupt PNG (palette index out of range); re-export it")
        return palette[index], 255, False
    return pixels, maxval, color in (4, 6)


def _read_bytes(path: Path, where: str) -> bytes:
    if not path.is_file():
        raise MapError(f"{where}: file not found; check the path")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise MapError(f"{where}: cannot read the file ({exc.strerror})") from None


def _read_image(path: Path, where: str) -> tuple[NDArray[np.uint16], int, bool]:
    """Pixels (h, w, c), maxval and has-alpha of a PGM or PNG file (kind from its bytes)."""
    data = _read_bytes(path, where)
    if data.startswith(_PNG_SIGNATURE):
        return _decode_png(data, where)
    if data[:2] in (b"P2", b"P5"):
        img, maxval = _decode_pgm(data, where)
        return img[:, :, None], maxval, False
    raise MapError(
        f"{where}: unsupported image format (expected a PGM P2/P5 or a PNG); "
        "convert the image to PGM or PNG"
    )


# ----------------------------------------------------------------------------------------
# ROS map_server maps
# ----------------------------------------------------------------------------------------


def _map_from_ros(doc: Mapping[Any, Any], path: Path) -> WorldMap:
    where = str(path)
    _check_keys(doc, where, "the ROS map YAML", _ROS_REQUIRED, _ROS_OPTIONAL)
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise MapError(f"{where}: field 'image' must be an image file name, got {image!r}")
    res = _check_positive(doc["resolution"], where, "resolution", "m")
    origin = doc["origin"]
    if not isinstance(origin, Sequence) or isinstance(origin, str | bytes) or len(origin) != 3:
        raise MapError(f"{where}: field 'origin' must be [x, y, yaw] (m, m, rad), got {origin!r}")
    ox = _real(origin[0], where, "origin[0]", "m")
    oy = _real(origin[1], where, "origin[1]", "m")
    yaw = _real(origin[2], where, "origin[2]", "rad")
    if yaw != 0.0:
        raise MapError(
            f"{where}: field 'origin' has yaw {yaw:g} rad; rotated maps are unsupported: "
            "rotate the image so the map axes align with the world and set yaw to 0"
        )
    negate = doc["negate"]
    if negate not in (0, 1) or not isinstance(negate, int):
        raise MapError(f"{where}: field 'negate' must be 0 or 1, got {negate!r}")
    occ_th = _real(doc["occupied_thresh"], where, "occupied_thresh")
    free_th = _real(doc["free_thresh"], where, "free_thresh")
    for label, th in (("occupied_thresh", occ_th), ("free_thresh", free_th)):
        if not 0.0 <= th <= 1.0:
            raise MapError(f"{where}: field '{label}' must be in [0, 1], got {th:g}")
    if occ_th <= free_th:
        raise MapError(
            f"{where}: field 'occupied_thresh' ({occ_th:g}) must exceed 'free_thresh' "
            f"({free_th:g}); typical values are 0.65 and 0.196"
        )
    mode = doc.get("mode", "trinary")
    if mode not in _ROS_MODES:
        raise MapError(
            f"{where}: field 'mode' must be one of {', '.join(_ROS_MODES)}, got {mode!r}"
        )
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    image_where = f"{where}: field 'image' ({image_path})"
    if not image_path.is_file():
        raise MapError(
            f"{where}: field 'image': file {image_path} not found; the image path is relative "
            "to the YAML file's folder"
        )
    pixels, maxval, has_alpha = _read_image(image_path, image_where)
    occupied, unknown = _classify(pixels, maxval, has_alpha, bool(negate), occ_th, free_th, mode)
    return WorldMap(
        np.array([ox, oy]),
        res,
        occupied[::-1],
        name=path.stem,
        source=where,
        unknown=unknown[::-1],
    )


def _classify(
    pixels: NDArray[np.uint16],
    maxval: int,
    has_alpha: bool,
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
    mode: str,
) -> tuple[BoolArray, BoolArray]:
    """map_server's cell classification, in image orientation (row 0 at the top).

    The gray level is the mean of the colour channels (a gray image has one; the alpha
    channel, as opacity, joins the mean in trinary mode only, as map_server does).
    ``p = (maxval − mean) / maxval`` (``mean / maxval`` if negated); a cell is occupied if
    p > occupied_thresh, free if p < free_thresh, unknown otherwise. In raw mode the cell
    value is the (negated) gray level itself and only 0 is free. Returns (occupied or
    unknown, unknown), both (h, w).
    """
    channels = pixels.shape[2]
    colour = channels - 1 if has_alpha else channels
    use = channels if (has_alpha and mode == "trinary") else colour
    sel = pixels[:, :, :use].astype(np.float64)
    if colour == 1 and use == 2:  # gray + alpha: the gray counts as R, G and B
        mean = (3.0 * sel[:, :, 0] + sel[:, :, 1]) / 4.0
    else:
        mean = sel.sum(axis=2) / use
    if mode == "raw":
        value = maxval - mean if negate else mean
        free = value == 0.0
        return ~free, np.zeros_like(free)
    p = mean / maxval if negate else (maxval - mean) / maxval
    occ = p > occupied_thresh
    free = p < free_thresh
    unknown = ~occ & ~free
    return ~free, unknown


def save_ros_map(
    world_map: WorldMap,
    path: str | os.PathLike[str],
    *,
    binary: bool = True,
) -> Path:
    """Write ``world_map`` as a ROS map_server map: ``path`` (YAML) and a PGM beside it.

    Occupied cells are written 0, unknown 205 and free 254 (map_saver's levels) with
    ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``, so
    :func:`load_map` reads back the same grid.

    Parameters
    ----------
    world_map : WorldMap
        The map to save.
    path : str or path-like
        The YAML file; the image is written next to it with suffix ``.pgm``.
    binary : bool
        Binary P5 (default) or ASCII P2 PGM.

    Returns
    -------
    Path
        The image file written.
    """
    yaml_path = Path(path)
    image_path = yaml_path.with_suffix(".pgm")
    img = np.full(world_map.grid_shape, 254, dtype=np.uint16)
    img[world_map.occupied] = 0
    if world_map.unknown is not None:
        img[world_map.unknown] = 205
    write_pgm(image_path, img[::-1], maxval=255, binary=binary)
    name = image_path.name
    if not re.fullmatch(r"[A-Za-z0-9_.+-]+", name):
        name = json.dumps(name)  # a JSON string is a valid YAML scalar
    ox, oy = (float(v) for v in world_map.origin)
    text = (
        f"image: {name}\n"
        "mode: trinary\n"
        f"resolution: {world_map.resolution!r}\n"
        f"origin: [{ox!r}, {oy!r}, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )
    atomic_write_text(yaml_path, text)
    return image_path


# ----------------------------------------------------------------------------------------
# Loading
# ----------------------------------------------------------------------------------------


def load_map(source: str | os.PathLike[str] | Mapping[str, Any]) -> WorldMap:
    """Load a map from a file or an inline description.

    Parameters
    ----------
    source : str, path-like or mapping
        * a mapping: inline geometry ``{"bounds": [[xmin, ymin], [xmax, ymax]],
          "obstacles": [...], "resolution": 0.05, "name": "..."}`` (m);
        * a YAML (or JSON) file holding either a ROS map_server description (key
          ``image``) or inline geometry (key ``bounds``).

    Returns
    -------
    WorldMap

    Raises
    ------
    MapError
        If the file is missing or malformed; the message names the file (or
        ``"inline map"``) and the offending field, and says how to fix it.

    Notes
    -----
    ROS maps follow map_server: ``image`` (relative to the YAML file's folder),
    ``resolution`` (m/cell), ``origin`` [x, y, yaw] (only yaw = 0 is supported),
    ``negate``, ``occupied_thresh``, ``free_thresh`` and optional ``mode`` (trinary,
    scale or raw). Unknown cells count as occupied. Obstacles of inline maps are
    ``{"rectangle": {"min": [x, y], "max": [x, y]}}``, ``{"circle": {"center": [x, y],
    "radius": r}}`` or ``{"polygon": {"points": [[x, y], ...]}}``, entirely inside the
    bounds; a cell is occupied iff its centre is inside some obstacle.
    """
    if isinstance(source, Mapping):
        return _map_from_geometry(source, INLINE, "map")
    if not isinstance(source, str | os.PathLike):
        raise MapError(f"map source must be a file path or a mapping, got {type(source).__name__}")
    try:
        path = Path(source)
    except TypeError:
        raise MapError(f"map source {source!r} is not a valid path") from None
    where = str(path)
    data = _read_bytes(path, where)
    try:
        doc = yaml.safe_load(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise MapError(
            f"{where}: not a text file; give the map's YAML file, not its image"
        ) from None
    except (yaml.YAMLError, ValueError, RecursionError) as exc:
        raise MapError(f"{where}: not valid YAML/JSON ({exc}); fix the syntax") from None
    if not isinstance(doc, Mapping):
        raise MapError(
            f"{where}: a map file must hold a mapping with key 'image' (ROS map) or "
            f"'bounds' (inline geometry), got {type(doc).__name__}"
        )
    has_image, has_bounds = "image" in doc, "bounds" in doc
    if has_image and has_bounds:
        raise MapError(
            f"{where}: has both 'image' (ROS map) and 'bounds' (inline geometry); keep one"
        )
    if has_image:
        return _map_from_ros(doc, path)
    if has_bounds:
        return _map_from_geometry(doc, where, path.stem)
    raise MapError(
        f"{where}: missing required key 'image' (ROS map) or 'bounds' (inline geometry); add one"
    )


# ----------------------------------------------------------------------------------------
# A synthetic office for benchmarks and tests
# ----------------------------------------------------------------------------------------


def office_map(
    size: float = 50.0, resolution: float = DEFAULT_RESOLUTION, seed: int = 0
) -> WorldMap:
    """A square office floor with corridors, rooms, doors and furniture.

    Layout: outer walls 0.2 m thick; a 2 m corridor along the west wall; bands 12 m deep,
    each a 2 m east-west corridor between two rows of 5 m deep rooms 3–6 m wide; one 1 m
    door per room onto its corridor; 1–3 desks (rectangles) or round tables (circles) per
    room, at least 0.7 m from its walls, so every room stays connected; any strip above the
    last band is an open hall with pillars. Everything random comes from ``seed``.

    Parameters
    ----------
    size : float
        Side of the square (m), >= 14 and a whole number of cells.
    resolution : float
        Cell side (m), > 0 and at most 0.1 (the 0.1 m partition walls must cover a row
        of cell centres).
    seed : int
        Seed of the layout's random generator.

    Returns
    -------
    WorldMap
        Bounds ((0, 0), (size, size)), with its shapes.
    """
    if not _is_real(size) or not float(size) >= 14.0:
        raise ConfigError(f"office_map size must be a number >= 14 m, got {size!r}")
    size = float(size)
    rng = np.random.default_rng(seed)
    shapes: list[Shape] = []
    outer, part = 0.2, 0.1
    shapes += [
        Rectangle((0.0, 0.0), (size, outer)),
        Rectangle((0.0, size - outer), (size, size)),
        Rectangle((0.0, 0.0), (outer, size)),
        Rectangle((size - outer, 0.0), (size, size)),
    ]
    x_in0, x_in1 = outer, size - outer
    y_in0, y_in1 = outer, size - outer
    rooms_x0 = x_in0 + 2.0  # west corridor
    depth, corridor, band = 5.0, 2.0, 12.0
    n_bands = int((y_in1 - y_in0) // band)

    def wall_x(x: float, y0: float, y1: float) -> None:
        shapes.append(Rectangle((x - part / 2, y0), (x + part / 2, y1)))

    def wall_y(y: float, x0: float, x1: float) -> None:
        if x1 - x0 > 1e-6:
            shapes.append(Rectangle((x0, y - part / 2), (x1, y + part / 2)))

    def furnish(x0: float, y0: float, x1: float, y1: float) -> None:
        margin = 0.7
        ax0, ay0, ax1, ay1 = x0 + margin, y0 + margin, x1 - margin, y1 - margin
        for _ in range(int(rng.integers(1, 4))):
            if rng.random() < 0.6:
                w, h = rng.uniform(0.6, 1.6), rng.uniform(0.6, 1.0)
                if rng.random() < 0.5:
                    w, h = h, w
                if ax1 - ax0 < w or ay1 - ay0 < h:
                    continue
                cx, cy = rng.uniform(ax0, ax1 - w), rng.uniform(ay0, ay1 - h)
                shapes.append(Rectangle((cx, cy), (cx + w, cy + h)))
            else:
                r = rng.uniform(0.3, 0.6)
                if ax1 - ax0 < 2 * r or ay1 - ay0 < 2 * r:
                    continue
                shapes.append(
                    Circle((rng.uniform(ax0 + r, ax1 - r), rng.uniform(ay0 + r, ay1 - r)), r)
                )

    for k in range(n_bands):
        yb = y_in0 + k * band
        for row_y0, door_y in ((yb, yb + depth), (yb + depth + corridor, yb + depth + corridor)):
            row_y1 = row_y0 + depth
            wall_x(rooms_x0, row_y0, row_y1)
            # Room partitions along x, then the corridor wall with one door per room.
            edges = [rooms_x0]
            while x_in1 - edges[-1] > 9.0:
                edges.append(edges[-1] + float(rng.uniform(3.0, 6.0)))
            edges.append(x_in1)
            for x in edges[1:-1]:
                wall_x(x, row_y0, row_y1)
            start = rooms_x0
            for x0, x1 in itertools.pairwise(edges):
                door = float(rng.uniform(x0 + 0.8, x1 - 1.8))
                wall_y(door_y, start, door)
                start = door + 1.0
                furnish(x0 + part / 2, row_y0 + part / 2, x1 - part / 2, row_y1 - part / 2)
            wall_y(door_y, start, x_in1)
        if y_in1 - (yb + band) > 0.5:  # back wall towards the next band or the hall
            wall_y(yb + band, rooms_x0, x_in1)
    hall_y0 = y_in0 + n_bands * band
    if y_in1 - hall_y0 > 3.0:
        for x in np.arange(rooms_x0 + 4.0, x_in1 - 2.0, 6.0):
            shapes.append(Circle((float(x), 0.5 * (hall_y0 + y_in1)), 0.25))
    return WorldMap.from_shapes(
        [[0.0, 0.0], [size, size]],
        shapes,
        resolution=resolution,
        name=f"office {size:g} m (seed {seed})",
        source=f"office_map(size={size:g}, resolution={resolution:g}, seed={seed})",
    )
