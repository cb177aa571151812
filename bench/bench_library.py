"""Speed of automatic instantiation and of the gracefully prepares graph.

Prints a table for two maps:

* the paper's 3.5 m × 3.5 m free area at d = 0.5 m (paper: 39 policies, 4521
  library policies, instantiation + graph in 2.5 s; our target <= 50 ms), one
  pass at spacing d as in the paper and, for information, the default
  coverage-driven refinement (up to 3 halvings);
* a 50 m × 50 m synthetic office at 5 cm resolution (``world.office_map``),
  one pass at spacing d (target <= 5 s for library + graph),

with library size, edges, coverage, medians of repeated runs, and peak memory
(tracemalloc peak of one run and the process's ru_maxrss). The real palette
(``load_palette()``) is used when it exists; otherwise a synthetic 39-policy
palette with the same structure (first-quadrant primitives, d = 0.5 m, cruise at
0.5 m/s, septic position references, S = 0.25–0.35 m, G = 0.1 m) stands in,
with a note.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_library.py
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from gracenav.control import design_gains
from gracenav.errors import CacheError
from gracenav.library import PolicyLibrary, build_library
from gracenav.palette import Palette, load_palette, palette_key
from gracenav.params import BallbotParams
from gracenav.planning.graph import build_graph
from gracenav.policies import (
    DomainRadii,
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
    VerificationOptions,
)
from gracenav.world import WorldMap, load_map, office_map

DT = 1.0 / 1024.0
V = 0.5  # cruise speed along an axis (m/s)
VD = 1.0 / 3.0  # cruise velocity components along the diagonal (m/s)


def _septic(p1: float, v0: float, v1: float, duration: float, t: np.ndarray) -> np.ndarray:
    """Position, velocity, acceleration, jerk of the septic with p(0) = 0, ṗ(0) = v0,
    p̈(0) = p⃛(0) = 0, p(T) = p1, ṗ(T) = v1, p̈(T) = p⃛(T) = 0. Shape (4, len(t))."""
    T = duration
    k = np.arange(4, 8)
    a = np.array(
        [
            T**k,
            k * T ** (k - 1),
            k * (k - 1) * T ** (k - 2),
            k * (k - 1) * (k - 2) * T ** (k - 3),
        ]
    )
    c = np.linalg.solve(a, [p1 - v0 * T, v1 - v0, 0.0, 0.0])
    tt = t[None, :]
    kk = k[:, None]
    cc = c[:, None]
    return np.array(
        [
            v0 * t + np.sum(cc * tt**kk, axis=0),
            v0 + np.sum(cc * kk * tt ** (kk - 1), axis=0),
            np.sum(cc * kk * (kk - 1) * tt ** (kk - 2), axis=0),
            np.sum(cc * kk * (kk - 1) * (kk - 2) * tt ** (kk - 3), axis=0),
        ]
    )


def synthetic_primitive(
    name: str, disp: tuple[float, float], v0: tuple[float, float], v1: tuple[float, float], T: float
) -> SampledPrimitive:
    """A primitive whose ball follows septic position references; lean ≈ acceleration / g."""
    n = round(T / DT)
    t = np.arange(n + 1) * DT
    ax = _septic(disp[0], v0[0], v1[0], T, t)
    ay = _septic(disp[1], v0[1], v1[1], T, t)
    pos = np.column_stack([ax[0], ay[0], ax[1], ay[1], ax[2], ay[2]])
    lean = np.column_stack([ax[2], ay[2]]) / 9.81
    rate = np.column_stack([ax[3], ay[3]]) / 9.81
    r = 0.1058
    states = np.column_stack([pos[:, :2] / r - lean, lean, pos[:, 2:4] / r - rate, rate])
    moving = any(v0) or any(v1)
    still = disp == (0.0, 0.0) and not moving
    trim = still or (v0 == v1 and np.allclose(np.array(disp), np.array(v0) * T))
    kind = (
        PrimitiveKind.REST if still else (PrimitiveKind.CRUISE if trim else PrimitiveKind.MANEUVER)
    )
    return SampledPrimitive(
        name=name,
        kind=kind,
        duration=n * DT,
        dt=DT,
        displacement=np.array(disp, dtype=float),
        start_velocity=np.array(v0, dtype=float),
        end_velocity=np.array(v1, dtype=float),
        states=states,
        accelerations=np.zeros((n + 1, 4)),
        inputs=np.zeros((n + 1, 2)),
        position=pos,
    )


def synthetic_palette() -> Palette:
    """39 policies of a first-quadrant primitive set Σ(0.5) with septic references."""
    z, x, y = (0.0, 0.0), (V, 0.0), (0.0, V)
    dg, dl = (VD, VD), (-VD, VD)  # diagonal, and diagonal turned left by 90°
    specs: list[tuple[str, tuple[float, float], tuple[float, float], tuple[float, float], float]]
    specs = [("rest", (0.0, 0.0), z, z, 1.0), ("cruise_x", (0.5, 0.0), x, x, 1.0)]
    specs += [("cruise_diag", (0.5, 0.5), dg, dg, 1.5)]
    for dx, dy in [(0.5, 0), (1, 0), (1.5, 0), (0.5, 0.5), (1, 0.5), (0.5, 1), (1, 1), (1.5, 0.5)]:
        d = float(np.hypot(dx, dy))
        specs.append((f"rest_rest_{dx:g}_{dy:g}", (dx, dy), z, z, round(3.57 * np.sqrt(d) * 8) / 8))
    specs += [
        ("rest_x_1_0", (1.0, 0.0), z, x, 3.5),
        ("rest_x_1_0.5", (1.0, 0.5), z, x, 3.5),
        ("rest_diag_1_1", (1.0, 1.0), z, dg, 4.0),
        ("rest_diag_1_0.5", (1.0, 0.5), z, dg, 3.5),
        ("x_rest_1_0", (1.0, 0.0), x, z, 3.5),
        ("x_rest_1_0.5", (1.0, 0.5), x, z, 3.5),
        ("diag_rest_1_1", (1.0, 1.0), dg, z, 4.0),
        ("diag_rest_0.5_1", (0.5, 1.0), dg, z, 3.5),
        ("x_x_lane_1.5_0.5", (1.5, 0.5), x, x, 3.0),
        ("x_x_lane_1_0.5", (1.0, 0.5), x, x, 2.25),
        ("y_y_lane_0.5_1.5", (0.5, 1.5), y, y, 3.0),
        ("y_y_lane_0.5_1", (0.5, 1.0), y, y, 2.25),
        ("x_y_turn_1_1", (1.0, 1.0), x, y, 3.0),
        ("x_y_turn_0.5_0.5", (0.5, 0.5), x, y, 1.5),
        ("y_x_turn_1_1", (1.0, 1.0), y, x, 3.0),
        ("y_x_turn_0.5_0.5", (0.5, 0.5), y, x, 1.5),
        ("x_diag_1_0.5", (1.0, 0.5), x, dg, 2.5),
        ("x_diag_1.5_0.5", (1.5, 0.5), x, dg, 3.5),
        ("diag_x_1_0.5", (1.0, 0.5), dg, x, 2.5),
        ("diag_x_1.5_1", (1.5, 1.0), dg, x, 4.0),
        ("y_diag_0.5_1", (0.5, 1.0), y, dg, 2.5),
        ("diag_y_0.5_1", (0.5, 1.0), dg, y, 2.5),
        ("diag_left_0_1", (0.0, 1.0), dg, dl, 3.0),
        ("left_diag_0_1", (0.0, 1.0), dl, dg, 3.0),
        ("x_uturn_0_1", (0.0, 1.0), x, (-V, 0.0), 3.5),
        ("y_uturn_1_0", (1.0, 0.0), y, (0.0, -V), 3.5),
        ("diag_lane_1.5_1", (1.5, 1.0), dg, dg, 4.0),
        ("x_y_turn_1.5_1.5", (1.5, 1.5), x, y, 4.5),
    ]
    params = BallbotParams()
    gains = design_gains(params)
    options = VerificationOptions()
    goal = DomainRadii(0.1, 0.1)
    policies = []
    for i, (name, disp, v0, v1, T) in enumerate(specs):
        prim = synthetic_primitive(name, disp, v0, v1, T)
        rp = 0.35 if prim.is_trim else 0.25 + 0.05 * (i % 3)
        policies.append(MotionPolicy(prim, gains, DomainRadii(rp, rp), goal, (1.3, 2.0)))
    return Palette(
        policies=tuple(policies),
        rejected=(),
        duplicates=(),
        d=0.5,
        params=params,
        options=options,
        key=palette_key(params, gains, options, 0.5),
    )


def get_palette() -> tuple[Palette, str]:
    """The real palette if it exists, else the synthetic one, with a note."""
    try:
        return load_palette(), "real palette (load_palette())"
    except CacheError as exc:
        return synthetic_palette(), (
            f"NOTE: real palette unavailable ({str(exc).split(';')[0]}); "
            "using a SYNTHETIC 39-policy palette"
        )


def _median_time(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def _peak(fn: Callable[[], Any]) -> float:
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def _row(label: str, wmap: WorldMap, palette: Palette, repeats: int, **kw: Any) -> list[str]:
    def lib_only() -> PolicyLibrary:
        return build_library(palette, wmap, **kw)

    lib = lib_only()  # warm up (clearance field, compiled caches)
    t_lib, lib = _median_time(lib_only, repeats)
    t_graph, graph = _median_time(lambda: build_graph(lib), repeats)
    peak = _peak(lambda: build_graph(build_library(palette, wmap, **kw)))
    return [
        label,
        f"{len(lib)}",
        f"{graph.num_edges}",
        f"{lib.spacing:g}",
        f"{lib.coverage:.3f}",
        f"{t_lib * 1e3:.1f}",
        f"{t_graph * 1e3:.1f}",
        f"{(t_lib + t_graph) * 1e3:.1f}",
        f"{peak:.0f}",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7, help="runs per measurement (median)")
    ap.add_argument("--skip-large", action="store_true", help="skip the 50 m office map")
    args = ap.parse_args()
    palette, note = get_palette()
    print(note)
    print(f"palette: {len(palette)} policies, d = {palette.d:g} m")
    here = os.path.dirname(os.path.abspath(__file__))
    free = load_map(os.path.join(here, "..", "examples", "maps", "free_area_3p5m.yaml"))
    rows = [
        [
            "case",
            "policies",
            "edges",
            "spacing (m)",
            "coverage",
            "library (ms)",
            "graph (ms)",
            "total (ms)",
            "tracemalloc peak (MiB)",
        ]
    ]
    rows.append(_row("3.5 m free, one pass (paper)", free, palette, args.repeats, max_halvings=0))
    rows.append(_row("3.5 m free, default halvings", free, palette, max(1, args.repeats // 3)))
    if not args.skip_large:

        def office_with_clearance() -> WorldMap:
            office = office_map(50.0, 0.05, seed=0)
            _ = office.clearance_grid
            return office

        t_map, office = _median_time(office_with_clearance, 3)
        rows.append(
            _row(
                "50 m office, 5 cm, one pass",
                office,
                palette,
                max(1, args.repeats // 2),
                max_halvings=0,
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print(
            "  ".join(
                c.rjust(w) if j else c.ljust(w)
                for j, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
    if not args.skip_large:
        print(
            "office map build + clearance field (once per map, not in the table), median "
            f"of 3: {t_map:.2f} s"
        )
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"process peak RSS (ru_maxrss): {rss:.0f} MiB")
    print("targets: 3.5 m one pass <= 50 ms (paper 2.5 s); 50 m office one pass <= 5 s")


if __name__ == "__main__":
    main()
