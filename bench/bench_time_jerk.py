"""Both planners on one time–jerk plane: gracenav's palettes against the baseline's curve.

The decoupled baseline trades jerk for time through one setting, its jerk limit
(``DecoupledOptions.jerk_scale`` times κ times the largest lean rate of the palette whose
limits it takes); a gracenav palette trades them through its ball jerk bound
(``PaletteLimits.max_ball_jerk``). This runs, on the first ``--trials`` trials of
``examples/campaigns/random_pairs.yaml`` (the campaign's own draws,
:func:`gracenav.campaign.runner.trial_result`):

- gracenav with each palette of ``--palettes`` (shipped names or files; each draws the
  pairs with its own library, as a campaign run with it would),
- the baseline at each jerk scale of ``--jerk-scales``, with the limits of
  ``--baseline-palette`` (default: the default palette) and that palette's draws and
  controller (``--baseline-friction-midpoint``: with the friction fed forward at the
  mid-period rate instead, :attr:`gracenav.control.ControllerGains.friction_midpoint`,
  to compare with palettes built with ``--friction-midpoint``; the baseline verifies no
  domain, so its palette need not be rebuilt for it),

on a pool of ``--processes`` worker processes, and prints for each line the success,
the median time to goal and the medians of the max and p95 jerk (true state,
:mod:`gracenav.execution.smoothness`) over the trials it reached, the largest lean, and
the median max jerk of the noise-free and of the noisy trials apart (the campaign's
trials alternate 0 and 5 mm of position noise; with noise the true state's jerk holds
the feedback's answer to the sensor too).
Then, for each palette: the baseline's time at the palette's median max jerk and its
jerk at the palette's median time (linear between the two scales around it; not
outside the measured scales), and whether the palette meets both targets of the speed
issue against the baseline at its default scale (median time and median max jerk at
most the baseline's). ``--plot FILE`` draws the plane (PNG); ``--jsonl FILE`` writes
every row as it comes, and a run given a file that holds rows (of an earlier or
interrupted run) runs only the trials it lacks. Progress goes to stderr, the tables to
stdout.

    OPENBLAS_NUM_THREADS=1 python bench/bench_time_jerk.py [--trials 200]
        [--palettes default,smooth] [--jerk-scales 0.6,0.9,1.35,1.8,2.7]
        [--baseline-palette default] [--baseline-friction-midpoint]
        [--processes 2] [--plot plane.png] [--jsonl rows.jsonl]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from bench_speed import HERE, PAIRS, _between, _scales

from gracenav.baseline import DecoupledOptions

#: The baseline's default jerk scale (its ``accel_scale``, which ``jerk_scale`` follows
#: when not given).
DEFAULT_SCALE = DecoupledOptions().accel_scale

#: Suffix of a palette name whose controller feeds friction forward at the mid-period
#: rate (the baseline's only: gracenav's palettes are verified with their own).
MIDPOINT = "+midpoint"

_PALETTES: dict[str, Any] = {}


def _palette(name: str) -> Any:
    """The palette ``name`` (``default``: :func:`gracenav.palette.load_palette`'s; with
    :data:`MIDPOINT` after it, that palette with the mid-period friction feed-forward in
    its controller), loaded once per worker."""
    import dataclasses

    from gracenav.palette import load_palette

    if name not in _PALETTES:
        if name.endswith(MIDPOINT):
            # The controller is the policies' (Palette.gains): theirs replaced; the
            # baseline uses no policy's domain, so none needs verifying again.
            pal = _palette(name.removesuffix(MIDPOINT))
            gains = dataclasses.replace(pal.gains, friction_midpoint=True)
            policies = tuple(dataclasses.replace(q, gains=gains) for q in pal.policies)
            _PALETTES[name] = dataclasses.replace(pal, policies=policies)
        else:
            _PALETTES[name] = load_palette(None if name == "default" else name)
    return _PALETTES[name]


def _label(name: str) -> str:
    """``name`` (a file's stem), the ball jerk bound of its maneuvers and its cruise
    speeds where they are not the default palette's."""
    from gracenav.palette import PaletteLimits

    limits = PaletteLimits.of(_palette(name))
    bound = (
        f"ball jerk ≤ {limits.max_ball_jerk:g} m/s³" if limits.reference == "limited" else "nonics"
    )
    if limits.cruise_speeds != PaletteLimits().cruise_speeds:
        bound += ", cruise " + ", ".join(f"{v:g}" for v in limits.cruise_speeds) + " m/s"
    return f"{Path(name).stem if ('/' in name or '.' in name) else name} ({bound})"


def _trial(job: tuple[str, str, float | None, int]) -> dict[str, Any]:
    """One row: gracenav on palette ``name``, or the baseline at jerk scale ``scale``
    with palette ``name``'s limits (in a worker)."""
    from gracenav.baseline import DecoupledOptions
    from gracenav.campaign import load_campaign
    from gracenav.campaign.runner import trial_result

    planner, name, scale, index = job
    options = DecoupledOptions(jerk_scale=scale) if scale is not None else None
    row, _ = trial_result(
        load_campaign(PAIRS), index, planner, palette=_palette(name), decoupled_options=options
    )
    keep = {k: v for k, v in row.items() if v is None or isinstance(v, int | float | str | bool)}
    return {"palette": name, "jerk_scale": scale, **keep}


def _read_rows(path: Path) -> dict[tuple[str, str, float | None, int], dict[str, Any]]:
    """The rows an earlier run wrote to ``path`` (a line cut by a kill is left out: that
    trial runs again)."""
    done: dict[tuple[str, str, float | None, int], dict[str, Any]] = {}
    if not path.exists():
        return done
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
            done[(row["planner"], row["palette"], row["jerk_scale"], row["trial"])] = row
        except (json.JSONDecodeError, KeyError, TypeError):
            continue
    return done


def _line(rows: list[dict[str, Any]]) -> dict[str, Any]:
    reached = [r for r in rows if r.get("reached_goal")]
    return {
        "success": f"{len(reached)}/{len(rows)}",
        "time": _median([r["time_s"] for r in reached]),
        "max_jerk": _median([r["max_jerk_mps3"] for r in reached]),
        "p95_jerk": _median([r["p95_jerk_mps3"] for r in reached]),
        "lean": max((r["max_lean_deg"] for r in reached), default=float("nan")),
        # The median max jerk of the noise-free and of the noisy trials: with position
        # noise the true state's jerk holds the feedback's answer to the sensor too.
        "quiet_jerk": _median([r["max_jerk_mps3"] for r in reached if not r["noise_std_m"]]),
        "noisy_jerk": _median([r["max_jerk_mps3"] for r in reached if r["noise_std_m"]]),
    }


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def _plot(
    path: Path,
    curve: list[tuple[float, dict[str, Any]]],
    palettes: list[tuple[str, dict[str, Any]]],
    trials: int,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    xs = [line["max_jerk"] for _, line in curve]
    ys = [line["time"] for _, line in curve]
    ax.plot(xs, ys, "o-", color="tab:gray", label="decoupled baseline, by jerk scale")
    for scale, line in curve:
        ax.annotate(
            f"{scale:g}",
            (line["max_jerk"], line["time"]),
            textcoords="offset points",
            xytext=(-4, -13),
            fontsize=8,
            color="tab:gray",
        )
    for name, line in palettes:
        ax.plot(
            line["max_jerk"], line["time"], "s", markersize=7, label=f"gracenav, {_label(name)}"
        )
    default = dict(curve)[DEFAULT_SCALE]
    ax.fill_between(
        [min(xs + [ln["max_jerk"] for _, ln in palettes]) * 0.8, default["max_jerk"]],
        0.0,
        default["time"],
        color="tab:gray",
        alpha=0.15,
        label="both targets against the default scale",
    )
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.ScalarFormatter())
    ax.tick_params(axis="x", which="minor", labelsize=7)
    ys_all = ys + [ln["time"] for _, ln in palettes]
    ax.set_ylim(min(ys_all) - 0.5, max(ys_all) + 0.5)
    ax.set_xlabel("median max jerk of the ball (m/s³, true state)")
    ax.set_ylabel("median time to goal (s)")
    ax.set_title(f"random pairs, first {trials} trials")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".part")
    fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
    tmp.replace(path)


def _names(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f"no palette named in {text!r}")
    return names


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--trials", type=int, default=200, help="random pairs trials (default 200)")
    ap.add_argument(
        "--palettes",
        type=_names,
        default=["default", "smooth"],
        help="gracenav's palettes, shipped names or files (default default,smooth)",
    )
    ap.add_argument(
        "--jerk-scales",
        type=_scales,
        default=[0.6, 0.9, 1.35, 1.8, 2.7],
        help="the baseline's jerk scales (default 0.6,0.9,1.35,1.8,2.7)",
    )
    ap.add_argument(
        "--baseline-palette",
        default="default",
        help="the palette whose limits the baseline takes (default: the default)",
    )
    ap.add_argument(
        "--baseline-friction-midpoint",
        action="store_true",
        help=(
            "the baseline's controller feeds friction forward at the mid-period rate (as "
            "palettes built with --friction-midpoint do)"
        ),
    )
    ap.add_argument("--processes", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--plot", type=Path, default=None, help="draw the plane here (PNG)")
    ap.add_argument(
        "--jsonl",
        type=Path,
        default=None,
        help="write every row here as it comes; rows already there are not run again",
    )
    args = ap.parse_args()
    if not 1 <= args.trials <= 200:
        ap.error(f"--trials must be 1..200 (the campaign's trials), got {args.trials}")
    if args.processes < 1:
        ap.error(f"--processes must be at least 1, got {args.processes}")
    args.jerk_scales = sorted(set(args.jerk_scales))
    if len(args.jerk_scales) < 2:
        ap.error("--jerk-scales needs at least two scales: the baseline's curve")
    if DEFAULT_SCALE not in args.jerk_scales:
        ap.error(f"--jerk-scales must include the baseline's default, {DEFAULT_SCALE:g}")
    if any(p.endswith(MIDPOINT) for p in [*args.palettes, args.baseline_palette]):
        ap.error(
            f"no palette name may end with {MIDPOINT!r}: build gracenav's palette with "
            "--friction-midpoint, give the baseline --baseline-friction-midpoint"
        )
    if args.baseline_friction_midpoint:
        args.baseline_palette += MIDPOINT
    for name in {*args.palettes, args.baseline_palette}:
        try:
            _palette(name)
        except Exception as exc:  # a one-line refusal, whatever the loader says
            ap.error(f"palette {name!r}: {exc}")
    jobs: list[tuple[str, str, float | None, int]] = [
        ("decoupled", args.baseline_palette, s, i)
        for s in args.jerk_scales
        for i in range(args.trials)
    ] + [("gracenav", p, None, i) for p in args.palettes for i in range(args.trials)]
    done = _read_rows(args.jsonl) if args.jsonl is not None else {}
    todo = [job for job in jobs if job not in done]
    if done:
        print(
            f"time-jerk: {len(jobs) - len(todo)} of {len(jobs)} rows read from {args.jsonl}",
            file=sys.stderr,
        )
    t0 = time.perf_counter()
    log = args.jsonl.open("a") if args.jsonl is not None else None
    try:
        with ProcessPoolExecutor(args.processes) as pool:
            for k, (job, row) in enumerate(
                zip(todo, pool.map(_trial, todo, chunksize=4), strict=True)
            ):
                done[job] = row
                if log is not None:
                    log.write(json.dumps(row) + "\n")
                    log.flush()
                print(
                    f"time-jerk: {k + 1}/{len(todo)} ({time.perf_counter() - t0:.0f} s)",
                    file=sys.stderr,
                    flush=True,
                )
    finally:
        if log is not None:
            log.close()
    rows = [done[job] for job in jobs]
    n = args.trials
    curve = [(s, _line(rows[k * n : (k + 1) * n])) for k, s in enumerate(args.jerk_scales)]
    base = len(args.jerk_scales) * n
    palettes = [
        (p, _line(rows[base + k * n : base + (k + 1) * n])) for k, p in enumerate(args.palettes)
    ]
    print(
        f"random pairs: {PAIRS.relative_to(HERE.parent)}, first {n} trials; medians over the "
        f"trials reached; the baseline with the limits of {args.baseline_palette!r}"
    )
    print(
        "  planner    palette / jerk scale   success  time (s)  max jerk  p95 jerk  max lean (°)"
        "  max jerk noise-free / noisy"
    )
    for label, line in [(f"decoupled  {s:<20g}", ln) for s, ln in curve] + [
        (f"gracenav   {p:<20s}", ln) for p, ln in palettes
    ]:
        print(
            f"  {label}  {line['success']:>7}  {line['time']:8.2f}  {line['max_jerk']:8.2f}"
            f"  {line['p95_jerk']:8.2f}  {line['lean']:12.2f}"
            f"  {line['quiet_jerk']:17.2f} / {line['noisy_jerk']:.2f}"
        )
    points = [(ln["max_jerk"], ln["time"]) for _, ln in curve]
    default = dict(curve)[DEFAULT_SCALE]
    for p, line in palettes:
        at_jerk = _between(points, line["max_jerk"])
        at_time = _between([(t, j) for j, t in points], line["time"])
        both = line["time"] <= default["time"] and line["max_jerk"] <= default["max_jerk"]
        print(
            f"  {p}: the baseline at its median max jerk {line['max_jerk']:.2f} m/s³ takes "
            + (
                f"{at_jerk:.2f} s (time ratio {line['time'] / at_jerk:.3f})"
                if at_jerk
                else "(outside)"
            )
            + f"; at its median time {line['time']:.2f} s jerks "
            + (
                f"{at_time:.2f} m/s³ (jerk ratio {line['max_jerk'] / at_time:.2f})"
                if at_time
                else "(outside)"
            )
            + f"; against the baseline's default scale {DEFAULT_SCALE:g}: time "
            f"{'<=' if line['time'] <= default['time'] else '>'} and jerk "
            f"{'<=' if line['max_jerk'] <= default['max_jerk'] else '>'}: "
            + ("both targets met" if both else "not both")
        )
    if args.plot is not None:
        _plot(args.plot, curve, palettes, n)
        print(f"  plane drawn: {args.plot}")


if __name__ == "__main__":
    main()
