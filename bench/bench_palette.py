"""Motion policy palette: load time, full re-verification, and build (sizing) time.

Targets: load_palette() <= 50 ms; full palette verification <= 120 s (2 cores).
Verification here means every policy at its 0° and 90° placement from 64 points
on the surface of its start domain, on the 3D model. Each load reads and checks the
file again (the palettes a process has read are forgotten before each). The palette
is the default, or ``$GRACENAV_PALETTE`` (a file or a shipped name: ``speed``).

    OPENBLAS_NUM_THREADS=1 python bench/bench_palette.py [--build]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time

from gracenav.palette import build_palette, forget_read_palettes, load_palette
from gracenav.policies import SampledPrimitive, verify_placements, verify_policy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--build", action="store_true", help="also time a full palette build")
    args = ap.parse_args()
    load_palette()  # warm the file cache and imports
    loads = []
    for _ in range(11):
        forget_read_palettes()  # read the file, not this process's copy
        t0 = time.perf_counter()
        pal = load_palette()
        loads.append(time.perf_counter() - t0)
    rows = [("load_palette(), median of 11", f"{1000 * statistics.median(loads):.1f} ms")]

    verify_policy(pal.policies[0], pal.options)  # compile the kernels
    t0 = time.perf_counter()
    runs = 0
    for pol in pal.policies:
        rep = verify_placements(pol, pal.options)
        runs += rep.runs
        assert rep.passed, pol.name
    rows.append(
        (
            f"verify {len(pal)} policies x 2 placements ({runs} runs), 1 process",
            f"{time.perf_counter() - t0:.1f} s",
        )
    )
    if args.build:
        from gracenav.primitives import primitive_set

        # The default palette's primitive set and verification options.
        pset = primitive_set(d=pal.d, params=pal.params, options=pal.primitive_options)
        prims = [SampledPrimitive.from_primitive(p) for p in pset]
        t0 = time.perf_counter()
        build_palette(
            prims,
            d=pal.d,
            params=pal.params,
            gains=pal.gains,
            options=pal.options,
            processes=2,
            progress=False,
            primitive_options=pal.primitive_options,
        )
        rows.append(("build (bisection sizing), 2 processes", f"{time.perf_counter() - t0:.1f} s"))
    width = max(len(r[0]) for r in rows)
    print(f"{'measure':<{width}}  value")
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


if __name__ == "__main__":
    main()
