"""A synthetic office floor for benchmarks and tests: :func:`office_map`."""

from __future__ import annotations

import itertools

import numpy as np

from gracenav._util.validate import check_number
from gracenav.world.geometry import Circle, Rectangle, Shape
from gracenav.world.occupancy import DEFAULT_RESOLUTION, WorldMap

__all__ = ["office_map"]


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
    size = check_number(size, "size", "office_map", minimum=14.0, unit="m")
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
