"""Swept outer domains: a policy's D'(t) sampled along its reference, grown by the
footprint and the stopping allowance, checked against a map's clearance (compiled)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from gracenav.library.types import ORIENTATIONS, BoolArray, FloatArray, IntArray, _rotate
from gracenav.policies import MotionPolicy
from gracenav.world import WorldMap

__all__ = ["sweep_samples"]

# The compiled sweep check runs in parallel. numba's default layer here is GNU OpenMP,
# which aborts any process that forks after using it (worker pools fork: palette
# builds, campaigns, benchmarks), so a fork-safe layer is chosen unless the user
# chose one (environment variable NUMBA_THREADING_LAYER).
_numba_config: Any = numba.config

if _numba_config.THREADING_LAYER == "default" and "NUMBA_THREADING_LAYER" not in os.environ:
    _numba_config.THREADING_LAYER = "forksafe"

_GROUP = 8  # checked sweep samples per bounding disc of the hierarchical sweep check


@dataclass(frozen=True)
class _Sweep:
    """Checked samples of one palette policy's swept D' (policy frame, footprint excluded).

    A sample j at offset c_j needs clearance(q + c_j) >= footprint + reach_j.
    Groups of consecutive samples are bounded by discs (centre, reach).
    """

    offsets: FloatArray  # (K, 2)
    reach: FloatArray  # (K,)
    group_centre: FloatArray  # (Gp, 2)
    group_reach: FloatArray  # (Gp,)
    group_first: IntArray  # (Gp,) first sample
    group_size: IntArray  # (Gp,)
    total_reach: float  # bound around the start point


def sweep_samples(
    policy: MotionPolicy, step: float, lead: float = 0.0
) -> tuple[FloatArray, FloatArray, IntArray]:
    """Samples of a policy's reference path for checking its swept outer domain D'.

    Parameters
    ----------
    policy : MotionPolicy
    step : float
        Largest arc (m) between selected samples (plus one control tick of motion).
    lead : float
        The path is led by this (s) times the reference velocity.

    Returns
    -------
    pos : ndarray, shape (T+1, 2)
        The (led) reference path relative to its start (m), at every tick.
    cum : ndarray, shape (T+1,)
        Its arc length at each tick (m).
    sel : ndarray of int
        The selected ticks, ascending: the first, the last, and ticks at most
        ``step`` of arc (plus one tick) apart.
    """
    prim = policy.primitive
    pos = prim.position[:, :2] - prim.position[0, :2] + lead * prim.position[:, 2:4]
    seg = np.hypot(*np.diff(pos, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n_ticks = pos.shape[0] - 1
    targets = np.arange(int(cum[-1] // step) + 2) * step
    picked = np.clip(np.searchsorted(cum, targets, side="right") - 1, 0, n_ticks)
    sel = np.unique(np.concatenate([[0], picked, [n_ticks]]))
    return pos, cum, sel


def _sweep(
    policy: MotionPolicy,
    step: float,
    samples: tuple[FloatArray, FloatArray, IntArray] | None = None,
    speed_clearance: float = 0.0,
) -> _Sweep:
    """Select samples of the reference path (led by half the stopping allowance times
    the velocity) at most ``step`` of arc (plus one tick) apart and the conservative
    reach of D' around each, plus half the allowance ``speed_clearance`` (s) times the
    reference speed (see :func:`build_library`). ``samples``: :func:`sweep_samples`
    of the policy's primitive with that lead, if already computed."""
    prim = policy.primitive
    half = 0.5 * speed_clearance
    pos, cum, sel = samples if samples is not None else sweep_samples(policy, step, half)
    outer, _ = policy.outer_extents(sel * prim.dt)
    speed = np.hypot(prim.position[:, 2], prim.position[:, 3])
    reach = outer + half * speed[sel]
    if sel.size > 1:
        # The fastest tick from one sample to the next, both included.
        seg_speed = np.maximum(np.maximum.reduceat(speed, sel)[:-1], speed[sel[1:]])
        seg_reach = np.maximum(outer[:-1], outer[1:]) + half * seg_speed + 0.5 * np.diff(cum[sel])
        reach[:-1] = np.maximum(reach[:-1], seg_reach)
        reach[1:] = np.maximum(reach[1:], seg_reach)
    offsets = pos[sel]
    first = np.arange(0, sel.size, _GROUP, dtype=np.int64)
    size = np.minimum(_GROUP, sel.size - first)
    centres = 0.5 * (
        np.minimum.reduceat(offsets, first, axis=0) + np.maximum.reduceat(offsets, first, axis=0)
    )
    own = np.repeat(np.arange(first.size), size)
    greach = np.maximum.reduceat(np.hypot(*(offsets - centres[own]).T) + reach, first)
    total = float(np.max(np.hypot(*offsets.T) + reach))
    return _Sweep(offsets, reach, centres, greach, first, size, total)


def _check_sweeps(
    world_map: WorldMap,
    points: FloatArray,
    pair_type: IntArray,
    pair_point: IntArray,
    tables: dict[str, NDArray[Any]],
    footprint: float,
) -> BoolArray:
    """Validity of undecided (type, point) pairs: group discs first, samples where a
    group disc is not clear (compiled; the clearance is computed as
    :meth:`gracenav.world.WorldMap.clearance` computes it, operation for operation)."""
    valid = np.ones(pair_type.size, dtype=bool)
    if pair_type.size == 0:
        return valid
    _, nearest = world_map._clearance_data()
    (x0, y0), (x1, y1) = world_map.bounds
    _check_sweeps_kernel(
        valid,
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(pair_type, dtype=np.int64),
        np.ascontiguousarray(pair_point, dtype=np.int64),
        tables["type_group_first"],
        tables["type_group_count"],
        tables["group_centre"],
        tables["group_reach"],
        tables["group_sample_first"],
        tables["group_size"],
        tables["sample_offset"],
        tables["sample_reach"],
        float(footprint),
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
    return valid


@njit(cache=True, nogil=True)
def _clearance_at(
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
    the same order (so the same value)."""
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
    best = np.inf
    for k in range(4):
        dyk = k >> 1
        dxk = k & 1
        jy = nearest[0, ky + dyk, kx + dxk] - 1
        jx = nearest[1, ky + dyk, kx + dxk] - 1
        bx0 = ox + jx * res
        by0 = oy + jy * res
        dx = max(max(bx0 - px, px - (bx0 + res)), 0.0)
        dy = max(max(by0 - py, py - (by0 + res)), 0.0)
        best = min(best, np.hypot(dx, dy))
    edge = min(min(px - xmin, xmax - px), min(py - ymin, ymax - py))
    return max(min(best, edge), 0.0)


@njit(cache=True, nogil=True, parallel=True)
def _check_sweeps_kernel(
    valid: Any,
    points: Any,
    pair_type: Any,
    pair_point: Any,
    type_group_first: Any,
    type_group_count: Any,
    group_centre: Any,
    group_reach: Any,
    group_sample_first: Any,
    group_size: Any,
    sample_offset: Any,
    sample_reach: Any,
    footprint: float,
    nearest: Any,
    occupied: Any,
    ox: float,
    oy: float,
    res: float,
    xmin: float,
    ymin: float,
    xmax: float,
    ymax: float,
) -> None:
    """Mark the pairs whose swept D' is not clear: a pair is valid iff in every group
    either the bounding disc or every sample is clear (see :func:`build_library`)."""
    for a in prange(pair_type.size):  # independent pairs: no shared writes
        t = pair_type[a]
        qx = points[pair_point[a], 0]
        qy = points[pair_point[a], 1]
        g0 = type_group_first[t]
        for g in range(g0, g0 + type_group_count[t]):
            c = _clearance_at(
                qx + group_centre[g, 0],
                qy + group_centre[g, 1],
                nearest,
                occupied,
                ox,
                oy,
                res,
                xmin,
                ymin,
                xmax,
                ymax,
            )
            if c >= footprint + group_reach[g]:
                continue
            s0 = group_sample_first[g]
            for k in range(s0, s0 + group_size[g]):
                c = _clearance_at(
                    qx + sample_offset[k, 0],
                    qy + sample_offset[k, 1],
                    nearest,
                    occupied,
                    ox,
                    oy,
                    res,
                    xmin,
                    ymin,
                    xmax,
                    ymax,
                )
                if c < footprint + sample_reach[k]:
                    valid[a] = False
                    break
            if not valid[a]:
                break


def _sweep_tables(sweeps: list[_Sweep]) -> dict[str, NDArray[Any]]:
    """Concatenate the sweeps of every type (rotated) into flat tables."""
    offs, reach, gc, gr, gsf, gsz, tgf, tgc, total = [], [], [], [], [], [], [], [], []
    n_samples = n_groups = 0
    for sw in sweeps:
        for k in range(ORIENTATIONS):
            offs.append(_rotate(sw.offsets, k))
            reach.append(sw.reach)
            gc.append(_rotate(sw.group_centre, k))
            gr.append(sw.group_reach)
            gsf.append(sw.group_first + n_samples)
            gsz.append(sw.group_size)
            tgf.append(n_groups)
            tgc.append(sw.group_first.size)
            total.append(sw.total_reach)
            n_samples += sw.offsets.shape[0]
            n_groups += sw.group_first.size
    return {
        "sample_offset": np.concatenate(offs),
        "sample_reach": np.concatenate(reach),
        # What the start point's own clearance must exceed (the first sample leads it by
        # half the allowance times the start velocity; clearance is 1-Lipschitz).
        "sample_first_reach": np.array(
            [sw.reach[0] - math.hypot(*sw.offsets[0]) for sw in sweeps for _ in range(4)]
        ),
        "group_centre": np.concatenate(gc),
        "group_reach": np.concatenate(gr),
        "group_sample_first": np.concatenate(gsf).astype(np.int64),
        "group_size": np.concatenate(gsz).astype(np.int64),
        "type_group_first": np.array(tgf, dtype=np.int64),
        "type_group_count": np.array(tgc, dtype=np.int64),
        "type_total_reach": np.array(total),
    }
