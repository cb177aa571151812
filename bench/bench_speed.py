"""Speed against the physical bound, gracenav and the decoupled baseline side by side.

Two measurements, each run with both planners (``planner.kind: gracenav`` and
``decoupled``) in this one process:

1. ``long``: a long open task. A fixed 30 m × 15 m building-like map
   (:func:`building_scenario`): two wall stubs along y = 7.5 m from the left and right
   edges, six columns of 0.6 m × 0.6 m, and a diagonal kept open from (3, 3) to
   (25, 12.08), L = 23.80 m (the walls and columns stay at least 1.5 m from it), rest to
   rest. Printed beside the measured time: the physical bound T* = L / v_max +
   v_max / a_max (:func:`gracenav.model.physical_time_bound`), v_max where friction
   alone takes the torque limit and a_max the steady acceleration at the palette's
   lean limit (its maneuvers' ``max_lean``, or ``--lean-limit-deg``), both from the
   palette's robot parameters.
2. ``pairs``: the first ``--trials`` trials of ``examples/campaigns/random_pairs.yaml``
   (the campaign's own draws, :func:`gracenav.campaign.runner.run_trial`; ``--seed`` replaces
   the file's seed), every trial run with both planners.

For each: success, median time to goal (trials that reached it) and the ratio
gracenav / decoupled, median max jerk and median p95 jerk (from the true state,
:mod:`gracenav.execution.smoothness`), largest lean (°) against the palette's lean
limits (its maneuvers' and the verified balancing domain's); for the pairs also the
median of time / T* with L the straight distance (a lower bound on the path, so T*
stays a bound). ``--design-push J`` sets ``planner.design_push`` (N s; default the
scenario default, gracenav.library.DEFAULT_DESIGN_PUSH; 0: none) on both measurements:
the library then keeps room, where it moves faster than 0.8 m/s
(``gracenav.library.push_fans.FAN_FLOOR``), for the catches of a push of J (with the
pairs, the campaign's draws are then checked against that library);
``--no-online-starts`` sets ``planner.online_starts: false`` on both (no start at rest
through one maneuver designed and verified at the start; the baseline ignores it), and
``--no-online-ends`` ``planner.online_ends: false`` (no end through one maneuver designed
and verified when the task starts, straight to rest at the goal);
``--no-position-filter`` sets ``simulation.position_filter: false`` on both pairs'
measurements (both planners act on the raw noisy position; the long task has no
noise). ``--baseline-jerk-scales S1,S2,...``
runs, after the pairs, the decoupled baseline alone on the same pairs at each jerk scale
(``DecoupledOptions.jerk_scale``: its flat output's jerk limit is that factor times κ
times the palette's largest lean rate; the default is 0.9), its time against its
jerk, and (after the pairs) the baseline's time at gracenav's median max jerk and its
jerk at gracenav's median time, interpolated between the scales around them
(``bench_time_jerk.py`` draws that plane for several palettes at once, on two
processes). ``--breakdown``
also prints, per pair, where gracenav's time goes (the start: capture regulators,
catches, shifts and rest trims before the first lattice maneuver that moves; the
lattice's maneuvers; the end after the last one), its path against the baseline's, and
where gracenav's largest jerk lies, with the medians over the pairs. Progress goes
to stderr, the tables to stdout.

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python bench/bench_speed.py
        [--trials 20] [--seed N] [--only long|pairs] [--lean-limit-deg 5]
        [--design-push 8] [--no-online-starts] [--no-online-ends]
        [--no-position-filter] [--breakdown] [--baseline-jerk-scales 0.9,1.8,3.6]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import dataclasses
import itertools
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.library import DEFAULT_DESIGN_PUSH
from gracenav.palette import PaletteLimits, load_palette

HERE = Path(__file__).resolve().parent
PAIRS = HERE.parent / "examples" / "campaigns" / "random_pairs.yaml"
PLANNERS = ("gracenav", "decoupled")
START = (3.0, 3.0)
GOAL = (25.0, 12.08)
CLEAR = 1.5  # m, walls and columns from the diagonal


def building_scenario(seed: int = 0) -> dict[str, Any]:
    """The long task's scenario document: 30 m × 15 m, walls and columns off an open
    diagonal from :data:`START` to :data:`GOAL` (rest to rest), no noise, no push."""
    walls = [
        {"rectangle": {"min": [0.0, 7.4], "max": [9.0, 7.6]}},
        {"rectangle": {"min": [19.0, 7.4], "max": [30.0, 7.6]}},
    ]
    columns = [(6.0, 11.0), (12.0, 11.5), (18.0, 3.5), (24.0, 4.0), (10.0, 2.0), (27.0, 9.0)]
    obstacles = walls + [
        {"rectangle": {"min": [x - 0.3, y - 0.3], "max": [x + 0.3, y + 0.3]}} for x, y in columns
    ]
    _check_open(obstacles)
    return {
        "name": "building 30 m x 15 m, long diagonal",
        "map": {"bounds": [[0.0, 0.0], [30.0, 15.0]], "resolution": 0.05, "obstacles": obstacles},
        "robot": {"footprint_radius": 0.2},
        "planner": {"cost": "time"},
        "task": {
            "kind": "point_to_point",
            "goal": [*GOAL, 0.0, 0.0],
            "starts": [[*START, 0.0, 0.0]],
        },
        "simulation": {"max_time": 150, "seed": seed},
    }


def _check_open(obstacles: list[dict[str, Any]]) -> None:
    """Every rectangle's corners and centre at least :data:`CLEAR` from the diagonal
    segment (the rectangles are small or parallel to an axis, so their vertices
    decide), and none crossing it."""
    a, b = np.asarray(START), np.asarray(GOAL)
    d = b - a
    for o in obstacles:
        lo, hi = np.asarray(o["rectangle"]["min"]), np.asarray(o["rectangle"]["max"])
        pts = np.array([lo, hi, [lo[0], hi[1]], [hi[0], lo[1]], 0.5 * (lo + hi)])
        s = np.clip((pts - a) @ d / (d @ d), 0.0, 1.0)
        dist = np.linalg.norm(pts - (a + s[:, None] * d), axis=1)
        side = np.sign(d[0] * (pts[:, 1] - a[1]) - d[1] * (pts[:, 0] - a[0]))
        if np.min(dist) < CLEAR or np.ptp(side) > 0:
            raise AssertionError(f"{o} is within {CLEAR} m of the diagonal")


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else math.nan


def _row(name: str, rows: list[dict[str, Any]], bound: float | None) -> dict[str, Any]:
    reached = [r for r in rows if r.get("reached_goal")]
    out: dict[str, Any] = {
        "planner": name,
        "success": f"{len(reached)}/{len(rows)}",
        "time": _median([r["time_s"] for r in reached]),
        "max_jerk": _median([r["max_jerk_mps3"] for r in rows if r.get("max_jerk_mps3")]),
        "p95_jerk": _median([r["p95_jerk_mps3"] for r in rows if r.get("p95_jerk_mps3")]),
        "lean_median": _median([r["max_lean_deg"] for r in rows if r.get("max_lean_deg")]),
        "lean_max": max((r["max_lean_deg"] for r in rows if r.get("max_lean_deg")), default=0.0),
        "over_bound": _median([r["time_s"] / r["bound_s"] for r in reached if "bound_s" in r]),
    }
    if bound is not None:
        out["over_bound"] = out["time"] / bound
    return out


def _print_table(rows: list[dict[str, Any]], lean: tuple[float, float]) -> None:
    print("  planner    success  time (s)  time/T*  max jerk  p95 jerk  max lean (°) median / max")
    for r in rows:
        print(
            f"  {r['planner']:<10} {r['success']:>7}  {r['time']:8.2f}  {r['over_bound']:7.2f}  "
            f"{r['max_jerk']:8.2f}  {r['p95_jerk']:8.2f}  "
            f"{r['lean_median']:.2f} / {r['lean_max']:.2f}"
        )
    g, d = rows
    print(
        f"  gracenav / decoupled: time {g['time'] / d['time']:.2f}, "
        f"max jerk {g['max_jerk'] / d['max_jerk']:.2f}, "
        f"p95 jerk {g['p95_jerk'] / d['p95_jerk']:.2f}"
    )
    print(
        f"  lean limits of the palette: maneuvers {lean[0]:.2f}°, verified balancing "
        f"domain {lean[1]:.2f}°; within the maneuvers' limit: "
        + ", ".join(f"{r['planner']} {'yes' if r['lean_max'] <= lean[0] else 'no'}" for r in rows)
    )


def bench_long(palette: Any, lean_limit: float, seed: int, keys: dict[str, Any]) -> None:
    from gracenav.model import physical_time_bound
    from gracenav.scenarios import parse_scenario, run_scenario

    length = float(np.hypot(GOAL[0] - START[0], GOAL[1] - START[1]))
    tb = physical_time_bound(palette.params, length, lean_limit=lean_limit)
    rows = []
    for planner in PLANNERS:
        doc = building_scenario(seed)
        doc["planner"]["kind"] = planner
        doc["planner"].update(keys)
        scenario = parse_scenario(doc, source="long task")
        t0 = time.perf_counter()
        print(f"long task: {planner} ...", file=sys.stderr, flush=True)
        result = run_scenario(scenario, palette=palette)
        run = result.runs[0]
        print(
            f"long task: {planner} done in {time.perf_counter() - t0:.0f} s wall "
            f"({run.outcome}, {run.time_s:.2f} s simulated)",
            file=sys.stderr,
            flush=True,
        )
        rows.append(_row(planner, [run.to_dict()], tb.bound))
    print(
        f"long task: 30 m x 15 m building, ({START[0]:g}, {START[1]:g}) -> "
        f"({GOAL[0]:g}, {GOAL[1]:g}), L = {length:.2f} m, rest to rest"
    )
    print(
        f"  physical bound: v_max {tb.v_max:.3f} m/s (friction = torque limit "
        f"{palette.params.torque_limit:g} N m), a_max {tb.a_max:.3f} m/s² at "
        f"{math.degrees(lean_limit):.2f}° lean, T* = L / v_max + v_max / a_max = {tb.bound:.2f} s"
    )
    _print_table(rows, _lean_limits(palette))


def _phases(result: Any) -> dict[str, Any]:
    """Where a gracenav run's time and largest jerk lie (:func:`bench_pairs`'s
    ``--breakdown``): the start before the first lattice maneuver that moves, the
    maneuvers, the end after the last one."""
    from gracenav.execution import CAPTURE, TERMINAL
    from gracenav.execution.smoothness import jerk_profile
    from gracenav.policies import PrimitiveKind

    ep, lib = result.episodes[0], result.library
    end_time = float(result.runs[0].time_s)

    def moving(row: int) -> bool:
        if row < 0:
            return False
        pol = lib.policy(row).policy
        return not pol.capture and pol.primitive.kind is not PrimitiveKind.REST

    def what(row: int) -> str:
        if row == CAPTURE:
            return "capture"
        if row == TERMINAL:
            return "terminal"
        if row < 0:
            return "balancing"
        pol = lib.policy(row).policy
        if pol.capture:
            return "regulator"
        return pol.primitive.kind.value

    events = ep.events
    moves = [k for k, e in enumerate(events) if moving(e.to_policy)]
    if not moves:
        start = end = end_time
    else:
        start = events[moves[0]].time
        last = moves[-1]
        end = events[last + 1].time if last + 1 < len(events) else end_time
    ps = ep.position_state
    jp = jerk_profile(ep.time, ps[:, 2:4])
    k = int(np.argmax(jp.jerk)) if jp.jerk.size else 0
    tj = float(jp.time[k]) if jp.jerk.size else math.nan
    row = int(ep.policy[min(int(np.searchsorted(ep.time, tj)), len(ep.policy) - 1)])
    where = "start" if tj < start else ("end" if tj >= end else "maneuvers")
    return {
        "start_s": start,
        "maneuvers_s": end - start,
        "end_s": end_time - end,
        "jerk_at": f"{where} ({what(row)})",
    }


def _print_breakdown(rows: list[tuple[dict[str, Any], dict[str, Any], dict[str, Any]]]) -> None:
    print(
        "  pair  dist (m)  gracenav: start  maneuvers  end  time (s)  path (m)  max jerk at"
        "                 | decoupled: time (s)  path (m)  max jerk"
    )
    for i, (g, phase, d) in enumerate(rows):
        dist = math.hypot(g["goal_x"] - g["start_x"], g["goal_y"] - g["start_y"])
        print(
            f"  {i:4d}  {dist:8.2f}  {phase['start_s']:15.2f}  {phase['maneuvers_s']:9.2f}  "
            f"{phase['end_s']:4.2f}  {g['time_s']:8.2f}  {g['path_length_m']:8.2f}  "
            f"{g['max_jerk_mps3']:6.2f} {phase['jerk_at']:<20} | {d['time_s']:19.2f}  "
            f"{d['path_length_m']:8.2f}  {d['max_jerk_mps3']:8.2f}"
        )
    jerk_where: dict[str, int] = {}
    for _, phase, _ in rows:
        key = phase["jerk_at"].split(" ")[0]
        jerk_where[key] = jerk_where.get(key, 0) + 1
    print(
        f"  medians: start {_median([p['start_s'] for _, p, _ in rows]):.2f} s, maneuvers "
        f"{_median([p['maneuvers_s'] for _, p, _ in rows]):.2f} s, end "
        f"{_median([p['end_s'] for _, p, _ in rows]):.2f} s; path gracenav / decoupled "
        f"{_median([g['path_length_m'] / d['path_length_m'] for g, _, d in rows]):.2f}; "
        "gracenav's largest jerk in the "
        + ", ".join(f"{k} {v}" for k, v in sorted(jerk_where.items()))
    )


def _pairs_campaign(
    seed: int | None, planner: dict[str, Any], simulation: dict[str, Any] | None
) -> Any:
    """The random pairs campaign with ``seed`` (None: the file's) and the planner and
    simulation keys set."""
    from gracenav.campaign import load_campaign

    campaign = load_campaign(PAIRS)
    if seed is not None:
        campaign = dataclasses.replace(campaign, seed=seed)
    doc = dict(campaign.scenario)
    doc["planner"] = {**(doc.get("planner") or {}), **planner}
    doc["simulation"] = {**(doc.get("simulation") or {}), **(simulation or {})}
    return dataclasses.replace(campaign, scenario=doc)


def bench_baseline_jerk(
    palette: Any,
    trials: int,
    seed: int | None,
    planner: dict[str, Any],
    simulation: dict[str, Any] | None,
    scales: list[float],
    gracenav: tuple[dict[str, Any], list[dict[str, Any]]] | None = None,
) -> None:
    """The decoupled baseline alone on the pairs at each jerk scale
    (``DecoupledOptions.jerk_scale``): its time against its jerk, to set beside
    gracenav's palettes at the same lean, speed and torque limits. With ``gracenav``
    (its row of the pairs' table and its rows trial by trial) also, per scale, the
    comparison pair by pair (:func:`_pair_by_pair`), and the baseline's time at
    gracenav's median max jerk and its jerk at gracenav's median time, each
    interpolated linearly between the two scales around it (not printed outside the
    measured range)."""
    from gracenav.baseline import DecoupledOptions, motion_limits
    from gracenav.campaign.runner import trial_result

    campaign = _pairs_campaign(seed, planner, simulation)
    print(
        f"decoupled baseline by jerk scale: {PAIRS.relative_to(HERE.parent)}, first "
        f"{trials} trials, seed {campaign.seed}"
    )
    print(
        "  jerk scale  jerk limit (m/s³)  filter T (s)  success  time (s)  max jerk  p95 jerk"
        "  max lean (°)"
    )
    t0 = time.perf_counter()
    points: list[tuple[float, float]] = []  # (median max jerk, median time) per scale
    for scale in scales:
        options = DecoupledOptions(jerk_scale=scale)
        limits = motion_limits(palette, options)
        rows = []
        for i in range(trials):
            row, _ = trial_result(campaign, i, "decoupled", decoupled_options=options)
            rows.append(row)
            print(
                f"baseline jerk scale {scale:g}: trial {i + 1}/{trials} "
                f"({time.perf_counter() - t0:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
        r = _row("decoupled", rows, None)
        print(
            f"  {scale:10.2f}  {limits.max_jerk:17.2f}  {limits.filter_time:12.3f}  "
            f"{r['success']:>7}  {r['time']:8.2f}  {r['max_jerk']:8.2f}  {r['p95_jerk']:8.2f}"
            f"  {r['lean_max']:12.2f}",
            flush=True,
        )
        points.append((r["max_jerk"], r["time"]))
        if gracenav is not None:
            print("              " + _pair_by_pair(gracenav[1], rows), flush=True)
    if gracenav is None or len(points) < 2:
        return
    jerk, when = gracenav[0]["max_jerk"], gracenav[0]["time"]
    at_jerk = _between(points, jerk)
    at_time = _between([(t, j) for j, t in points], when)
    print(
        f"  at gracenav's median max jerk {jerk:.2f} m/s³ the baseline takes "
        + (
            f"{at_jerk:.2f} s (gracenav / baseline {when / at_jerk:.2f})"
            if at_jerk is not None
            else "(outside the measured scales)"
        )
        + f"; at gracenav's median time {when:.2f} s it jerks "
        + (
            f"{at_time:.2f} m/s³ (gracenav / baseline {jerk / at_time:.2f})"
            if at_time is not None
            else "(outside the measured scales)"
        )
    )


def _pair_by_pair(gracenav: list[dict[str, Any]], decoupled: list[dict[str, Any]]) -> str:
    """gracenav against the baseline on the pairs both reached: on how many gracenav is
    faster and jerks less, the medians of the time and path ratios, the least-squares
    slope and the correlation of the time difference on the path difference, and the
    median time difference where the two paths agree within 0.1 m."""
    both = [
        (g, d)
        for g, d in zip(gracenav, decoupled, strict=True)
        if g.get("reached_goal") and d.get("reached_goal")
    ]
    if len(both) < 2:
        return "pair by pair: fewer than 2 pairs both reached"
    dt = np.array([g["time_s"] - d["time_s"] for g, d in both])
    dp = np.array([g["path_length_m"] - d["path_length_m"] for g, d in both])
    slope = float(np.polyfit(dp, dt, 1)[0]) if np.ptp(dp) > 0 else math.nan
    corr = float(np.corrcoef(dp, dt)[0, 1]) if np.ptp(dp) > 0 and np.ptp(dt) > 0 else math.nan
    same = dt[np.abs(dp) < 0.1]
    return (
        f"pair by pair ({len(both)}): gracenav faster on "
        f"{sum(g['time_s'] < d['time_s'] for g, d in both)}, jerks less on "
        f"{sum(g['max_jerk_mps3'] < d['max_jerk_mps3'] for g, d in both)}; median time "
        f"ratio {_median([g['time_s'] / d['time_s'] for g, d in both]):.3f}, path ratio "
        f"{_median([g['path_length_m'] / d['path_length_m'] for g, d in both]):.3f}; time "
        f"difference {slope:.2f} s per m of path difference (correlation {corr:.2f}); "
        f"paths within 0.1 m on {same.size}: median time difference "
        f"{(float(np.median(same)) if same.size else math.nan):+.2f} s"
    )


def _between(points: list[tuple[float, float]], x: float) -> float | None:
    """y at ``x``, linear between the two points around it in x (None outside)."""
    pts = sorted(points)
    for (x0, y0), (x1, y1) in itertools.pairwise(pts):
        if x0 <= x <= x1:
            return y0 if x1 == x0 else y0 + (x - x0) / (x1 - x0) * (y1 - y0)
    return None


def bench_pairs(
    palette: Any,
    trials: int,
    seed: int | None,
    lean_limit: float,
    planner: dict[str, Any],
    breakdown: bool = False,
    simulation: dict[str, Any] | None = None,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    from gracenav.campaign.runner import trial_result
    from gracenav.model import physical_time_bound

    campaign = _pairs_campaign(seed, planner, simulation)
    by_planner: dict[str, list[dict[str, Any]]] = {p: [] for p in PLANNERS}
    phases: list[tuple[dict[str, Any], dict[str, Any], dict[str, Any]]] = []
    t0 = time.perf_counter()
    for i in range(trials):
        phase = None
        for kind in PLANNERS:
            row, result = trial_result(campaign, i, kind)
            if breakdown and kind == "gracenav" and result is not None and row["reached_goal"]:
                phase = _phases(result)
            if "start_x" in row:
                length = math.hypot(row["goal_x"] - row["start_x"], row["goal_y"] - row["start_y"])
                bound = physical_time_bound(palette.params, length, lean_limit=lean_limit)
                row["bound_s"] = bound.bound
            by_planner[kind].append(row)
        if phase is not None and by_planner["decoupled"][-1].get("reached_goal"):
            phases.append((by_planner["gracenav"][-1], phase, by_planner["decoupled"][-1]))
        print(
            f"pairs: trial {i + 1}/{trials} ({time.perf_counter() - t0:.0f} s)",
            file=sys.stderr,
            flush=True,
        )
    rows = [_row(p, by_planner[p], None) for p in PLANNERS]
    print(
        f"random pairs: {PAIRS.relative_to(HERE.parent)}, first {trials} trials, seed "
        f"{campaign.seed}; time/T* is the median over trials, L the straight distance, "
        f"a_max at {math.degrees(lean_limit):.2f}°"
    )
    _print_table(rows, _lean_limits(palette))
    if breakdown:
        print("  where the time goes (pairs both planners reached):")
        _print_breakdown(phases)
    return rows, by_planner["gracenav"]


def _lean_limits(palette: Any) -> tuple[float, float]:
    """The palette's lean limits (°): its maneuvers' and its verified balancing domain's."""
    return (
        math.degrees(PaletteLimits.of(palette).max_lean),
        math.degrees(palette.options.lean_limit),
    )


def _scales(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not a comma-separated list of numbers: {text!r}"
        ) from None
    if not values or not all(0 < v <= 10 for v in values):
        raise argparse.ArgumentTypeError(f"jerk scales lie in (0, 10], got {text!r}")
    return values


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--trials", type=int, default=20, help="random pairs trials (default 20)")
    ap.add_argument(
        "--seed", type=int, default=None, help="campaign seed (default: the file's); long: sim"
    )
    ap.add_argument("--only", choices=("long", "pairs"), default=None)
    ap.add_argument(
        "--lean-limit-deg",
        type=float,
        default=None,
        help="lean limit of the bound (default: the palette's maneuvers' max_lean)",
    )
    ap.add_argument(
        "--design-push",
        type=float,
        default=DEFAULT_DESIGN_PUSH,
        help="planner.design_push (N s) of both measurements (default "
        f"{DEFAULT_DESIGN_PUSH:g}, the scenario default; 0: none)",
    )
    ap.add_argument(
        "--no-online-starts",
        action="store_true",
        help="planner.online_starts: false (no start at rest through one maneuver designed "
        "and verified at the start)",
    )
    ap.add_argument(
        "--no-online-ends",
        action="store_true",
        help="planner.online_ends: false (no end through one maneuver designed and verified "
        "when the task starts)",
    )
    ap.add_argument(
        "--no-position-filter",
        action="store_true",
        help="simulation.position_filter: false on the pairs (both planners act on the raw "
        "noisy position)",
    )
    ap.add_argument(
        "--baseline-jerk-scales",
        type=_scales,
        default=None,
        metavar="S1,S2,...",
        help="pairs: also the decoupled baseline alone at each jerk scale "
        "(DecoupledOptions.jerk_scale; its default is accel_scale, 0.9)",
    )
    ap.add_argument(
        "--breakdown",
        action="store_true",
        help="pairs: also where gracenav's time and largest jerk lie, pair by pair",
    )
    args = ap.parse_args()
    palette = load_palette()
    lean = (
        math.radians(args.lean_limit_deg)
        if args.lean_limit_deg is not None
        else float(PaletteLimits.of(palette).max_lean)
    )
    planner: dict[str, Any] = {"design_push": args.design_push}
    if args.no_online_starts:
        planner["online_starts"] = False
    if args.no_online_ends:
        planner["online_ends"] = False
    if args.only in (None, "long"):
        bench_long(palette, lean, args.seed if args.seed is not None else 0, planner)
    simulation = {"position_filter": False} if args.no_position_filter else {}
    gracenav = None
    if args.only in (None, "pairs"):
        rows, trials = bench_pairs(
            palette, args.trials, args.seed, lean, planner, args.breakdown, simulation
        )
        gracenav = (rows[0], trials)
    if args.baseline_jerk_scales:
        bench_baseline_jerk(
            palette,
            args.trials,
            args.seed,
            planner,
            simulation,
            args.baseline_jerk_scales,
            gracenav,
        )


if __name__ == "__main__":
    main()
