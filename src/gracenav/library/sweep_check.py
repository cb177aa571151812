"""The compiled sweep check: which placed policies' swept domains clear a map.

Each undecided (policy type, lattice point) pair is checked at the sweep tables of
:func:`gracenav.library.sweeps.sweep_tables` against the map's clearance (the values of
:meth:`gracenav.world.WorldMap.clearance`, operation for operation): bounding discs
first, samples only where a disc is not clear; compiled, in parallel.
"""

from __future__ import annotations

import os
from typing import Any

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from gracenav.library.sweeps import GROUP
from gracenav.library.types import BoolArray, FloatArray, IntArray
from gracenav.world import WorldMap

__all__ = [
    "check_sweeps",
    "clearance_at",
    "map_grid",
]

# The compiled sweep check runs in parallel. numba's default layer here is GNU OpenMP,
# which aborts any process that forks after using it (worker pools fork: palette
# builds, campaigns, benchmarks), so a fork-safe layer is chosen unless the user
# chose one (environment variable NUMBA_THREADING_LAYER).
_numba_config: Any = numba.config

if _numba_config.THREADING_LAYER == "default" and "NUMBA_THREADING_LAYER" not in os.environ:
    _numba_config.THREADING_LAYER = "forksafe"


def check_sweeps(
    world_map: WorldMap,
    points: FloatArray,
    pair_type: IntArray,
    pair_point: IntArray,
    tables: dict[str, NDArray[Any]],
    footprint: float,
) -> BoolArray:
    """Validity of undecided (type, point) pairs: the discs bounding groups of groups
    first, then the group discs where one is not clear, then the samples where a group
    disc is not clear; a type's group that failed last is checked first at the next
    pair (neighbouring points tend to fail at the same place; the verdicts do not
    depend on the order). Compiled; the clearance is computed as
    :meth:`gracenav.world.WorldMap.clearance` computes it, operation for operation."""
    valid = np.ones(pair_type.size, dtype=bool)
    if pair_type.size == 0:
        return valid
    grid, floor = map_grid(world_map)
    hint = np.full(tables["type_super_first"].size, -1, dtype=np.int64)
    supers = tuple(
        tables[k]
        for k in (
            "type_super_first",
            "type_super_count",
            "super_centre",
            "super_reach",
            "super_group_first",
            "super_size",
        )
    )
    groups = tuple(
        tables[k]
        for k in (
            "group_centre",
            "group_reach",
            "group_sample_first",
            "group_size",
            "sample_offset",
            "sample_reach",
        )
    )
    _check_sweeps_kernel(
        valid,
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(pair_type, dtype=np.int64),
        np.ascontiguousarray(pair_point, dtype=np.int64),
        supers,
        groups,
        hint,
        float(footprint),
        grid,
        floor,
        GROUP,
    )
    return valid


def map_grid(world_map: WorldMap) -> tuple[tuple[Any, ...], FloatArray]:
    """The map as the compiled check reads it: the grid (nearest occupied cells,
    occupancy, origin, resolution and bounds: the arguments of :func:`clearance_at`
    after the point) and its :func:`_clearance_floor`, computed once per map and kept
    with its clearance data (8 bytes a cell, counted in the memory budget's
    ``MAP_CELL_BYTES``)."""
    _, nearest = world_map._clearance_data()
    (x0, y0), (x1, y1) = world_map.bounds
    grid = (
        nearest,
        np.ascontiguousarray(world_map.occupied, dtype=np.bool_),
        float(world_map.origin[0]),
        float(world_map.origin[1]),
        float(world_map.resolution),
        float(x0),
        float(y0),
        float(x1),
        float(y1),
    )
    floor = world_map._cache.get("clearance_floor")
    if floor is None:
        floor = world_map._cache["clearance_floor"] = _clearance_floor(*grid)
        floor.setflags(write=False)
    return grid, floor


@njit(cache=True, nogil=True)
def clearance_at(
    px: float,
    py: float,
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> float:
    """:meth:`gracenav.world.WorldMap.clearance` of one point, the same operations in
    the same order (so the same value). ``check_sweeps`` passes the arguments after
    the point as one tuple, the grid."""
    ny, nx = occupied.shape
    fx = np.floor((px - ox) / res)
    fy = np.floor((py - oy) / res)
    if not (fx >= 0 and fx < nx and fy >= 0 and fy < ny):
        return 0.0
    iy = int(fy)
    ix = int(fx)
    if occupied[iy, ix]:
        return 0.0
    ky = int(np.floor((py - oy) / res - 0.5)) + 1
    kx = int(np.floor((px - ox) / res - 0.5)) + 1
    best = _nearest_squares(nearest, ky, kx, ox, oy, res, px, px, py, py)
    edge = min(min(px - xmin, xmax - px), min(py - ymin, ymax - py))
    return max(min(best, edge), 0.0)


@njit(cache=True, nogil=True)
def _nearest_squares(
    nearest: Any,
    ky: int,
    kx: int,
    ox: float,
    oy: float,
    res: float,
    x0: float,
    x1: float,
    y0: float,
    y1: float,
) -> float:
    """Distance from the rectangle [x0, x1] × [y0, y1] (a point when x0 = x1, y0 = y1)
    to the nearest of the occupied squares nearest to the four cell centres around
    index (ky, kx) of ``nearest`` (with a point, the operations of
    :meth:`gracenav.world.WorldMap.clearance`)."""
    best = np.inf
    for k in range(4):
        dyk = k >> 1
        dxk = k & 1
        jy = nearest[0, ky + dyk, kx + dxk] - 1
        jx = nearest[1, ky + dyk, kx + dxk] - 1
        bx0 = ox + jx * res
        by0 = oy + jy * res
        dx = max(max(bx0 - x1, x0 - (bx0 + res)), 0.0)
        dy = max(max(by0 - y1, y0 - (by0 + res)), 0.0)
        best = min(best, np.hypot(dx, dy))
    return best


#: What :func:`_clearance_floor` takes off its bounds (m): far more than the rounding of
#: the clearance's own arithmetic (about 1e-15 m), so a bound never exceeds a value.
_FLOOR_SLACK = 1e-9


@njit(cache=True)
def _clearance_floor(
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> FloatArray:
    """A lower bound on :func:`clearance_at` over each cell of the half-cell-shifted
    grid whose four surrounding cell centres (and so whose four nearest occupied cells)
    it shares, shape (ny + 1, nx + 1), indexed as :func:`clearance_at` indexes
    ``nearest`` (row ``floor((y - oy) / res - 0.5) + 1``): the distance from that
    rectangle to the nearest of the four occupied cells' squares or to the map edge,
    less :data:`_FLOOR_SLACK`; 0 where the rectangle reaches outside the grid."""
    ny, nx = occupied.shape
    out = np.empty((ny + 1, nx + 1))
    for ky in range(ny + 1):
        ry0 = oy + (ky - 0.5) * res
        ry1 = oy + (ky + 0.5) * res
        for kx in range(nx + 1):
            rx0 = ox + (kx - 0.5) * res
            rx1 = ox + (kx + 0.5) * res
            if ky == 0 or kx == 0 or ky == ny or kx == nx:
                out[ky, kx] = 0.0  # part of the rectangle lies off the grid: clearance 0
                continue
            best = _nearest_squares(nearest, ky, kx, ox, oy, res, rx0, rx1, ry0, ry1)
            edge = min(min(rx0 - xmin, xmax - rx1), min(ry0 - ymin, ymax - ry1))
            out[ky, kx] = max(min(best, edge), 0.0) - _FLOOR_SLACK
    return out


@njit(cache=True, nogil=True)
def _disc_clear(px: float, py: float, need: float, floor: Any, grid: Any) -> bool:
    """Whether :func:`clearance_at` at (px, py) is at least ``need``: decided by the
    point's cell of :func:`_clearance_floor` when that bound reaches ``need`` (the same
    verdict, without the four nearest cells), else by the clearance itself."""
    oy = grid[3]
    ox = grid[2]
    res = grid[4]
    ky = np.floor((py - oy) / res - 0.5) + 1
    kx = np.floor((px - ox) / res - 0.5) + 1
    if ky >= 0 and ky < floor.shape[0] and kx >= 0 and kx < floor.shape[1]:
        if floor[int(ky), int(kx)] >= need:
            return True
    return clearance_at(px, py, *grid) >= need


@njit(cache=True, nogil=True)
def _group_clear(
    g: int, qx: float, qy: float, footprint: float, groups: Any, grid: Any, floor: Any
) -> bool:
    """Whether group ``g`` of the swept samples is clear at (qx, qy): its disc, or else
    every sample (``groups``: the group and sample tables, ``grid``: the map's, as
    :func:`check_sweeps` packs them; ``floor``: :func:`_clearance_floor`)."""
    centre, reach, sample_first, size, sample_offset, sample_reach = groups
    if _disc_clear(qx + centre[g, 0], qy + centre[g, 1], footprint + reach[g], floor, grid):
        return True
    for k in range(sample_first[g], sample_first[g] + size[g]):
        if not _disc_clear(
            qx + sample_offset[k, 0],
            qy + sample_offset[k, 1],
            footprint + sample_reach[k],
            floor,
            grid,
        ):
            return False
    return True


@njit(cache=True, nogil=True, parallel=True)
def _check_sweeps_kernel(
    valid: Any,
    points: Any,
    pair_type: Any,
    pair_point: Any,
    supers: Any,
    groups: Any,
    hint: Any,
    footprint: float,
    grid: Any,
    floor: Any,
    group: int,
) -> None:
    """Mark the pairs whose swept D' is not clear: a pair is valid iff in every group
    of groups either its bounding disc or, in every group, the group's disc or every
    sample is clear (see :func:`build_library`). ``hint[t]``: the group at which type
    t failed last (-1: none), checked first, behind its group of groups' disc as in the
    full check; threads write it without order, which changes only how soon a failing
    pair is found, never the verdict. ``floor``: :func:`_clearance_floor`, which decides
    a disc at one look-up when the map leaves it room to spare. ``group``: the groups
    per group of groups (:data:`gracenav.library.sweeps.GROUP`), an argument rather than
    a global read when compiling, which the cache would keep past a change of
    :mod:`~gracenav.library.sweeps`."""
    type_first, type_count, centre, reach, group_first, size = supers
    for a in prange(pair_type.size):  # independent pairs: the hints are only hints
        t = pair_type[a]
        qx = points[pair_point[a], 0]
        qy = points[pair_point[a], 1]
        h = hint[t]
        bad = False
        if h >= 0:
            # The hinted group as the loop below would reach it: within its group of
            # groups (runs of `group` from the type's first group), only when that
            # group's disc is not clear, so the verdict never depends on the hint.
            s0 = type_first[t]
            sh = s0 + (h - group_first[s0]) // group
            near = not _disc_clear(
                qx + centre[sh, 0], qy + centre[sh, 1], footprint + reach[sh], floor, grid
            )
            bad = near and not _group_clear(h, qx, qy, footprint, groups, grid, floor)
        for sg in range(type_first[t], type_first[t] + type_count[t]):
            if bad:
                break
            if _disc_clear(
                qx + centre[sg, 0], qy + centre[sg, 1], footprint + reach[sg], floor, grid
            ):
                continue
            for g in range(group_first[sg], group_first[sg] + size[sg]):
                if g != h and not _group_clear(g, qx, qy, footprint, groups, grid, floor):
                    bad = True
                    hint[t] = g
                    break
        valid[a] = not bad
