"""Shortest paths on occupancy grids: A* over the cells of a map that a footprint keeps
free (the decoupled baseline's geometric path, and the task region of a library)."""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["astar_cells"]


@njit(cache=True)
def astar_cells(  # pragma: no cover
    free: NDArray[np.bool_], start: int, goal: int
) -> NDArray[np.int64]:
    """Cell indices (row-major) of a shortest 8-connected path on the cells where
    ``free`` (ny, nx) is True, from cell ``start`` to cell ``goal`` (row-major indices),
    both included; empty if there is none.

    A* with the octile heuristic (consistent, so the path is shortest on the grid);
    diagonal moves need both side cells free (no corner cutting). Compiled.
    """
    ny, nx = free.shape
    n = ny * nx
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    di = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
    dj = np.array([-1, 0, 1, -1, 1, -1, 0, 1])
    gi, gj = goal // nx, goal % nx
    g[start] = 0.0
    heap = [(0.0, start)]
    found = False
    while len(heap) > 0:
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == goal:
            found = True
            break
        closed[u] = True
        ui, uj = u // nx, u % nx
        for k in range(8):
            vi = ui + di[k]
            vj = uj + dj[k]
            if vi < 0 or vi >= ny or vj < 0 or vj >= nx or not free[vi, vj]:
                continue
            diag = di[k] != 0 and dj[k] != 0
            if diag and not (free[ui, vj] and free[vi, uj]):
                continue  # no corner cutting
            v = vi * nx + vj
            if closed[v]:
                continue
            ng = g[u] + (1.4142135623730951 if diag else 1.0)
            if ng < g[v]:
                g[v] = ng
                parent[v] = u
                dx = abs(vj - gj)
                dy = abs(vi - gi)
                h = dx + dy + (1.4142135623730951 - 2.0) * min(dx, dy)
                heapq.heappush(heap, (ng + h, v))
    if not found:
        return np.zeros(0, dtype=np.int64)
    count = 1
    u = goal
    while u != start:
        u = parent[u]
        count += 1
    out = np.empty(count, dtype=np.int64)
    u = goal
    for k in range(count - 1, -1, -1):
        out[k] = u
        u = parent[u]
    return out
