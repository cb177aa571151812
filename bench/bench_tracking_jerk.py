"""The ball's jerk as tracked against as planned, maneuver by maneuver, with the friction
fed forward at the measured ball rate and at the rate predicted for the middle of the
control period (:attr:`gracenav.control.ControllerGains.friction_midpoint`).

For every maneuver of a palette (no larger-domain variants, fine copies or captures) it
runs the closed loop on the 3D model from the maneuver's own start, with its start trim
held for ``--hold`` seconds before it and its end trim after it (constant velocity), once
with each feed-forward and the palette's gains otherwise, and prints: the largest jerk
of the plan and of each run (the true ball velocity differentiated as the run summaries
do, :mod:`gracenav.execution.smoothness`), the largest jerk of the difference (run minus
plan: what the tracking adds) and the largest position error. Where the ball's rate
relative to the body crosses zero, the smoothed Coulomb term turns by 2 D_c within a few
tens of control periods; the measured rate's feed-forward is held behind it, which
leaves a pulse of the ball's acceleration there. Then the medians and the largest of
each column over the maneuvers.

    OPENBLAS_NUM_THREADS=1 python bench/bench_tracking_jerk.py [--palette smooth]
        [--hold 0.4]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import dataclasses
import statistics
import sys
import time

import numpy as np
from numpy.typing import NDArray

from gracenav.execution.smoothness import jerk_profile
from gracenav.palette import load_palette
from gracenav.policies import PrimitiveKind
from gracenav.sim import Reference, simulate

FloatArray = NDArray[np.float64]


def with_trims(states: FloatArray, inputs: FloatArray, dt: float, hold: float) -> Reference:
    """The plan with its start trim held ``hold`` (s) before it and its end trim after it:
    the angles advance at the trims' constant rates, the torques are the ends'."""
    pad = round(hold / dt)
    k = np.arange(1, pad + 1, dtype=float)[:, None]
    before = np.repeat(states[:1], pad, axis=0)
    before[:, :4] = states[0, :4] - states[0, 4:] * k[::-1] * dt
    after = np.repeat(states[-1:], pad, axis=0)
    after[:, :4] = states[-1, :4] + states[-1, 4:] * k * dt
    u = np.vstack([np.repeat(inputs[:1], pad, 0), inputs, np.repeat(inputs[-1:], pad, 0)])
    return Reference(np.vstack([before, states, after]), u, dt)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--palette", default="smooth", help="shipped palette name or file (default smooth)"
    )
    ap.add_argument(
        "--hold", type=float, default=0.4, help="trim held before and after (s, default 0.4)"
    )
    args = ap.parse_args()
    if not 0.2 <= args.hold <= 5.0:
        ap.error(f"--hold must be 0.2..5 s (a jerk window is 0.3 s), got {args.hold}")
    try:
        pal = load_palette(args.palette)
    except Exception as exc:  # a one-line refusal, whatever the loader says
        ap.error(f"palette {args.palette!r}: {exc}")
    r = pal.params.ball_radius
    maneuvers = {
        q.primitive.name: q.primitive
        for q in pal.policies
        if q.primitive.kind is PrimitiveKind.MANEUVER and not q.label and not q.capture
    }
    modes = {
        "measured": dataclasses.replace(pal.gains, friction_midpoint=False),
        "mid-period": dataclasses.replace(pal.gains, friction_midpoint=True),
    }
    print(
        f"palette {args.palette!r}: {len(maneuvers)} maneuvers, trims held {args.hold:g} s "
        f"around each; jerk (m/s³) and error (mm) with the friction fed forward at the "
        "measured / mid-period rate"
    )
    print(f"  {'maneuver':30s} {'plan':>6s} {'run':>13s} {'run − plan':>13s} {'position err':>13s}")
    columns: dict[str, list[float]] = {}
    t0 = time.perf_counter()
    for name, prim in sorted(maneuvers.items()):
        ref = with_trims(prim.states, prim.inputs, prim.dt, args.hold)
        t = np.arange(ref.num_ticks + 1) * ref.dt
        v_plan = r * (ref.states[:, 4:6] + ref.states[:, 6:8])
        p_plan = r * (ref.states[:, :2] + ref.states[:, 2:4])
        row = {"plan": jerk_profile(t, v_plan).max}
        for mode, gains in modes.items():
            run = simulate(ref.states[0], ref, gains).position_state
            row[f"run {mode}"] = jerk_profile(t, run[:, 2:4]).max
            row[f"diff {mode}"] = jerk_profile(t, run[:, 2:4] - v_plan).max
            row[f"err {mode}"] = 1e3 * float(np.max(np.hypot(*(run[:, :2] - p_plan).T)))
        for key, value in row.items():
            columns.setdefault(key, []).append(value)
        print(
            f"  {name:30s} {row['plan']:6.2f} {row['run measured']:6.2f} / "
            f"{row['run mid-period']:4.2f} {row['diff measured']:6.3f} / "
            f"{row['diff mid-period']:4.3f} {row['err measured']:6.3f} / "
            f"{row['err mid-period']:4.3f}"
        )
    print(f"bench_tracking_jerk: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    for label, pick in (("median", statistics.median), ("largest", max)):
        c = {k: pick(v) for k, v in columns.items()}
        print(
            f"  {label:30s} {c['plan']:6.2f} {c['run measured']:6.2f} / "
            f"{c['run mid-period']:4.2f} {c['diff measured']:6.3f} / "
            f"{c['diff mid-period']:4.3f} {c['err measured']:6.3f} / {c['err mid-period']:4.3f}"
        )
    over = [(m - p) / p for m, p in zip(columns["run measured"], columns["plan"], strict=True)]
    over_mid = [
        (m - p) / p for m, p in zip(columns["run mid-period"], columns["plan"], strict=True)
    ]
    print(
        f"  the run's largest jerk above the plan's: measured rate median "
        f"{100 * statistics.median(over):.1f} %, largest {100 * max(over):.1f} %; mid-period "
        f"median {100 * statistics.median(over_mid):.1f} %, largest {100 * max(over_mid):.1f} %"
    )


if __name__ == "__main__":
    main()
