"""Automatic instantiation (paper Sec. V-A): the palette placed on a lattice of the map
at spacing d, d/2, ... wherever the swept domains clear the obstacles, within a memory
budget checked before anything is allocated."""

from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError
from gracenav.library.library import DEFAULT_COVERAGE_SAMPLES, PolicyLibrary, sample_position_states
from gracenav.library.push_fans import push_fan
from gracenav.library.sweep_check import check_sweeps
from gracenav.library.sweeps import sweep, sweep_samples, sweep_tables
from gracenav.library.types import (
    _LATTICE_EPS,
    BoolArray,
    FloatArray,
    InstantiationIteration,
    IntArray,
    PolicyTypes,
    _readonly,
)
from gracenav.palette import Palette
from gracenav.world import WorldMap

__all__ = [
    "DEFAULT_DESIGN_PUSH",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_SPEED_CLEARANCE",
    "ESTIMATE_SAMPLES",
    "LATTICE_POINT_BYTES",
    "MAX_DESIGN_PUSH",
    "MAX_SPEED_CLEARANCE",
    "POLICY_BYTES",
    "LibrarySizeEstimate",
    "build_library",
    "estimate_library_size",
    "expected_library_size",
    "lattice_origin",
    "lattice_points",
    "max_trim_speed",
]

#: Peak memory per library policy (bytes) of building the library, its graph with the
#: edges generated from the lattice and one search, measured on a 100 m open hall
#: (6.28 M policies, 1.56 GiB peak of which 0.31 GiB before the library).
POLICY_BYTES = 208

#: Default memory limit (bytes) of :func:`build_library`: 4 GiB.
DEFAULT_MEMORY_LIMIT = 4 * 2**30

#: Bytes per lattice point that estimating a pass allocates (coordinates, clearance and
#: its sorted copy, per-point counts); a lattice above the limit at this rate is refused
#: by arithmetic, before anything is allocated.
LATTICE_POINT_BYTES = 64

#: Undecided lattice points checked by :func:`expected_library_size` (a seeded uniform
#: sample; all of them when there are fewer): ≈ 1.3 % standard error and ≈ 0.1 s on the
#: 30 m × 50 m warehouse and the 100 m office (bench/bench_bigmaps.py).
ESTIMATE_SAMPLES = 512

#: Default stopping allowance of :func:`build_library` (s): extra clearance per m/s of
#: reference speed toward an obstacle. With it every one of 900 seeded pushes (0–16 N s
#: on the 5 m room, bench/bench_pushes.py) is caught by a verified policy, against 97.0–
#: 98.7 % without; the unpushed run there takes 1 % longer. Larger allowances cut off
#: narrow passages: of 400 random rest-to-rest pairs on the cluttered 6 m room, 131 are
#: possible without, 130 with 0.1 s, 118 with 0.2 s and 104 with 0.3 s; on a 50 m office
#: with 1 m doors the corridors' strongly connected part loses 30 % of its policies.
DEFAULT_SPEED_CLEARANCE = 0.1

#: Largest stopping allowance accepted (s).
MAX_SPEED_CLEARANCE = 2.0

#: Cells (types × lattice points) of the masks instantiation decides at once.
_CHOOSE_CELLS = 2**22

#: Largest design push accepted (N s): twice the capture regulators' largest verified push.
MAX_DESIGN_PUSH = 80.0

#: Default design push of :func:`build_library` (N s). It acts only where a reference's
#: flat output is faster than :data:`gracenav.library.push_fans.FAN_FLOOR` (0.8 m/s), so
#: the shipped palette's libraries do not change. With the speed levels (the ``speed``
#: palette: ``gracenav palette build --cruise-speeds 1.0 1.2 --max-ball-jerk 6``) it
#: catches every one of 900 seeded pushes of 0–16 N s on the 5 m room (291–295 of 300
#: per seed without)
#: and keeps the 1.2 m/s level, so the 23.8 m diagonal of bench/bench_speed.py takes
#: 25.37 s (1.48 times its physical bound) against 25.05 s without; 16 N s would
#: leave that level out (28.52 s). docs/design/speed.md has the measurements.
DEFAULT_DESIGN_PUSH = 8.0

#: The palette's types and swept outer domain tables of one sweep step, speed clearance
#: and design push.
_Tables = tuple[PolicyTypes, dict[str, NDArray[Any]]]


class _PaletteTables:
    """Instantiation's tables of each live palette, by sweep step, speed clearance and
    design push (``f"{step!r}-{speed_clearance!r}-{design_push!r}"``).

    A palette is keyed by identity (it is not hashable) and held weakly: its entry goes
    when it is collected. The tables hold no reference to the palette.
    """

    def __init__(self) -> None:
        self._entries: dict[int, tuple[weakref.ref[Palette], dict[str, _Tables]]]
        self._entries = {}

    def of(self, palette: Palette) -> dict[str, _Tables]:
        """The tables computed so far for ``palette`` (a dict to add to)."""
        key = id(palette)
        got = self._entries.get(key)
        if got is not None and got[0]() is palette:
            return got[1]
        entries = self._entries

        def forget(ref: weakref.ref[Palette]) -> None:
            if key in entries and entries[key][0] is ref:
                del entries[key]

        tables: dict[str, _Tables] = {}
        entries[key] = (weakref.ref(palette, forget), tables)
        return tables


_PALETTE_TABLES = _PaletteTables()


def _palette_tables(
    palette: Palette, step: float, speed_clearance: float, design_push: float = 0.0
) -> _Tables:
    """The palette's types and swept outer domain tables for sweep step ``step``,
    ``speed_clearance`` and ``design_push``: they depend on the palette only, so they
    are computed once per palette, step, speed clearance and design push."""
    cache = _PALETTE_TABLES.of(palette)
    key = f"{step!r}-{speed_clearance!r}-{design_push!r}"
    cached = cache.get(key)
    if cached is None:
        fan = push_fan(palette, design_push, step)
        samples: dict[int, tuple[FloatArray, FloatArray, IntArray]] = {}
        sweeps = []
        for pol in palette.policies:
            got = samples.get(id(pol.primitive))
            if got is None:
                got = samples[id(pol.primitive)] = sweep_samples(pol, step, 0.5 * speed_clearance)
            sweeps.append(sweep(pol, step, got, speed_clearance, fan))
        cached = cache[key] = (
            PolicyTypes.from_palette(palette),
            sweep_tables(sweeps),
        )
    return cached


def lattice_origin(
    world_map: WorldMap, spacing: float, anchor: ArrayLike | None = None
) -> FloatArray:
    """The first point (2,) of the instantiation lattice of ``spacing`` on the map: its
    minimum corner, or with ``anchor`` (x, y) the lattice point nearest that corner
    among those of the lattice through ``anchor`` (inside the map)."""
    corner = np.asarray(world_map.bounds[0], dtype=float)
    if anchor is None:
        return corner
    a = np.asarray(anchor, dtype=float).reshape(2)
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"a lattice anchor is a finite point (x, y), got {anchor!r}")
    off = np.mod(a - corner, spacing)
    # A point within rounding of the next lattice line is on it.
    off = np.where(spacing - off < _LATTICE_EPS * spacing, 0.0, off)
    out: FloatArray = corner + off
    return out


def _lattice(
    world_map: WorldMap, spacing: float, anchor: ArrayLike | None = None
) -> tuple[FloatArray, int, int, FloatArray]:
    """Origin (2,), nx, ny and the points (ny · nx, 2) of the instantiation lattice
    (anchored at the map's minimum corner, or through ``anchor``)."""
    (x0, y0), (x1, y1) = world_map.bounds
    x0, y0 = (float(v) for v in lattice_origin(world_map, spacing, anchor))
    nx = math.floor((x1 - x0) / spacing + _LATTICE_EPS) + 1
    ny = math.floor((y1 - y0) / spacing + _LATTICE_EPS) + 1
    origin = np.array([x0, y0])
    ix = np.tile(np.arange(nx), ny)
    iy = np.repeat(np.arange(ny), nx)
    pts = np.column_stack([x0 + ix * spacing, y0 + iy * spacing])
    return origin, nx, ny, pts


def _choose(
    types: PolicyTypes,
    tables: dict[str, NDArray[Any]],
    world_map: WorldMap,
    points: FloatArray,
    c0: FloatArray,
    footprint: float,
) -> tuple[IntArray, IntArray]:
    """(type, point index) of every policy instantiation keeps at ``points`` (clearance
    ``c0``), grouped by start domain size from the largest: a scale group (a policy, its
    larger-domain variants and its fine copies at one orientation) takes at each point
    the largest size whose swept D' fits, so a smaller size is only checked where every
    larger one failed. The pairs come in no particular order (a scale group has one
    type of each size, so the decisions of one size do not depend on each other)."""
    taken = np.zeros((int(types.scale_group.max(initial=-1)) + 1, points.shape[0]), dtype=bool)
    found_t: list[IntArray] = [np.zeros(0, dtype=np.int64)]
    found_q: list[IntArray] = [np.zeros(0, dtype=np.int64)]
    placed_types = _placed_types(types)
    first_reach = footprint + tables["sample_first_reach"]
    total_reach = footprint + tables["type_total_reach"]
    for size in np.unique(types.start_radii[:, 0])[::-1]:
        # A capture regulator is invariant under rotations (rest reference, round
        # domains in the plane): one orientation suffices.
        placed = np.flatnonzero((types.start_radii[:, 0] == size) & placed_types)
        if placed.size == 0:
            continue
        group = types.scale_group[placed]
        sure_t: list[IntArray] = []
        sure_q: list[IntArray] = []
        undecided_t: list[IntArray] = []
        undecided_q: list[IntArray] = []
        # Types × points at once, in chunks of points that bound the masks' memory.
        chunk = max(1, _CHOOSE_CELLS // placed.size)
        for a in range(0, points.shape[0], chunk):
            c = c0[a : a + chunk]
            maybe = (c[None, :] >= first_reach[placed][:, None]) & ~taken[group, a : a + chunk]
            ti, qi = np.nonzero(maybe)
            t, q = placed[ti], qi + a
            sure = c[qi] >= total_reach[t]
            sure_t.append(t[sure])
            sure_q.append(q[sure])
            undecided_t.append(t[~sure])
            undecided_q.append(q[~sure])
        ut, uq = np.concatenate(undecided_t), np.concatenate(undecided_q)
        ok = check_sweeps(world_map, points, ut, uq, tables, footprint)
        lt = np.concatenate([*sure_t, ut[ok]])
        lq = np.concatenate([*sure_q, uq[ok]])
        taken[types.scale_group[lt], lq] = True
        found_t.append(lt)
        found_q.append(lq)
    return np.concatenate(found_t).astype(np.int64), np.concatenate(found_q).astype(np.int64)


def _instantiate(
    palette: Palette,
    types: PolicyTypes,
    tables: dict[str, NDArray[Any]],
    world_map: WorldMap,
    spacing: float,
    footprint: float,
    sweep_step: float,
    anchor: ArrayLike | None = None,
) -> PolicyLibrary:
    origin, nx, ny, points = _lattice(world_map, spacing, anchor)
    c0 = world_map.clearance(points)
    all_t, all_q = _choose(types, tables, world_map, points, c0, footprint)
    if all_t.size:
        # Type-major, point-ascending order.
        order = np.lexsort((all_q, all_t))
        typ, pt = all_t[order], all_q[order]
    else:
        typ = pt = np.zeros(0, dtype=np.int64)
    p_idx = types.palette_index[typ]
    k_idx = types.orientation[typ]
    cell = np.column_stack([pt % nx, pt // nx]).astype(np.int64)
    start_xy = points[pt] if pt.size else np.zeros((0, 2))
    start_state = np.concatenate([start_xy, types.start_velocity[typ]], axis=1)
    end_state = np.concatenate([start_xy + types.end_offset[typ], types.end_velocity[typ]], axis=1)
    return PolicyLibrary(
        palette=palette,
        world_map=world_map,
        footprint_radius=footprint,
        spacing=spacing,
        lattice_shape=(ny, nx),
        origin=_readonly(origin),
        types=types,
        palette_index=_readonly(p_idx),
        orientation=_readonly(k_idx),
        start_cell=_readonly(cell),
        start_xy=_readonly(start_xy),
        start_state=_readonly(start_state),
        end_state=_readonly(end_state),
        durations=_readonly(types.duration[typ]),
        path_lengths=_readonly(types.path_length[typ]),
        sweep_step=sweep_step,
    )


def max_trim_speed(palette: Palette) -> float:
    """v_max: the largest reference speed of the palette's trim policies (m/s); 0 if the
    palette has no cruise trim."""
    speeds = [
        float(np.hypot(*p.primitive.start_velocity))
        for p in palette.policies
        if p.primitive.is_trim
    ]
    return max(speeds, default=0.0)


def _out_of_reach(
    types: PolicyTypes,
    tables: dict[str, NDArray[Any]],
    world_map: WorldMap,
    samples: FloatArray,
    footprint: float,
    coverage_target: float,
) -> bool:
    """Whether no spacing can reach ``coverage_target``: some coverage sample is too near
    an obstacle for any start domain to hold it, and the target asks for every one.

    A policy placed at q has clearance(q) >= f + r₀ (r₀ the reach of its first swept
    sample); its S holds only positions within ρ_S (the radius of S's XY projection) of
    q, whose clearance is at least clearance(q) − ρ_S (clearance is 1-Lipschitz). So a
    sample of clearance below f + min(r₀ − ρ_S) over the types lies in no S, whatever
    the spacing, and coverage stays below 1: the passes before the last would be built
    and discarded."""
    if coverage_target < 1.0 or samples.shape[0] == 0:
        return False
    placed = _placed_types(types)
    least = float(np.min((tables["sample_first_reach"] - types.start_xy_radius)[placed]))
    return bool(np.any(world_map.clearance(samples[:, :2]) < footprint + least))


def _placed_types(types: PolicyTypes) -> BoolArray:
    """Types instantiated: all but the orientations k > 0 of a rotation-invariant capture
    regulator (rest reference, round domains), for which one orientation suffices."""
    invariant = (
        types.is_capture
        & np.all(types.start_velocity == 0.0, axis=1)
        & np.all(types.end_offset == 0.0, axis=1)
    )
    out: BoolArray = ~(invariant & (types.orientation > 0))
    return out


def estimate_library_size(
    palette: Palette,
    world_map: WorldMap,
    spacing: float,
    *,
    footprint_radius: float = 0.2,
    sweep_step: float | None = None,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    design_push: float = DEFAULT_DESIGN_PUSH,
) -> tuple[int, int]:
    """Bounds on the number of policies one pass at ``spacing`` would keep, without
    instantiating: O(P log P) in the lattice points P.

    A scale group (a policy and its larger-domain variants at one orientation) keeps at
    most one policy per lattice point, and exactly one where the clearance of the point
    is at least the footprint plus the reach of a whole swept D' of one of its sizes
    (the instantiation's "sure" test). Points below the footprint plus the reach of the
    first sample cannot hold the group.

    Parameters
    ----------
    palette : Palette
    world_map : WorldMap
    spacing : float
        Lattice spacing (m).
    footprint_radius : float
        Robot footprint radius (m).
    sweep_step : float, optional
        As for :func:`build_library`; default the map resolution.
    speed_clearance : float
        As for :func:`build_library` (s).
    design_push : float
        As for :func:`build_library` (N s).

    Returns
    -------
    (int, int)
        A lower and an upper bound of the library size.
    """
    step = float(sweep_step) if sweep_step is not None else float(world_map.resolution)
    types, tables = _palette_tables(palette, step, float(speed_clearance), float(design_push))
    _, _, _, points = _lattice(world_map, spacing)
    c0 = np.sort(world_map.clearance(points))
    placed = _placed_types(types)
    groups = types.scale_group[placed]
    fp = float(footprint_radius)

    def count(reach: FloatArray) -> int:
        """Σ over scale groups of the most points any of its types passes."""
        n_ok = c0.size - np.searchsorted(c0, fp + reach[placed], side="left")
        best = np.zeros(int(types.scale_group.max(initial=-1)) + 1, dtype=np.int64)
        np.maximum.at(best, groups, n_ok)
        return int(best.sum())

    return count(tables["type_total_reach"]), count(tables["sample_first_reach"])


@dataclass(frozen=True)
class LibrarySizeEstimate:
    """The number of policies one pass would keep, estimated before instantiating
    (:func:`expected_library_size`).

    Attributes
    ----------
    low, high : int
        Bounds of the size (those of :func:`estimate_library_size`).
    expected : float
        Estimate of the size: exact at the lattice points the bounds decide, from a
        uniform sample of the others.
    std_error : float
        Standard error of ``expected`` (0 when every undecided point was checked: then
        ``expected`` is the size).
    points : int
        Lattice points.
    undecided : int
        Lattice points the bounds do not decide.
    sampled : int
        Undecided points checked.
    """

    low: int
    high: int
    expected: float
    std_error: float
    points: int
    undecided: int
    sampled: int

    def upper(self, z: float = 2.0) -> float:
        """``expected`` plus ``z`` standard errors, at most ``high``: the size to budget
        memory for (z = 2: the true size exceeds it for about 2 % of seeds)."""
        return float(min(self.high, self.expected + z * self.std_error))


def expected_library_size(
    palette: Palette,
    world_map: WorldMap,
    spacing: float,
    *,
    footprint_radius: float = 0.2,
    sweep_step: float | None = None,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    design_push: float = DEFAULT_DESIGN_PUSH,
    samples: int = ESTIMATE_SAMPLES,
    seed: int = 0,
    sample_above: float | None = None,
) -> LibrarySizeEstimate:
    """Estimate the number of policies one pass at ``spacing`` would keep, without
    instantiating the pass.

    A scale group keeps at most one policy per lattice point; the bounds of
    :func:`estimate_library_size` decide a point for every group when the point's
    clearance either reaches the footprint plus a whole swept D' of one of the group's
    sizes (kept) or does not reach the footprint plus the first sample's reach of any
    (not kept). At the points they leave undecided for some group, instantiation's own
    test (largest size first, the swept samples checked against the map) runs on a
    seeded uniform sample of ``samples`` points, or on all of them when there are
    fewer, and the mean count there scales to all undecided points. The points are
    independent, so with every undecided point checked the estimate is the size that
    :func:`build_library` keeps.

    Parameters
    ----------
    palette : Palette
    world_map : WorldMap
    spacing : float
        Lattice spacing (m).
    footprint_radius, sweep_step, speed_clearance, design_push
        As for :func:`build_library`.
    samples : int
        Undecided points to check, >= 2.
    seed : int
        Seed of the sample.
    sample_above : float, optional
        Check the undecided points only when the upper bound (``high``) exceeds this
        many policies; at or below it the estimate is that bound (``expected`` =
        ``high``, nothing sampled). For a caller that only asks whether the library
        stays within a size: the bounds cost the clearance at the lattice points, the
        check the swept samples (most of a small map's instantiation time).

    Returns
    -------
    LibrarySizeEstimate
    """
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 2:
        raise ConfigError(f"samples must be an integer >= 2, got {samples!r}")
    step = float(sweep_step) if sweep_step is not None else float(world_map.resolution)
    fp = float(footprint_radius)
    types, tables = _palette_tables(palette, step, float(speed_clearance), float(design_push))
    _, _, _, points = _lattice(world_map, spacing)
    c0 = world_map.clearance(points)
    placed = _placed_types(types)
    groups = types.scale_group[placed]
    n_groups = int(types.scale_group.max(initial=-1)) + 1

    def per_point(reach: FloatArray) -> IntArray:
        """Groups per point of which some size has ``c0 >= fp + reach``."""
        need = np.full(n_groups, np.inf)
        np.minimum.at(need, groups, fp + reach[placed])
        counts: IntArray = np.searchsorted(np.sort(need), c0, side="right")
        return counts

    low = per_point(tables["type_total_reach"])
    high = per_point(tables["sample_first_reach"])
    undecided = np.flatnonzero(low < high)
    u = int(undecided.size)
    if sample_above is not None and float(high.sum()) <= sample_above:
        return LibrarySizeEstimate(
            low=int(low.sum()),
            high=int(high.sum()),
            expected=float(high.sum()),
            std_error=0.0,
            points=int(points.shape[0]),
            undecided=u,
            sampled=0,
        )
    if u > samples:
        rng = np.random.default_rng(seed)
        sample = np.sort(rng.choice(undecided, samples, replace=False))
    else:
        sample = undecided
    n = int(sample.size)
    expected = float(low.sum())
    extra = np.zeros(0)
    if n:
        kept = _kept_per_point(types, tables, world_map, points[sample], c0[sample], fp)
        extra = (kept - low[sample]).astype(float)
        expected += u * float(extra.mean())
    std_error = 0.0
    if 1 < n < u:  # the standard error of a sample without replacement
        std_error = u * float(extra.std(ddof=1)) / math.sqrt(n) * math.sqrt(1.0 - n / u)
    return LibrarySizeEstimate(
        low=int(low.sum()),
        high=int(high.sum()),
        expected=expected,
        std_error=std_error,
        points=int(points.shape[0]),
        undecided=u,
        sampled=n,
    )


def _kept_per_point(
    types: PolicyTypes,
    tables: dict[str, NDArray[Any]],
    world_map: WorldMap,
    points: FloatArray,
    c0: FloatArray,
    footprint: float,
) -> IntArray:
    """Policies instantiation keeps at each of ``points`` (lattice points, clearance
    ``c0``): the decisions of :func:`_instantiate` at those points alone (each point's
    decisions depend on that point only)."""
    _, at = _choose(types, tables, world_map, points, c0, footprint)
    kept: IntArray = np.bincount(at, minlength=points.shape[0]).astype(np.int64)
    return kept


def lattice_points(world_map: WorldMap, spacing: float) -> int:
    """Number of instantiation lattice points at ``spacing`` (m) on ``world_map``, by
    arithmetic (nothing is allocated)."""
    (x0, y0), (x1, y1) = world_map.bounds
    nx = math.floor((x1 - x0) / spacing + _LATTICE_EPS) + 1
    ny = math.floor((y1 - y0) / spacing + _LATTICE_EPS) + 1
    return int(nx) * int(ny)


def _check_memory(
    palette: Palette,
    world_map: WorldMap,
    spacing: float,
    footprint: float,
    step: float,
    speed_clearance: float,
    design_push: float,
    limit: float,
    halving: int,
) -> None:
    """Refuse a pass whose library would not fit in ``limit`` bytes (see
    :func:`build_library`): by arithmetic when its lattice alone would not, by the
    bounds of :func:`estimate_library_size` when they decide, else by
    :func:`expected_library_size`."""
    (x0, y0), (x1, y1) = world_map.bounds
    where = (
        f"{world_map.source}: one pass at spacing {spacing:g} m (halving {halving}) on "
        f"this {x1 - x0:g} m × {y1 - y0:g} m map"
    )
    todo = "; plan on a smaller map or region of it, use fewer halvings, or raise memory_limit"
    points = lattice_points(world_map, spacing)
    if points * LATTICE_POINT_BYTES > limit:
        raise ConfigError(
            f"{where} has {points:.3g} lattice points, whose estimate alone needs "
            f"{points * LATTICE_POINT_BYTES / 2**30:.1f} GiB ({LATTICE_POINT_BYTES} bytes "
            f"per point), above memory_limit {limit / 2**30:.1f} GiB{todo}"
        )
    low, high = estimate_library_size(
        palette,
        world_map,
        spacing,
        footprint_radius=footprint,
        sweep_step=step,
        speed_clearance=speed_clearance,
        design_push=design_push,
    )
    if high * POLICY_BYTES <= limit:
        return
    need = float(low * POLICY_BYTES)
    size, amount = f"{low:.3g} to {high:.3g}", "at least"
    if need <= limit:
        est = expected_library_size(
            palette,
            world_map,
            spacing,
            footprint_radius=footprint,
            sweep_step=step,
            speed_clearance=speed_clearance,
            design_push=design_push,
        )
        need = est.upper() * POLICY_BYTES
        size, amount = f"about {est.expected:.3g} (of {low:.3g} to {high:.3g})", "about"
    if need > limit:
        raise ConfigError(
            f"{where} would keep {size} policies, needing {amount} {need / 2**30:.1f} GiB "
            f"for the library, its graph and a search ({POLICY_BYTES} bytes per policy), "
            f"above memory_limit {limit / 2**30:.1f} GiB{todo}"
        )


def _check_inputs(
    palette: Palette,
    world_map: WorldMap,
    footprint_radius: float,
    coverage_target: float,
    max_halvings: int,
    coverage_samples: int,
    sweep_step: float | None,
    memory_limit: float | None,
    speed_clearance: float,
    design_push: float = DEFAULT_DESIGN_PUSH,
) -> None:
    if not isinstance(palette, Palette):
        raise ConfigError(f"palette must be a Palette, got {type(palette).__name__}")
    if not isinstance(world_map, WorldMap):
        raise ConfigError(
            f"world_map must be a WorldMap (see gracenav.world.load_map), got "
            f"{type(world_map).__name__}"
        )
    if len(palette) == 0:
        raise ConfigError("the palette has no policies; build one with `gracenav palette build`")
    if not (math.isfinite(palette.d) and palette.d > 0):
        raise ConfigError(f"palette distance parameter d must be positive, got {palette.d!r}")
    if not (isinstance(footprint_radius, int | float) and math.isfinite(footprint_radius)):
        raise ConfigError(f"footprint_radius must be a finite number (m), got {footprint_radius!r}")
    if footprint_radius < 0:
        raise ConfigError(
            f"footprint_radius must be >= 0 m, got {footprint_radius:g}; the robot body "
            "needs about 0.2 m"
        )
    if not (isinstance(coverage_target, int | float) and 0.0 <= coverage_target <= 1.0):
        raise ConfigError(f"coverage_target must be a fraction in [0, 1], got {coverage_target!r}")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, int) or max_halvings < 0:
        raise ConfigError(f"max_halvings must be an integer >= 0, got {max_halvings!r}")
    if (
        isinstance(coverage_samples, bool)
        or not isinstance(coverage_samples, int)
        or coverage_samples < 1
    ):
        raise ConfigError(f"coverage_samples must be an integer >= 1, got {coverage_samples!r}")
    if sweep_step is not None and not (
        isinstance(sweep_step, int | float) and math.isfinite(sweep_step) and sweep_step > 0
    ):
        raise ConfigError(f"sweep_step must be a positive length (m), got {sweep_step!r}")
    if not (
        isinstance(speed_clearance, int | float)
        and not isinstance(speed_clearance, bool)
        and 0.0 <= speed_clearance <= MAX_SPEED_CLEARANCE
    ):
        raise ConfigError(
            f"speed_clearance must be a time in [0, {MAX_SPEED_CLEARANCE:g}] s (extra "
            f"clearance per m/s of reference speed), got {speed_clearance!r}"
        )
    if not (
        isinstance(design_push, int | float)
        and not isinstance(design_push, bool)
        and 0.0 <= design_push <= MAX_DESIGN_PUSH
    ):
        raise ConfigError(
            f"design_push must be an impulse in [0, {MAX_DESIGN_PUSH:g}] N s (0: none), got "
            f"{design_push!r}"
        )
    if memory_limit is not None and not (
        isinstance(memory_limit, int | float)
        and not isinstance(memory_limit, bool)
        and memory_limit > 0
    ):
        raise ConfigError(
            f"memory_limit must be a positive number of bytes or None, got {memory_limit!r}"
        )
    for pol in palette.policies:
        start = pol.primitive.position[0, :2]
        if np.any(np.abs(start) > 1e-9):
            raise ConfigError(
                f"palette policy {pol.name!r} starts at {tuple(start)} m, not at the origin of "
                "its frame; rebuild the palette"
            )


def build_library(
    palette: Palette,
    world_map: WorldMap,
    *,
    footprint_radius: float = 0.2,
    coverage_target: float = 1.0,
    max_halvings: int = 3,
    seed: int = 0,
    coverage_samples: int = DEFAULT_COVERAGE_SAMPLES,
    sweep_step: float | None = None,
    memory_limit: float | None = DEFAULT_MEMORY_LIMIT,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    anchor: ArrayLike | None = None,
    design_push: float = DEFAULT_DESIGN_PUSH,
) -> PolicyLibrary:
    """Instantiate the palette on a map with coverage-driven lattice refinement.

    Parameters
    ----------
    palette : Palette
        The motion policy palette Π(Σ(d)).
    world_map : WorldMap
        The map M; its minimum corner anchors the lattice of instantiation points
        (so a goal on that lattice is an instantiation point) unless ``anchor`` is
        given.
    footprint_radius : float
        Robot footprint radius (m), >= 0. The body is 0.37 m across.
    coverage_target : float
        Coverage fraction in [0, 1] at which refinement stops.
    max_halvings : int
        Largest number of spacing halvings (the last lattice spacing is at least
        d / 2^max_halvings).
    seed : int
        Seed of the coverage sampling.
    coverage_samples : int
        Position states sampled to estimate coverage (the same set at every spacing,
        so coverage never decreases from one spacing to the next).
    sweep_step : float, optional
        Largest arc length (m) between the checked samples of a swept outer domain;
        default the map resolution.
    memory_limit : float or None
        Bytes the library, its graph and a search may take (default 4 GiB). Before
        each pass, the lower bound of :func:`estimate_library_size` times
        :data:`POLICY_BYTES` is compared with it and an over-budget pass is refused;
        None turns the check off.
    speed_clearance : float
        Stopping allowance (s): where the reference moves at velocity v, an obstacle
        straight ahead must be this times |v| farther than the swept D' needs; the disc
        checked for it also asks half of that beside the path, nothing behind (0 is the
        paper's instantiation; see the notes).
    anchor : array_like, shape (2,), optional
        A point (m) every lattice passes through (:func:`lattice_origin`): a goal at
        rest there is the end of the library's rest trims, reached without a terminal.
        Default: the lattice starts at the map's minimum corner.
    design_push : float
        Design push (N s, 0: none): where the reference is faster than
        :data:`~gracenav.library.push_fans.FAN_FLOOR`, the catches of every state this
        push leaves must fit too (see the notes). Policies whose pushed states no
        verified catch holds are not placed. Default :data:`DEFAULT_DESIGN_PUSH`; a
        palette whose references all stay at or below the floor needs no fan, and
        none is checked.

    Returns
    -------
    PolicyLibrary
        The library at the last spacing tried, with the per-iteration records.

    Raises
    ------
    ConfigError
        For invalid arguments (the message names the argument), and for a pass whose
        estimated memory exceeds ``memory_limit`` (the message gives the estimate).
    MapError
        If no position of the map has clearance >= ``footprint_radius``.

    Notes
    -----
    **Obstacle check.** Instantiation at point q with orientation k is valid iff for
    every t in [0, t_f] the disc of radius f + ρ'(t) around q + R_k σ_xy(t) lies in
    free space inside the map (f the footprint radius, ρ'(t) the XY radius of D'(t):
    outer position factor × position extent of D(t)). It is checked with
    ``world_map.clearance`` (distance to the nearest occupied cell or the map edge,
    0 outside; as exact as the map's rasterisation, within one cell of the true
    obstacles) at reference samples c_0 = 0, ..., c_K = σ_xy(t_f), chosen at most
    ``sweep_step`` of arc apart (plus one control tick of motion). Between samples
    j and j+1, separated by arc length ℓ_j, every reference point is within ℓ_j / 2
    of one of them, and ρ'(t) (geometric in t, hence monotone) is at most
    max(ρ'_j, ρ'_{j+1}). So requiring

        clearance(q + c_j) >= f + max over adjacent intervals i of
                                  (max(ρ'_i, ρ'_{i+1}) + ℓ_i / 2)

    at every sample is sufficient: the allowance for the spacing of samples is
    ℓ/2 <= (sweep_step + one tick of motion) / 2. To be fast the check is
    hierarchical and uses that clearance is a distance (1-Lipschitz): a disc around q
    (then one around each group of 8 samples) that bounds all the required discs is
    tested first, and the samples only where it is not clear. Loops run over
    palette policies × orientations only; all points are handled by numpy.

    **Stopping allowance.** With ``speed_clearance`` κ_v > 0 an obstacle in direction
    u from the reference point at velocity v must also leave κ_v max(0, v · u) more
    room: the full κ_v |v| straight ahead, nothing beside or behind. The disc of radius
    f + ρ'(t) + κ_v |v|/2 centred κ_v v/2 ahead of σ_xy(t) contains that region: with
    R = f + ρ' and a = κ_v |v|/2, its boundary in direction θ from v lies at
    a cos θ + √((R + a)² − a² sin² θ), whose square exceeds that of
    R + 2a max(0, cos θ) by 2aR(1 − |cos θ|) >= 0. So the check above runs on the
    path led by κ_v v/2 with every reach grown by κ_v |v|/2 (the samples take the
    fastest tick between them and their neighbours).
    Verification does not depend on it (D' is unchanged); it keeps policies from
    heading fast at obstacles, so that a push there leaves room for a catch
    (:mod:`gracenav.execution.capture`) to stop the robot: a push of 8–16 N s leaves
    0.8–1.2 m/s, whose shortest verified catch reaches 0.7–1.2 m. Running along a wall
    costs half the allowance beside it. Rest policies (the goals, and the catches'
    ends) are unaffected.

    **Design push.** A catch's reach grows with the square of its speed (0.71 m from
    0.8 m/s, 2.81 m from 1.3 m/s on the speed-level palette), faster than any
    allowance proportional to speed. With ``design_push`` J > 0, wherever the flat
    output's reference speed exceeds :data:`~gracenav.library.push_fans.FAN_FLOOR`, the
    flat output's state is pushed by J in each of
    :data:`~gracenav.library.push_fans.FAN_DIRECTIONS` directions (its velocity changes by
    :func:`~gracenav.library.push_fans.flat_speed_change`), and the pushed catch of the
    nearest speed, turned along the new velocity and started there, must fit with its
    swept D' grown by one cell of the catches' placement grid
    (:class:`~gracenav.library.push_fans.PushFan`). It is checked at states along the
    reference whose catches' discs are at most
    :data:`~gracenav.library.push_fans.FAN_GAP` from those of every state between them,
    and every disc is grown by that. A pushed speed that no pushed catch's
    S holds (beyond the fastest catch the torque limit lets verify) leaves the policy
    out everywhere. At and below the floor the allowance above applies alone.

    **Coverage** is the fraction of ``coverage_samples`` position states, uniform
    over free positions with clearance >= f and velocities in [−v_max, v_max]² (v_max
    the largest trim speed; see :func:`sample_position_states` and
    :func:`max_trim_speed`), inside at least one start domain S. Points whose
    clearance is below f + (outer position factor − 1) · ρ_S (ρ_S the XY radius of
    S) cannot be covered: no valid start domain reaches them. On maps with walls
    coverage therefore stays below 1 and a target of 1 uses every halving; when a
    coverage sample lies that near an obstacle (for every type) and the target is 1,
    only the last spacing is built (the others would be discarded), and
    ``iterations`` has its record alone.
    """
    _check_inputs(
        palette,
        world_map,
        footprint_radius,
        coverage_target,
        max_halvings,
        coverage_samples,
        sweep_step,
        memory_limit,
        speed_clearance,
        design_push,
    )
    footprint = float(footprint_radius)
    allowance = float(speed_clearance)
    push = float(design_push)
    step = float(sweep_step) if sweep_step is not None else float(world_map.resolution)
    types, tables = _palette_tables(palette, step, allowance, push)
    samples = sample_position_states(
        world_map,
        coverage_samples,
        footprint_radius=footprint,
        v_max=max_trim_speed(palette),
        seed=seed,
    )
    iterations: list[InstantiationIteration] = []
    library: PolicyLibrary | None = None
    coverage = 0.0
    first = (
        max_halvings
        if _out_of_reach(types, tables, world_map, samples, footprint, coverage_target)
        else 0
    )
    for h in range(first, max_halvings + 1):
        t0 = time.perf_counter()
        spacing = palette.d / 2**h
        if memory_limit is not None:
            _check_memory(
                palette,
                world_map,
                spacing,
                footprint,
                step,
                allowance,
                push,
                float(memory_limit),
                h,
            )
        library = _instantiate(palette, types, tables, world_map, spacing, footprint, step, anchor)
        coverage = float(np.mean(library.start_domain_covers(samples)))
        iterations.append(
            InstantiationIteration(spacing, len(library), coverage, time.perf_counter() - t0)
        )
        if coverage >= coverage_target:
            break
    assert library is not None
    return library._with_results(
        coverage=coverage,
        iterations=tuple(iterations),
        speed_clearance=allowance,
        design_push=push,
    )
