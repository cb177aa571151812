"""Closed-loop 3D simulation speed.

Prints a table: single-run speed as simulated seconds per wall second at the
1024 Hz control rate (target >= 200x real time), and batch throughput in
state-steps per second for 1,000 initial conditions. Medians of repeated runs;
the first (compiling) call is excluded and reported separately.

    OPENBLAS_NUM_THREADS=1 python bench/bench_simulate.py
"""

from __future__ import annotations

import os
import statistics
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from gracenav import BallbotParams
from gracenav.control import design_gains
from gracenav.sim import Reference, simulate, simulate_batch, state_from_position


def main() -> None:
    params = BallbotParams()
    gains = design_gains(params)
    x0 = state_from_position(np.zeros(4), params.ball_radius, lean=np.deg2rad([5.0, 5.0]))

    t0 = time.perf_counter()
    simulate(x0, Reference.hold((0.0, 0.0), 0.1), gains)
    first_call = time.perf_counter() - t0

    sim_time = 10.0
    ref = Reference.hold((0.0, 0.0), sim_time)
    single = []
    for _ in range(7):
        t0 = time.perf_counter()
        simulate(x0, ref, gains)
        single.append(time.perf_counter() - t0)
    med = statistics.median(single)

    rng = np.random.default_rng(0)
    n_runs, batch_time = 1000, 3.0
    p0 = rng.uniform(-0.2, 0.2, (n_runs, 4))
    xb = state_from_position(p0, params.ball_radius)
    ref_b = Reference.hold((0.0, 0.0), batch_time)
    batch = []
    for _ in range(3):
        t0 = time.perf_counter()
        simulate_batch(xb, ref_b, gains)
        batch.append(time.perf_counter() - t0)
    med_b = statistics.median(batch)
    steps = n_runs * ref_b.num_ticks

    rows = [
        ("first call (compile or load cache)", f"{first_call:.2f} s"),
        (f"single run, {sim_time:g} s at 1024 Hz, median of 7", f"{med * 1000:.1f} ms"),
        ("  simulated s per wall s", f"{sim_time / med:.0f}x real time"),
        (f"batch {n_runs} x {batch_time:g} s, median of 3", f"{med_b:.2f} s"),
        ("  state-steps per second", f"{steps / med_b:.3g}"),
    ]
    width = max(len(r[0]) for r in rows)
    print(f"{'measure':<{width}}  value")
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


if __name__ == "__main__":
    main()
