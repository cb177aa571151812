"""The part of a map a scenario's library is built on: the whole map, or on big maps the
task's region (``planner.region``).

The task region is the set of cells within ``planner.region_margin`` of the
footprint's shortest paths through the task's positions (each start to the goal, or the
surveillance start through the goals and back to the first), as a map of its own
(:meth:`gracenav.world.WorldMap.window`): the cells beyond the margin count as obstacles.
Instantiating there keeps every guarantee (the window's clearance never exceeds the
map's, so a policy clear in the region is clear in the map); it costs what lies outside:
routes that leave the region and detours around moving obstacles wider than the margin.
:func:`gracenav.scenarios.run_scenario` therefore falls back to the whole map when the
task is impossible in its region (``auto``).

The paths are A* on the cells whose clearance keeps the footprint
(:func:`gracenav.world.grid_search.astar_cells`), searched in a window around the task
grown until they are found or the window is the whole map; the region's lower corner
lies on the lattice of the whole map (a multiple of the palette's d from its corner,
when some multiple of the cell side is one), so that lattice points of the whole map
stay lattice points of the region.
"""

from __future__ import annotations

import itertools
import math
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from gracenav.world.grid_search import astar_cells

__all__ = [
    "AUTO_REGION_AREA",
    "DEFAULT_REGION_MARGIN",
    "REGIONS",
    "REGION_POLICIES",
    "resolve_region",
    "task_region",
    "task_waypoints",
]

REGIONS = ("auto", "map", "task")
"""Values of ``planner.region``."""

AUTO_REGION_AREA = 1000.0
"""Map area (m²) above which ``planner.region: auto`` builds the library on the task's
region: a 30 m × 50 m warehouse or a 100 m hall; the paper's rooms and a 30 m × 15 m
depot keep the whole map."""

DEFAULT_REGION_MARGIN = 5.0
"""``planner.region_margin`` (m): room for detours on either side of the footprint's
shortest path."""

REGION_POLICIES = 400_000
"""Most policies (estimated) of a task region's library when its halvings are chosen
automatically: about a second of library and graph on a 2-core machine. A long task's
region (a 77 m route across the 100 m office: 840,690 policies at one halving, the
first command 5.6 s after start) takes a coarser lattice instead (190,707 policies at
none, 2.7 s)."""

_MAX_PERIOD_CELLS = 1000
"""Most cells searched for a multiple of the cell side that is a multiple of d."""


def task_waypoints(scenario: Any) -> NDArray[np.float64]:
    """The positions (K, 2) (m) the task's paths join, in order: each start then the
    goal (point-to-point, starts repeated), or the start, the goals and the first goal
    again after a loop (surveillance)."""
    goals = [tuple(g[:2]) for g in scenario.goals]
    if scenario.kind == "point_to_point":
        pts = [p for s in scenario.starts for p in (tuple(s[:2]), goals[0])]
    else:
        pts = [tuple(scenario.starts[0][:2]), *goals]
        if scenario.loops > 1 or len(goals) > 1:
            pts.append(goals[0])
    return np.asarray(pts, dtype=float)


def resolve_region(scenario: Any, world_map: Any) -> Literal["map", "task"]:
    """``planner.region`` of a scenario on its map: ``auto`` is ``task`` on maps larger
    than :data:`AUTO_REGION_AREA`, else ``map``."""
    if scenario.region != "auto":
        return scenario.region
    return "task" if world_map.width * world_map.height > AUTO_REGION_AREA else "map"


def _period_cells(resolution: float, d: float) -> int:
    """Fewest cells whose span is a whole number of d (1 if none up to
    :data:`_MAX_PERIOD_CELLS`)."""
    for n in range(1, _MAX_PERIOD_CELLS + 1):
        k = n * resolution / d
        if abs(k - round(k)) <= 1e-6 * max(1.0, k) and round(k) >= 1:
            return n
    return 1


def _cell_window(
    world_map: Any, lo: NDArray[np.float64], hi: NDArray[np.float64], period: int
) -> tuple[slice, slice]:
    """Rows and columns of the cells between ``lo`` and ``hi`` (m), the lower ones
    rounded down to a multiple of ``period``, clipped to the grid."""
    ny, nx = world_map.grid_shape
    res = world_map.resolution
    c0 = math.floor((lo[0] - world_map.origin[0]) / res)
    r0 = math.floor((lo[1] - world_map.origin[1]) / res)
    c0, r0 = max(0, c0 - c0 % period), max(0, r0 - r0 % period)
    c1 = min(nx, math.ceil((hi[0] - world_map.origin[0]) / res))
    r1 = min(ny, math.ceil((hi[1] - world_map.origin[1]) / res))
    return slice(r0, max(r1, r0 + 1)), slice(c0, max(c1, c0 + 1))


def _paths(window: Any, points: NDArray[np.float64], footprint: float) -> list[Any] | None:
    """The A* cell paths of ``window`` joining consecutive ``points``, None if one is
    missing (a point not free for the footprint counts as missing)."""
    free = np.ascontiguousarray(window.clearance_grid >= footprint)
    iy, ix, inside = window._cells(points)
    if not np.all(inside) or not np.all(free[iy, ix]):
        return None
    nx = window.grid_shape[1]
    cells = iy * nx + ix
    out = []
    for a, b in itertools.pairwise(cells.tolist()):
        path = astar_cells(free, int(a), int(b))
        if path.size == 0:
            return None
        out.append(path)
    if not out:  # a single position: the region around it
        out.append(cells[:1])
    return out


def task_region(
    world_map: Any,
    waypoints: NDArray[np.float64],
    *,
    footprint_radius: float,
    margin: float,
    d: float,
) -> Any | None:
    """The region of ``world_map`` within ``margin`` (m) of the footprint's shortest
    paths through ``waypoints`` (K, 2) (m), as a map (see the module docstring).

    Returns
    -------
    WorldMap or None
        None when some waypoint is not free for the footprint or some path does not
        exist in the whole map (the whole map's checks then say why).
    """
    pts = np.asarray(waypoints, dtype=float).reshape(-1, 2)
    res = world_map.resolution
    period = _period_cells(res, d)
    pad = margin
    while True:
        rows, cols = _cell_window(world_map, pts.min(axis=0) - pad, pts.max(axis=0) + pad, 1)
        search = world_map.window(rows, cols)
        found = _paths(search, pts, footprint_radius)
        whole = rows.stop - rows.start == world_map.grid_shape[0] and (
            cols.stop - cols.start == world_map.grid_shape[1]
        )
        if found is not None or whole:
            break
        pad *= 2.0
    if found is None:
        return None
    # The path cells in the whole map's indices, then the region around them.
    sub_nx = search.grid_shape[1]
    cells = np.concatenate(found)
    prow = cells // sub_nx + rows.start
    pcol = cells % sub_nx + cols.start
    centres = world_map.origin + res * (np.column_stack([pcol, prow]) + 0.5)
    rows, cols = _cell_window(
        world_map, centres.min(axis=0) - margin, centres.max(axis=0) + margin, period
    )
    marks = np.ones((rows.stop - rows.start, cols.stop - cols.start), dtype=bool)
    marks[prow - rows.start, pcol - cols.start] = False
    near = ndimage.distance_transform_edt(marks, sampling=res) <= margin
    return world_map.window(rows, cols, keep=near)
