"""Starts at rest off the lattice: a shift and a start from rest, against one maneuver.

A task that starts at rest off the lattice reaches the lattice with a shift (a nonic
from rest to rest within the shifts' ball jerk bound, ``CatchOptions.shift_max_ball_jerk``)
and then leaves the rest trim with ``rest_to_cruise_x_1_0``. This measures what a single
maneuver from the start itself to the cruise trim would take instead: for start offsets
(a, b) from a lattice point P (a behind P along the cruise direction +x, b across it,
on a grid of ``--step`` over a cell of the goal's sub-lattice, 0 <= a < d and
0 <= b <= d / 2: the robot is symmetric about its direction of travel), the shortest
nonic from rest at (−a, −b) to cruise at P + k d (k ≥ 1, the smallest that is
feasible) that the shape trajectory planner makes feasible on the 3D model in both
frames, as the palette's maneuvers (``gracenav.primitives.design``), against the shift
(from (−a, −b) to P, at rest) and ``rest_to_cruise_x_1_0`` followed by cruise to P + k d.
Both ways end in the same state (cruise at P + k d); the time the robot waits between
the shift and the start (the still band) is not counted, which favours the shift.

Prints, per offset, the two ways' durations and their difference, then the medians.

``--pairs N`` then runs gracenav on the first N trials of
``examples/campaigns/random_pairs.yaml`` (online starts and ends on, as by default) and
times the design of each online start (its candidates,
:func:`gracenav.execution.launch.launch_candidates`, and the still band's verification of
the one taken, :func:`gracenav.execution.launch.confirm_launch`) and each online end
(:func:`gracenav.execution.arrival.arrival_plan`), wall time, every call: the campaign's
check of the pair, the task's check and its run (a task's check and run share one
design): calls, calls that gave one, median, 90th percentile and largest time.

    OPENBLAS_NUM_THREADS=1 python bench/bench_starts.py [--step 0.125] [--pairs 20]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math
import statistics

import numpy as np

from gracenav.params import BallbotParams
from gracenav.policies.catches import ball_jerk
from gracenav.policies.options import CatchOptions
from gracenav.primitives import PrimitiveSetOptions
from gracenav.primitives.design import _plan_pair, _reference_ok
from gracenav.primitives.references import NonicReference

D = 0.5  # m, the lattice's d
V = 0.5  # m/s, the cruise speed
START = 1.875  # s, rest_to_cruise_x_1_0 of the shipped palette (d at 0.5 m/s)


def shortest(
    disp: np.ndarray, v1: np.ndarray, options: PrimitiveSetOptions, params: BallbotParams
) -> float | None:
    """Shortest duration on the grid of a nonic from rest over ``disp`` to ``v1`` that
    is feasible on the 3D model in both frames; None within ``options.max_duration``."""
    step = options.duration_step
    zero = np.zeros(2)
    for m in range(1, math.floor(options.max_duration / step + 1e-9) + 1):
        ref = NonicReference.between(m * step, zero, zero, disp, v1)
        if not _reference_ok(ref, zero, v1, options):
            continue
        if _plan_pair(ref, zero, disp, v1, params, options) is not None:
            return m * step
    return None


def shift_duration(disp: np.ndarray, params: BallbotParams, bound: float) -> float:
    """The shift's nonic: the shortest duration (1/128 s grid, at least 1 s) whose ball
    jerk stays within ``bound`` (the lean limit is never what sets a shift's duration)."""
    zero = np.zeros(2)
    t = 1.0
    while ball_jerk(NonicReference.between(t, zero, zero, disp, zero), params) > bound:
        t += 1.0 / 128.0
        if t > 60.0:  # the nonic's jerk falls as 1/T³: never reached for a sane bound
            raise ValueError(f"no shift over {disp} within {bound} m/s³ of ball jerk")
    return t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=0.125, help="offset grid (m)")
    ap.add_argument(
        "--pairs",
        type=int,
        default=0,
        help="also time the online starts' design on the first N random pairs",
    )
    args = ap.parse_args()
    params = BallbotParams()
    options = PrimitiveSetOptions()
    bound = CatchOptions().shift_max_ball_jerk
    assert bound is not None
    v1 = np.array([V, 0.0])
    n = round(D / args.step)
    print(
        f"{'a (m)':>6s} {'b (m)':>6s} {'k':>2s} {'shift (s)':>9s} {'start+cruise':>12s} "
        f"{'total (s)':>9s} {'one maneuver':>12s} {'saved (s)':>9s}"
    )
    saved = []
    ones = []
    for i in range(n):
        a = i * args.step
        for j in range(n // 2 + 1):
            b = j * args.step
            if a == 0.0 and b == 0.0:
                continue
            one = None
            k = 1
            while one is None and k <= 4:
                one = shortest(np.array([k * D + a, b]), v1, options, params)
                k += 1 if one is None else 0
            if one is None:
                print(f"{a:6.3f} {b:6.3f}  - no maneuver within {options.max_duration} s")
                continue
            shift = shift_duration(np.array([a, b]), params, bound)
            rest = START + (k - 1) * D / V
            total = shift + rest
            saved.append(total - one)
            ones.append(one)
            print(
                f"{a:6.3f} {b:6.3f} {k:2d} {shift:9.3f} {rest:12.3f} {total:9.3f} "
                f"{one:12.3f} {total - one:9.3f}"
            )
    if saved:
        print(
            f"offsets: {len(saved)}; one maneuver median {statistics.median(ones):.3f} s; "
            f"saved median {statistics.median(saved):.3f} s (least {min(saved):.3f}, most "
            f"{max(saved):.3f})"
        )
    if args.pairs:
        time_starts(args.pairs)


def time_starts(trials: int) -> None:
    """Wall time of every online start's and online end's design on the first
    ``trials`` random pairs."""
    import dataclasses
    import sys
    import time
    from collections.abc import Callable
    from pathlib import Path
    from typing import Any

    import gracenav.execution.controller as controller
    from gracenav.campaign import load_campaign
    from gracenav.campaign.runner import trial_result

    names = {
        "launch_candidates": "online starts (candidates)",
        "confirm_launch": "online starts (still band)",
        "arrival_plan": "online ends",
    }
    designs = {name: getattr(controller, name) for name in names}
    seconds: dict[str, list[float]] = {name: [] for name in names}
    taken = dict.fromkeys(names, 0)

    def timed(name: str) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            plan = designs[name](*args, **kwargs)
            seconds[name].append(time.perf_counter() - t0)
            taken[name] += plan is not None and plan != ()
            return plan

        return run

    campaign = load_campaign(
        Path(__file__).resolve().parent.parent / "examples" / "campaigns" / "random_pairs.yaml"
    )
    doc = dict(campaign.scenario)
    doc["planner"] = {**(doc.get("planner") or {}), "online_starts": True, "online_ends": True}
    campaign = dataclasses.replace(campaign, scenario=doc)
    for name in names:
        setattr(controller, name, timed(name))
    try:
        for i in range(trials):
            trial_result(campaign, i, "gracenav")
            print(f"pairs: trial {i + 1}/{trials}", file=sys.stderr, flush=True)
    finally:
        for name, design in designs.items():
            setattr(controller, name, design)
    for name, label in names.items():
        t = np.array(seconds[name])
        if t.size == 0:
            print(f"{label} on the first {trials} random pairs: no calls")
            continue
        print(
            f"{label} on the first {trials} random pairs: {t.size} calls, {taken[name]} took "
            f"one; wall time median {np.median(t):.3f} s, 90th percentile "
            f"{np.percentile(t, 90):.2f} s, largest {t.max():.2f} s"
        )


if __name__ == "__main__":
    main()
