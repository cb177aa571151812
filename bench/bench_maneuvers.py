"""Maneuver durations: the nonic of fixed form against the limited reference, per
maneuver of the primitive set Σ(d), both planned feasible on the 3D model by the shape
trajectory planner within the same lean and torque limits.

For every maneuver of the catalogue (rest to rest, starts and stops, turns, lane
changes, U-turns) it prints the shortest duration on the grid of each reference kind
(``PrimitiveSetOptions.reference``: ``nonic`` or ``limited``,
:mod:`gracenav.primitives.limited`), their ratio, and the peak lean and torque of the
3D plans, and the largest jerk of the ball along each plan (the 3D plan's ball
velocity sampled at 1024 Hz between the trims before and after it, the maneuver's own
ends included, and differentiated as the run summaries do,
:mod:`gracenav.execution.smoothness`); then the sums and the median ratio.
``--cruise-speed`` builds both sets for another cruise speed (``--max-speed`` caps the
references' speed), to see which maneuvers each reference makes feasible there;
``--max-ball-jerk`` is the limited references' bound on the ball's jerk
(``PrimitiveSetOptions.max_ball_jerk``), to see what a tighter bound costs in time.

    OPENBLAS_NUM_THREADS=1 python bench/bench_maneuvers.py [--cruise-speed 0.5]
        [--max-speed 0.8] [--duration-step 0.125] [--max-ball-jerk 6]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math
import statistics
import sys
import time

import numpy as np

from gracenav.execution.smoothness import planned_jerk
from gracenav.primitives import PrimitiveSetOptions, primitive_set
from gracenav.primitives.motion import Maneuver

RATE = 1024.0  # Hz, the control rate the runs are sampled at


def plan_ball_jerk(p: Maneuver) -> float:
    """Largest ball jerk (m/s³) along the maneuver's 3D plan, with the trims before and
    after it (constant velocity for a window each side), so that its ends count."""
    n = round(p.duration * RATE)
    t = np.arange(n + 1) / RATE
    return planned_jerk(p.sample(t).position[:, 2:4], 1.0 / RATE)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cruise-speed", type=float, default=0.5, help="cruise speed (m/s)")
    ap.add_argument("--max-speed", type=float, default=0.8, help="reference speed cap (m/s)")
    ap.add_argument("--duration-step", type=float, default=0.125, help="duration grid (s)")
    ap.add_argument(
        "--max-ball-jerk",
        type=float,
        default=PrimitiveSetOptions().max_ball_jerk,
        help="the limited references' bound on the ball's jerk (m/s³; default %(default)s)",
    )
    args = ap.parse_args()
    sets = {}
    for kind in ("nonic", "limited"):
        t0 = time.perf_counter()
        options = PrimitiveSetOptions(
            cruise_speed=args.cruise_speed,
            max_speed=args.max_speed,
            duration_step=args.duration_step,
            reference=kind,
            max_ball_jerk=args.max_ball_jerk,
        )
        sets[kind] = primitive_set(options=options)
        print(f"{kind}: set built or loaded in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    rows = {
        kind: {p.name: p for p in s.primitives if isinstance(p, Maneuver)}
        for kind, s in sets.items()
    }
    names = list(dict.fromkeys([*rows["nonic"], *rows["limited"]]))
    lean = "lean (°)"
    print(
        f"{'maneuver':28s} {'nonic s':>8s} {'limited s':>9s} {'ratio':>6s}   "
        f"{lean + ' n / l':>15s} {'torque (N m) n / l':>19s} {'ball jerk n / l':>16s}"
    )
    jerks: dict[str, list[float]] = {"nonic": [], "limited": []}
    ratios = []
    total = {"nonic": 0.0, "limited": 0.0}
    for name in names:
        n, lim = rows["nonic"].get(name), rows["limited"].get(name)
        dn = f"{n.duration:8.3f}" if n else f"{'-':>8s}"
        dl = f"{lim.duration:9.3f}" if lim else f"{'-':>9s}"
        ratio = f"{lim.duration / n.duration:6.3f}" if n and lim else f"{'-':>6s}"
        if n and lim:
            ratios.append(lim.duration / n.duration)
            total["nonic"] += n.duration
            total["limited"] += lim.duration

        def peaks(p: Maneuver | None) -> tuple[str, str]:
            if p is None or not p.reports:
                return "-", "-"
            lean_deg = max(math.degrees(r.peak_lean) for r in p.reports)
            return f"{lean_deg:.2f}", f"{max(r.peak_torque for r in p.reports):.1f}"

        (ln, tn), (ll, tl) = peaks(n), peaks(lim)
        jn = plan_ball_jerk(n) if n else math.nan
        jl = plan_ball_jerk(lim) if lim else math.nan
        if n and lim:
            jerks["nonic"].append(jn)
            jerks["limited"].append(jl)
        print(
            f"{name:28s} {dn} {dl} {ratio}   {ln + ' / ' + ll:>15s} {tn + ' / ' + tl:>19s} "
            f"{f'{jn:.2f} / {jl:.2f}':>16s}"
        )
    both = len(ratios)
    print(
        f"\nmaneuvers: nonic {len(rows['nonic'])}, limited {len(rows['limited'])}; on the "
        f"{both} both have: total {total['nonic']:.3f} s / {total['limited']:.3f} s "
        f"({total['limited'] / max(total['nonic'], 1e-9):.3f}), median ratio "
        f"{statistics.median(ratios) if ratios else float('nan'):.3f}; ball jerk (m/s³) "
        f"median / largest: nonic {_stats(jerks['nonic'])}, limited {_stats(jerks['limited'])}"
    )


def _stats(values: list[float]) -> str:
    if not values:
        return "-"
    return f"{statistics.median(values):.2f} / {max(values):.2f}"


if __name__ == "__main__":
    main()
