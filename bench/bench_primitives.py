"""Planning the motion primitive set Σ(0.5): time and quality.

Prints one row per primitive (duration, peak lean, peak torque, tracking error
of the achieved flat output against the nonic, dynamics residual; the worse of
the 0° and 90° plans), then the time to plan the whole set (median of repeated
in-process runs, cache off; target <= 5 s) and the time to load it from the
on-disk cache (median; target well under 100 ms). The first call, which also
loads the compiled kernels, is reported separately.

    OPENBLAS_NUM_THREADS=1 python bench/bench_primitives.py
"""

from __future__ import annotations

import math
import os
import statistics
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gracenav import BallbotParams
from gracenav.primitives import Maneuver, primitive_set


def main() -> None:
    params = BallbotParams()

    t0 = time.perf_counter()
    pset = primitive_set(0.5, params, cache=False)
    first_call = time.perf_counter() - t0

    runs = []
    for _ in range(3):
        t0 = time.perf_counter()
        pset = primitive_set(0.5, params, cache=False)
        runs.append(time.perf_counter() - t0)

    with tempfile.TemporaryDirectory() as tmp:
        os.environ["GRACENAV_CACHE_DIR"] = tmp
        t0 = time.perf_counter()
        primitive_set(0.5, params)
        plan_and_write = time.perf_counter() - t0
        loads = []
        for _ in range(7):
            t0 = time.perf_counter()
            primitive_set(0.5, params)
            loads.append(time.perf_counter() - t0)

    header = (
        f"{'primitive':32s} {'T (s)':>7s} {'lean (°)':>9s} {'|τ| (N m)':>10s} "
        f"{'rms (mm)':>9s} {'max (mm)':>9s} {'resid (N m)':>11s}"
    )
    print(header)
    print("-" * len(header))
    for p in pset:
        if isinstance(p, Maneuver) and p.reports is not None:
            r0, r1 = p.reports
            lean = math.degrees(max(r0.peak_lean, r1.peak_lean))
            tau = max(r0.peak_torque, r1.peak_torque)
            rms = 1e3 * max(r0.tracking_rms, r1.tracking_rms)
            mx = 1e3 * max(r0.tracking_max, r1.tracking_max)
            res = max(r0.dynamics_residual, r1.dynamics_residual)
            print(
                f"{p.name:32s} {p.duration:7.3f} {lean:9.2f} {tau:10.1f} "
                f"{rms:9.1e} {mx:9.1e} {res:11.1e}"
            )
        else:
            tau = float(abs(p.sample([0.0]).inputs).max())
            print(
                f"{p.name:32s} {p.duration:7.3f} {0.0:9.2f} {tau:10.1f} "
                f"{0.0:9.1e} {0.0:9.1e} {0.0:11.1e}   (trim)"
            )
    print()
    print(f"primitives: {len(pset)} ({len(pset.maneuvers)} maneuvers, each planned at 0° and 90°)")
    print(f"first call (loads compiled kernels): {first_call:.2f} s")
    print(f"plan the set, median of {len(runs)}: {statistics.median(runs):.2f} s (target <= 5 s)")
    print(f"plan and write the cache: {plan_and_write:.2f} s")
    print(f"load from cache, median of {len(loads)}: {1e3 * statistics.median(loads):.1f} ms")


if __name__ == "__main__":
    main()
