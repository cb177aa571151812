"""Seeded synthetic maps for benchmarks and tests, of the kinds users bring: an office
floor (:func:`office_map`), a forest of posts (:func:`forest_map`) and a warehouse
(:func:`warehouse_map`); and the check that the robot's footprint can get from one
point to another at all (:func:`footprint_connected`)."""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import ArrayLike

from gracenav._util.validate import check_number
from gracenav.world.geometry import Circle, Rectangle, Shape
from gracenav.world.occupancy import DEFAULT_RESOLUTION, WorldMap

__all__ = ["footprint_connected", "forest_map", "office_map", "warehouse_map"]


def office_map(
    size: float = 50.0,
    resolution: float = DEFAULT_RESOLUTION,
    seed: int = 0,
    *,
    door: float = 1.0,
) -> WorldMap:
    """A square office floor with corridors, rooms, doors and furniture.

    Layout: outer walls 0.2 m thick; a 2 m corridor along the west wall; bands 12 m deep,
    each a 2 m east-west corridor between two rows of 5 m deep rooms 3–6 m wide; one 1 m
    door per room onto its corridor; 1–3 desks (rectangles) or round tables (circles) per
    room, at least 0.7 m from its walls, so every room stays connected; any strip above the
    last band is an open hall with pillars. Everything random comes from ``seed``; the
    doors are ``door`` wide (m, 0.6-1.5; 1 m by default).

    Parameters
    ----------
    size : float
        Side of the square (m), >= 14 and a whole number of cells.
    resolution : float
        Cell side (m), > 0 and at most 0.1 (the 0.1 m partition walls must cover a row
        of cell centres).
    seed : int
        Seed of the layout's random generator.
    door : float
        Width of every door (m).

    Returns
    -------
    WorldMap
        Bounds ((0, 0), (size, size)), with its shapes.
    """
    size = check_number(size, "size", "office_map", minimum=14.0, unit="m")
    door_w = check_number(door, "door", "office_map", minimum=0.6, maximum=1.5, unit="m")
    resolution = check_number(
        resolution, "resolution", "office_map", positive=True, maximum=0.1, unit="m"
    )
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
                at = float(rng.uniform(x0 + 0.8, x1 - 1.8))
                wall_y(door_y, start, at)
                start = at + door_w
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
        source=f"office_map(size={size:g}, resolution={resolution:g}, seed={seed}"
        + (f", door={door_w:g})" if door_w != 1.0 else ")"),
    )


def forest_map(
    width: float = 4.5,
    length: float = 16.0,
    *,
    post: float = 0.15,
    density: float = 0.06,
    resolution: float = 0.05,
    seed: int = 0,
) -> WorldMap:
    """A field of square posts between two walls: a cluttered forest.

    Posts ``post`` wide (m) stand on a grid of pitch ``post`` (m) across the field,
    each cell of the grid holding one with probability ``density``; the first and last
    2.5 m of the field are clear (start and goal areas). The field runs along x from 0 to
    ``length`` between walls 0.1 m thick at y = 0 and y = ``width``.

    Parameters
    ----------
    width, length : float
        The field (m).
    post : float
        Side of a post and pitch of their grid (m).
    density : float
        Fraction of grid cells holding a post, in [0, 0.9].
    resolution : float
        Cell side (m), at most ``post`` / 2.
    seed : int

    Returns
    -------
    WorldMap
        Bounds ((0, −0.1), (length, width + 0.1)).
    """
    width = check_number(width, "width", "forest_map", minimum=1.0, unit="m")
    length = check_number(length, "length", "forest_map", minimum=6.0, unit="m")
    post = check_number(post, "post", "forest_map", minimum=0.05, unit="m")
    density = check_number(density, "density", "forest_map", minimum=0.0, maximum=0.9)
    resolution = check_number(
        resolution, "resolution", "forest_map", positive=True, maximum=post / 2, unit="m"
    )
    rng = np.random.default_rng(seed)
    shapes: list[Shape] = [
        Rectangle((0.0, -0.1), (length, 0.0)),
        Rectangle((0.0, width), (length, width + 0.1)),
    ]
    clear = 2.5
    nx = int((length - 2 * clear) // post)
    ny = int(width // post)
    has = rng.random((nx, ny)) < density
    for i, j in zip(*np.nonzero(has), strict=True):
        x0, y0 = clear + i * post, j * post
        shapes.append(Rectangle((x0, y0), (x0 + post, y0 + post)))
    return WorldMap.from_shapes(
        [[0.0, -0.1], [length, width + 0.1]],
        shapes,
        resolution=resolution,
        name=f"forest {width:g} m x {length:g} m (seed {seed})",
        source=f"forest_map(width={width:g}, length={length:g}, post={post:g}, "
        f"density={density:g}, resolution={resolution:g}, seed={seed})",
    )


def warehouse_map(
    width: float = 30.0,
    length: float = 50.0,
    *,
    resolution: float = 0.03,
    seed: int = 0,
) -> WorldMap:
    """A warehouse: rows of shelves with aisles 1.0-2.5 m wide, a cross aisle, pillars,
    and the inside of every shelf unknown (as a scan sees only the shelves' faces).

    Shelves 0.9-1.2 m deep run along y in rows across x, each row broken by a 3 m cross
    aisle in the middle of the hall; the aisles between rows are drawn from 1.0-2.5 m;
    a 3 m loading strip runs along the south wall; pillars (0.4 m) stand at the row ends
    on a 10 m pitch. The outer walls are 0.2 m thick. A shelf's outline (one cell wide)
    is occupied, its inside unknown (occupied for planning, as map_server's trinary
    maps mark it).

    Parameters
    ----------
    width, length : float
        The hall along x and y (m).
    resolution : float
        Cell side (m), at most 0.05.
    seed : int

    Returns
    -------
    WorldMap
        Bounds ((0, 0), (width, length)) rounded up to whole cells, with an unknown mask.
    """
    width = check_number(width, "width", "warehouse_map", minimum=10.0, unit="m")
    length = check_number(length, "length", "warehouse_map", minimum=12.0, unit="m")
    resolution = check_number(
        resolution, "resolution", "warehouse_map", positive=True, maximum=0.05, unit="m"
    )
    rng = np.random.default_rng(seed)
    # Whole cells: the hall is rounded up to them (50 m at 3 cm: 50.01 m).
    width = math.ceil(width / resolution - 1e-9) * resolution
    length = math.ceil(length / resolution - 1e-9) * resolution
    outer = 0.2
    walls: list[Shape] = [
        Rectangle((0.0, 0.0), (width, outer)),
        Rectangle((0.0, length - outer), (width, length)),
        Rectangle((0.0, 0.0), (outer, length)),
        Rectangle((width - outer, 0.0), (width, length)),
    ]
    shelves: list[Rectangle] = []
    pillars: list[Shape] = []
    y0, y1 = outer + 3.0, length - outer - 1.5
    mid = 0.5 * (y0 + y1)
    x = outer + float(rng.uniform(1.0, 2.5))
    while True:
        depth = float(rng.uniform(0.9, 1.2))
        if x + depth > width - outer - 1.0:
            break
        for a, b in ((y0, mid - 1.5), (mid + 1.5, y1)):
            if b - a > 1.0:
                shelves.append(Rectangle((x, a), (x + depth, b)))
        for py in np.arange(y0 - 0.6, y1 + 0.6, 10.0):
            pillars.append(Circle((x + 0.5 * depth, float(py)), 0.2))
        x += depth + float(rng.uniform(1.0, 2.5))
    grid = WorldMap.from_shapes(
        [[0.0, 0.0], [width, length]], [*walls, *shelves, *pillars], resolution=resolution
    )
    centers = grid.cell_centers()
    inside = np.zeros(grid.occupied.shape, dtype=bool)
    for r in shelves:
        (ax, ay), (bx, by) = r.min_corner, r.max_corner
        inside |= (
            (centers[..., 0] > ax + 1.5 * resolution)
            & (centers[..., 0] < bx - 1.5 * resolution)
            & (centers[..., 1] > ay + 1.5 * resolution)
            & (centers[..., 1] < by - 1.5 * resolution)
        )
    return WorldMap(
        grid.origin,
        grid.resolution,
        grid.occupied,
        name=f"warehouse {width:g} m x {length:g} m (seed {seed})",
        unknown=inside & grid.occupied,
    )


def footprint_connected(
    world_map: WorldMap, start: ArrayLike, goal: ArrayLike, footprint_radius: float
) -> bool:
    """Whether a disc of ``footprint_radius`` (m) can move from ``start`` to ``goal``
    (x, y) (m): both cell centres have at least that clearance and lie in one
    4-connected region of such cells (the footprint-inflated grid; 8-connected moves
    that cut no corner connect the same cells). The traversability check of generated
    maps: the decoupled baseline's A* finds a path exactly then.
    """
    from scipy import ndimage

    ok = world_map.clearance_grid >= footprint_radius
    labels, _ = ndimage.label(ok)  # 4-connected
    iy, ix, inside = world_map._cells(np.asarray([start, goal], dtype=float).reshape(2, 2))
    if not (np.all(inside) and np.all(ok[iy, ix])):
        return False
    return bool(labels[iy[0], ix[0]] == labels[iy[1], ix[1]])
