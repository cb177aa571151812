"""The occupancy grid of the world: :class:`WorldMap`, rasterisation and clearance.

A :class:`WorldMap` is a 2D occupancy grid (paper Sec. IV-A: motion policies are
instantiated on a map M and kept only where they are obstacle free). This module holds
the grid, how obstacle shapes become cells and the queries the library asks of it (is a
point free, how far is it from the nearest obstacle); reading map files is
:mod:`gracenav.world.ros_map`'s and :mod:`gracenav.world.inline`'s job.

Conventions (SI units throughout): ``origin`` is the world position (m) of the lower-left
corner of cell (0, 0); cell (i, j) (row i, column j) covers
``[x0 + j·res, x0 + (j+1)·res) × [y0 + i·res, y0 + (i+1)·res)``, so row 0 is the lowest y.
Points are arrays of shape (..., 2) holding (x, y) in metres. Unknown cells count as
occupied: a robot must not plan through space nobody has seen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from gracenav._util.validate import check_number
from gracenav.errors import MapError
from gracenav.world.geometry import (
    _EPS,
    BoolArray,
    Circle,
    FloatArray,
    Polygon,
    Rectangle,
    Shape,
    _points_array,
)

__all__ = [
    "DEFAULT_RESOLUTION",
    "INLINE",
    "MAP_BYTES_PER_CELL",
    "MAX_MAP_CELLS",
    "WorldMap",
    "check_map_budget",
]

IntArray = NDArray[np.int64]

#: Rasterisation resolution (m per cell) of inline maps that do not give one.
DEFAULT_RESOLUTION = 0.05

INLINE = "inline map"
"""Name used in error messages for maps given as a mapping rather than a file."""

#: The map budget: the most cells a map may have. Maps are refused before anything of
#: their size is allocated (an inline map from its bounds and resolution, a ROS map from
#: its image header). 10 million cells is 158 m × 158 m at 5 cm, 316 m × 316 m at 10 cm.
MAX_MAP_CELLS = 10_000_000

#: Estimated peak memory (bytes) per cell while a map is loaded and its clearance field
#: computed: the grids (2 B), the clearance field and nearest-obstacle indices (16 B) and
#: the distance transform's work arrays; for a ROS map also the decoded image and its
#: gray levels, freed before the clearance field is computed. Measured (tracemalloc,
#: 2000 × 2000 maps): 34–35 B per cell for inline, gray and RGBA maps, plus Pillow's own
#: image buffer (1–4 B). At :data:`MAX_MAP_CELLS` that is ≈ 0.4 GB.
MAP_BYTES_PER_CELL = 40


def _format_bytes(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def check_map_budget(ny: float, nx: float, where: str, advice: str) -> None:
    """Refuse a map of ``ny`` × ``nx`` cells over the budget, before it is allocated.

    Parameters
    ----------
    ny, nx : float
        Rows and columns the map would have (may be non-integer or infinite estimates).
    where : str
        The map's source; starts the message.
    advice : str
        What the user can do about it; ends the message.

    Raises
    ------
    MapError
        If ``ny · nx`` exceeds :data:`MAX_MAP_CELLS` (or is not finite); the message
        gives the cell count, the estimated memory (:data:`MAP_BYTES_PER_CELL` per cell)
        and the limit.
    """
    cells = float(ny) * float(nx)
    if cells <= MAX_MAP_CELLS:
        return
    if math.isfinite(cells):
        size = f"{float(nx):,.0f} × {float(ny):,.0f} = {cells:,.0f} cells"
    else:
        size = "more cells than can be counted"
    raise MapError(
        f"{where}: the map would have {size}, needing about "
        f"{_format_bytes(cells * MAP_BYTES_PER_CELL)} of memory; the limit is "
        f"{MAX_MAP_CELLS:,} cells (about {_format_bytes(MAX_MAP_CELLS * MAP_BYTES_PER_CELL)}); "
        f"{advice}"
    )


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
        res = check_number(
            self.resolution, "resolution", where, positive=True, unit="m", error=MapError
        )
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
            If the bounds, resolution or any shape is invalid, or the grid would exceed
            :data:`MAX_MAP_CELLS` (checked before it is allocated).
        """
        where = source
        try:
            b = np.asarray(bounds, dtype=float)
        except (TypeError, ValueError, OverflowError):
            b = np.full(1, np.nan)
        if b.shape != (2, 2) or not np.all(np.isfinite(b)):
            raise MapError(f"{where}: 'bounds' must be [[xmin, ymin], [xmax, ymax]] in m")
        res = check_number(resolution, "resolution", where, positive=True, unit="m", error=MapError)
        if not (b[1, 0] > b[0, 0] and b[1, 1] > b[0, 1]):
            raise MapError(
                f"{where}: 'bounds' max ({b[1, 0]:g}, {b[1, 1]:g}) must exceed min "
                f"({b[0, 0]:g}, {b[0, 1]:g}) in x and y; "
                "give [[xmin, ymin], [xmax, ymax]]"
            )
        # Python floats: an absurd span or resolution gives inf, never an overflow warning.
        spans = [float(b[1, k]) - float(b[0, k]) for k in (0, 1)]
        check_map_budget(
            spans[1] / res,
            spans[0] / res,
            where,
            "use a coarser 'resolution' or smaller 'bounds'",
        )
        counts = []
        for axis, label in ((0, "width"), (1, "height")):
            span = spans[axis]
            cells = span / res
            k = round(cells)
            if k < 1 or abs(cells - k) > 1e-6 * max(1.0, cells):
                raise MapError(
                    f"{where}: 'bounds' {label} {span:g} m is not a whole number of cells of "
                    f"'resolution' {res:g} m; adjust the bounds or the resolution"
                )
            counts.append(int(k))
        nx, ny = counts
        check_map_budget(ny, nx, where, "use a coarser 'resolution' or smaller 'bounds'")
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

    def window(self, rows: slice, cols: slice, *, keep: BoolArray | None = None) -> WorldMap:
        """The part of the map made of the cells ``occupied[rows, cols]``, as a map of its
        own; cells where ``keep`` is False are occupied in it.

        Its edge is an obstacle like any map's, so its clearance is never larger than the
        whole map's: a path or policy clear in the window is clear in the map.

        Parameters
        ----------
        rows, cols : slice
            Cell rows (along y) and columns (along x), with step 1 and inside the grid.
        keep : ndarray of bool, shape (rows, cols), optional
            Cells of the window that keep the map's occupancy; the others become
            occupied (not unknown). Default: all.

        Returns
        -------
        WorldMap
            Same resolution and source, origin at the window's lower-left corner, named
            after this map; ``shapes`` is None.

        Raises
        ------
        MapError
            For an empty window, a step other than 1 or a ``keep`` of another shape.
        """
        ny, nx = self.grid_shape
        r0, r1, rs = rows.indices(ny)
        c0, c1, cs = cols.indices(nx)
        if rs != 1 or cs != 1 or r1 <= r0 or c1 <= c0:
            raise MapError(
                f"{self.source}: a window needs non-empty row and column ranges with step 1, "
                f"got rows {rows} and columns {cols} of a {ny} × {nx} grid"
            )
        occupied = self.occupied[r0:r1, c0:c1]
        if keep is not None:
            mask = np.asarray(keep, dtype=bool)
            if mask.shape != occupied.shape:
                raise MapError(
                    f"{self.source}: window keep mask {mask.shape} must match the window "
                    f"{occupied.shape}"
                )
            occupied = occupied | ~mask
        unknown = None if self.unknown is None else self.unknown[r0:r1, c0:c1]
        origin = self.origin + self.resolution * np.array([c0, r0], dtype=float)
        return WorldMap(
            origin,
            self.resolution,
            occupied,
            name=f"{self.name} [{c0}:{c1}, {r0}:{r1}]",
            source=self.source,
            unknown=unknown,
        )

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
