"""Sweep samples: each palette policy's swept outer domain D' as discs to check.

A policy's D'(t) is sampled along its reference, grown by the footprint, the stopping
allowance and, with a design push, the push fan's catch discs; the discs are bounded
group by group, and the sweeps of every policy type are concatenated into the tables
that :mod:`~gracenav.library.sweep_check` checks against a map.

The modules depend one way: :mod:`~gracenav.library.push_fans` builds its catches'
discs with :func:`swept_discs` and :mod:`~gracenav.library.sweep_check` reads
:data:`GROUP` from here; this module imports neither (:func:`sweep` reaches a push fan
through :class:`FanDiscs`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from gracenav.library.types import ORIENTATIONS, FloatArray, IntArray, _rotate
from gracenav.model.rotation import rotate_pairs
from gracenav.policies import MotionPolicy

__all__ = [
    "GROUP",
    "FanDiscs",
    "sweep",
    "sweep_samples",
    "sweep_tables",
    "swept_discs",
]

GROUP = 8  # checked sweep samples per bounding disc of the hierarchical sweep check


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
    # Groups of consecutive groups, bounded by discs too (a push fan's thousands of
    # samples per policy are checked group by group only near obstacles).
    super_centre: FloatArray  # (Sp, 2)
    super_reach: FloatArray  # (Sp,)
    super_first: IntArray  # (Sp,) first group
    super_size: IntArray  # (Sp,)


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


def swept_discs(policy: MotionPolicy, step: float) -> tuple[FloatArray, FloatArray]:
    """Discs whose union holds a policy's swept D' (policy frame, from its start).

    Reference samples (K, 2) at most ``step`` of arc apart and the XY radius of D'
    there plus half the arc to a neighbouring sample (K,), as instantiation checks a
    swept D'. A D' whose XY section is an ellipse (along a, across b <= a; a policy
    with ``outer_cross``) lies in the discs of radius b centred on its major axis
    within a - b of its centre: the straight path is extended by a - b at both ends.
    """
    pos, cum, sel = sweep_samples(policy, step)
    outer, _ = policy.outer_extents(sel * policy.primitive.dt)
    along = float(np.max(outer))
    if policy.outer_cross is not None and np.any(policy.primitive.start_velocity):
        ext = along - policy.outer_cross
        u = policy.primitive.start_velocity / np.hypot(*policy.primitive.start_velocity)
        k = np.arange(1, int(np.ceil(ext / step)) + 1)
        grow = np.minimum(k * step, ext)
        pts = np.concatenate(
            [(-grow[::-1])[:, None] * u, pos[sel], pos[sel][-1] + grow[:, None] * u]
        )
        cum_all = np.concatenate([-grow[::-1], cum[sel], cum[sel][-1] + grow])
        outer = np.full(pts.shape[0], policy.outer_cross)
    else:
        pts, cum_all = pos[sel], cum[sel]
    reach = np.asarray(outer, dtype=float).copy()
    if pts.shape[0] > 1:
        half = 0.5 * np.diff(cum_all)
        seg = np.maximum(outer[:-1], outer[1:]) + half
        reach[:-1] = np.maximum(reach[:-1], seg)
        reach[1:] = np.maximum(reach[1:], seg)
    return np.ascontiguousarray(pts), reach


class FanDiscs(Protocol):
    """What :func:`sweep` asks of a push fan
    (:class:`~gracenav.library.push_fans.PushFan`): a protocol, so that this module does
    not import the fan's, which builds the fan's discs with :func:`swept_discs`."""

    def with_discs(
        self, prim: Any, offsets: FloatArray, reach: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """``offsets`` and ``reach`` with the fan's discs along ``prim``'s reference
        appended."""
        ...


def sweep(
    policy: MotionPolicy,
    step: float,
    samples: tuple[FloatArray, FloatArray, IntArray] | None = None,
    speed_clearance: float = 0.0,
    fan: FanDiscs | None = None,
) -> _Sweep:
    """Select samples of the reference path (led by half the stopping allowance times
    the velocity) at most ``step`` of arc (plus one tick) apart and the conservative
    reach of D' around each, plus half the allowance ``speed_clearance`` (s) times the
    reference speed (see :func:`build_library`). ``samples``: :func:`sweep_samples`
    of the policy's primitive with that lead, if already computed. With ``fan``, the
    discs of the catches of the design push (:meth:`PushFan.samples_along`) where the flat
    output is faster than ``fan.above`` are checked too (:meth:`PushFan.with_discs`,
    :class:`~gracenav.library.push_fans.PushFan`); a policy
    with a pushed state that no catch holds gets an infinite reach (it is placed
    nowhere)."""
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
    if fan is not None:
        offsets, reach = fan.with_discs(prim, offsets, reach)
    centres, greach, first, size = _bounding_discs(offsets, reach)
    total = float(np.max(np.hypot(*offsets.T) + reach))
    scentres, sreach, sfirst, ssize = _bounding_discs(centres, greach)
    return _Sweep(
        offsets, reach, centres, greach, first, size, total, scentres, sreach, sfirst, ssize
    )


def _bounding_discs(
    centres: FloatArray, reach: FloatArray
) -> tuple[FloatArray, FloatArray, IntArray, IntArray]:
    """Discs bounding each run of :data:`GROUP` consecutive discs (``centres``,
    ``reach``): (centres, reach, first disc, discs). A bounding disc's centre is the
    middle of its discs' centres' box, its reach the farthest any of them reaches from
    there, so a point whose clearance exceeds it (clearance is 1-Lipschitz) clears
    every disc it bounds."""
    first = np.arange(0, centres.shape[0], GROUP, dtype=np.int64)
    size = np.minimum(GROUP, centres.shape[0] - first)
    mid = 0.5 * (
        np.minimum.reduceat(centres, first, axis=0) + np.maximum.reduceat(centres, first, axis=0)
    )
    own = np.repeat(np.arange(first.size), size)
    bound = np.maximum.reduceat(np.hypot(*(centres - mid[own]).T) + reach, first)
    return mid, bound, first, size


def sweep_tables(sweeps: list[_Sweep]) -> dict[str, NDArray[Any]]:
    """Concatenate the sweeps of every type (rotated) into flat tables."""
    gc, gr, gsf, gsz, total = [], [], [], [], []
    sc, sr, sgf, ssz, tsf, tsc = [], [], [], [], [], []
    n_samples = n_groups = n_supers = 0
    # The samples (most of the tables: millions with a design push) are written in
    # place, rotated, rather than rotated into copies and concatenated.
    size = ORIENTATIONS * sum(sw.offsets.shape[0] for sw in sweeps)
    sample_offset = np.empty((size, 2))
    sample_reach = np.empty(size)
    for sw in sweeps:
        for k in range(ORIENTATIONS):
            sc.append(_rotate(sw.super_centre, k))
            sr.append(sw.super_reach)
            sgf.append(sw.super_first + n_groups)
            ssz.append(sw.super_size)
            tsf.append(n_supers)
            tsc.append(sw.super_first.size)
            n_supers += sw.super_first.size
            rows = slice(n_samples, n_samples + sw.offsets.shape[0])
            rotate_pairs(sw.offsets, k, out=sample_offset[rows])
            sample_reach[rows] = sw.reach
            gc.append(_rotate(sw.group_centre, k))
            gr.append(sw.group_reach)
            gsf.append(sw.group_first + n_samples)
            gsz.append(sw.group_size)
            total.append(sw.total_reach)
            n_samples += sw.offsets.shape[0]
            n_groups += sw.group_first.size
    return {
        "sample_offset": sample_offset,
        "sample_reach": sample_reach,
        # What the start point's own clearance must exceed (the first sample leads it by
        # half the allowance times the start velocity; clearance is 1-Lipschitz).
        "sample_first_reach": np.array(
            [sw.reach[0] - math.hypot(*sw.offsets[0]) for sw in sweeps for _ in range(4)]
        ),
        "group_centre": np.concatenate(gc),
        "group_reach": np.concatenate(gr),
        "group_sample_first": np.concatenate(gsf).astype(np.int64),
        "group_size": np.concatenate(gsz).astype(np.int64),
        "super_centre": np.concatenate(sc),
        "super_reach": np.concatenate(sr),
        "super_group_first": np.concatenate(sgf).astype(np.int64),
        "super_size": np.concatenate(ssz).astype(np.int64),
        "type_super_first": np.array(tsf, dtype=np.int64),
        "type_super_count": np.array(tsc, dtype=np.int64),
        "type_total_reach": np.array(total),
    }
