"""``gracenav palette ...``: build, verify and show the motion policy palette."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.cli._common import add_palette_argument, add_params_argument, load_params

__all__ = ["register"]


def _bound_or_none(text: str) -> float | None:
    """A bound (float) from the command line, or None for ``none``."""
    if text.strip().lower() == "none":
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected m/s³ or 'none', got {text!r}") from None


def register(sub: Any) -> None:
    """Add the ``palette`` command group."""
    p = sub.add_parser(
        "palette",
        help="build, verify or show the motion policy palette",
        description=(
            "The motion policy palette: one verified motion policy per primitive of the "
            "set Σ(d). The palette shipped with gracenav is used unless --file is given."
        ),
    )
    s = p.add_subparsers(dest="what", metavar="WHAT", parser_class=type(p))
    s.required = True
    b = s.add_parser(
        "build",
        help="plan the primitives, size and verify every policy, write the palette file",
        description=(
            "Plan the primitive set Σ(d), then size each policy's start domain by bisection "
            "and verify it on the 3D model from points on the surface of S. Policies that "
            "fail are left out and listed. Runs in parallel worker processes."
        ),
    )
    b.add_argument(
        "--out",
        type=Path,
        default=None,
        help=(
            "palette file to write (default: the user cache, where every command that "
            "needs this palette finds it; see $GRACENAV_CACHE_DIR)"
        ),
    )
    b.add_argument("--processes", type=int, default=2, help="worker processes (default 2)")
    add_params_argument(b, "the robot to build the palette for (controller and plant)")
    b.add_argument("--d", type=float, default=0.5, help="distance parameter d (m, default 0.5)")
    b.add_argument(
        "--reference",
        choices=("nonic", "limited"),
        default=argparse.SUPPRESS,
        help=(
            "maneuver references: the polynomials that keep the lean, the torque and the "
            "ball's jerk within their limits for the shortest duration (limited, the "
            "default palette's), or the nonic of fixed form"
        ),
    )
    b.add_argument(
        "--cruise-speed",
        type=float,
        default=0.5,
        metavar="V",
        help=(
            "speed (m/s) of the first level's cruise trims (default 0.5): a palette whose "
            "ball jerk bound is low keeps its tight turns, starts and stops (one or two "
            "cells) only at a lower speed, since their jerk grows with the cube of it"
        ),
    )
    b.add_argument(
        "--cruise-speeds",
        type=float,
        nargs="+",
        default=(),
        metavar="V",
        help=(
            "further cruise speeds (m/s) above --cruise-speed, ascending, each with its "
            "maneuvers; the catches then reach 0.3 m/s above the top one (at least 1.2 m/s)"
        ),
    )
    b.add_argument(
        "--max-speed",
        type=float,
        default=None,
        help="largest speed of a maneuver's reference (m/s; default 0.8, or 1.1 × the top speed)",
    )
    b.add_argument(
        "--max-ball-jerk",
        type=float,
        default=argparse.SUPPRESS,
        help="largest ball jerk of a limited reference (m/s³; default: the default palette's, 3)",
    )
    b.add_argument(
        "--shift-max-ball-jerk",
        type=_bound_or_none,
        default=argparse.SUPPRESS,
        metavar="J",
        help=(
            "largest ball jerk of the capture's shifts (m/s³; default: the default "
            "palette's, 3): they last as "
            "long as their nonic needs to stay within it; 'none': the shortest feasible "
            "nonic"
        ),
    )
    b.add_argument(
        "--friction-midpoint",
        action="store_true",
        help=(
            "build for a controller that feeds friction forward at the ball rate predicted "
            "for the middle of each control period (the measured rate plus half the "
            "reference's change over it) instead of the measured rate: no jerk pulse where "
            "the ball's rate crosses zero; the shipped palettes use the measured rate"
        ),
    )
    b.set_defaults(func=run_build)
    v = s.add_parser(
        "verify",
        help="re-verify every policy of a palette file on the 3D model",
        description="Re-run the verification of every policy of the palette and report.",
    )
    add_palette_argument(v, "--file")
    v.add_argument(
        "--switches",
        action="store_true",
        help="also simulate every graceful switch and report the commanded torque jump",
    )
    add_params_argument(
        v,
        "the simulated plant the policies are re-verified on (a robustness check); the "
        "controllers keep their nominal design",
    )
    v.set_defaults(func=run_verify)
    sh = s.add_parser(
        "show",
        help="print the palette as a table",
        description=(
            "Print name, duration, start and goal radii, worst D' margin, max lean and max "
            "torque of every policy (lean in degrees)."
        ),
    )
    add_palette_argument(sh, "--file")
    sh.set_defaults(func=run_show)


def _table(palette: Any) -> str:
    rows = [
        (
            "name",
            "T (s)",
            "S pos (m)",
            "S vel (m/s)",
            "G pos (m)",
            "G vel (m/s)",
            "D' margin",
            "max lean (°)",
            "max τ (N m)",
        )
    ]
    for pol in (*palette.policies, *palette.catches, *palette.shifts):
        rep = pol.report
        rows.append(
            (
                pol.name,
                f"{pol.duration:.3f}",
                f"{pol.start_radii.position:.3f}",
                f"{pol.start_radii.velocity:.3f}",
                f"{pol.goal_radii.position:.3f}",
                f"{pol.goal_radii.velocity:.3f}",
                "-" if rep is None else f"{1.0 - np.sqrt(rep.max_outer_value):.3f}",
                "-" if rep is None else f"{np.rad2deg(rep.max_lean):.2f}",
                "-" if rep is None else f"{rep.max_torque:.1f}",
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def run_build(args: argparse.Namespace) -> int:
    """Run ``gracenav palette build``."""
    import time

    from gracenav import BallbotParams
    from gracenav.control import design_gains
    from gracenav.errors import ConfigError
    from gracenav.model import top_speed
    from gracenav.palette import (
        PaletteLimits,
        build_palette_for,
        cached_palette_path,
        catch_speeds_for,
    )

    if args.processes < 1:
        raise ConfigError(f"--processes must be >= 1, got {args.processes}")
    if not args.d > 0:
        raise ConfigError(f"--d must be positive, got {args.d}")
    t0 = time.perf_counter()
    params = load_params(args) or BallbotParams()
    v_max = top_speed(params)
    for flag, v in (
        ("--cruise-speed", args.cruise_speed),
        *(("--cruise-speeds", v) for v in args.cruise_speeds),
    ):
        if not (math.isfinite(v) and 0.0 < v < v_max):
            raise ConfigError(
                f"{flag} {v:g} m/s: a cruise speed must be positive and below the robot's top "
                f"speed {v_max:.3f} m/s (where friction alone takes the torque limit)"
            )
    speeds = (args.cruise_speed, *args.cruise_speeds)
    max_speed = args.max_speed if args.max_speed is not None else max(0.8, 1.1 * speeds[-1])
    limits = PaletteLimits(
        cruise_speeds=speeds,
        catch_speeds=catch_speeds_for(speeds),
        max_speed=max_speed,
        # Limits not given are the default palette's (PaletteLimits()).
        reference=getattr(args, "reference", PaletteLimits.reference),
        max_ball_jerk=getattr(args, "max_ball_jerk", PaletteLimits.max_ball_jerk),
        shift_max_ball_jerk=getattr(args, "shift_max_ball_jerk", PaletteLimits.shift_max_ball_jerk),
    )
    pal = build_palette_for(
        params=params,
        gains=design_gains(params, friction_midpoint=args.friction_midpoint),
        options=limits.verification_options(),
        d=args.d,
        processes=args.processes,
        primitive_options=limits.primitive_options(),
    )
    t2 = time.perf_counter()
    out = pal.save(args.out if args.out is not None else cached_palette_path(pal.key))
    print(_table(pal))
    for name, rep in pal.rejected:
        print(
            f"rejected {name}: D' value {rep.max_outer_value:.2f}, goal value "
            f"{rep.max_goal_value:.2f}, lean {np.rad2deg(rep.max_lean):.1f}°, "
            f"saturated runs {rep.saturated_runs}"
        )
    print(
        f"{len(pal)} policies verified, {len(pal.rejected)} rejected, primitives planned and "
        f"policies sized and verified in {t2 - t0:.1f} s; wrote {out}"
    )
    return 0


def run_verify(args: argparse.Namespace) -> int:
    """Run ``gracenav palette verify``."""
    import time

    from gracenav.palette import REGULATOR_NAME, load_palette
    from gracenav.policies import switch_torque_jumps, verify_placements

    pal = load_palette(args.file)
    plant = load_params(args)
    t0 = time.perf_counter()
    failed = []
    opts = pal.options
    leans = None
    if any(p.capture for p in pal.policies):
        from gracenav.policies import RegulatorOptions, push_lean_table

        pushes = opts.regulator or RegulatorOptions()  # the push table capture was built with
        leans = push_lean_table(pal.gains, pushes.push_impulses, pushes.push_times, params=plant)
    for pol in pal.policies:
        if pol.capture:  # as built: push leans and the capture family's boundary points
            regulator = pol.primitive.name == REGULATOR_NAME
            fam = opts.regulator if regulator else opts.braking
            points = fam.boundary_points if fam is not None else None
            rep = verify_placements(
                pol, opts, params=plant, push_leans=leans, boundary_points=points
            )
        else:
            rep = verify_placements(pol, opts, params=plant)
        if not rep.passed:
            failed.append(pol.name)
        elif pol.starts_from_still_band:
            # As built: also from the corners of the still band.
            from gracenav.policies.catches import verify_still_start

            if not verify_still_start(pol, opts, params=plant).starts_from_still_band:
                failed.append(f"{pol.name} (still band)")
    placed = (*pal.catches, *pal.shifts)
    if placed:
        from gracenav.policies import RegulatorOptions, push_lean_table
        from gracenav.policies.catches import reverify

        pushes = opts.regulator or RegulatorOptions()
        table = push_lean_table(pal.gains, pushes.push_impulses, pushes.push_times, params=plant)
        for pol in placed:
            if not reverify(pol, opts, table, params=plant).passed:
                failed.append(pol.name)
    dt = time.perf_counter() - t0
    total = len(pal) + len(placed)
    still = sum(p.starts_from_still_band for p in pal.policies)
    if failed:
        print(f"{len(failed)} of {total} policies FAILED verification: {', '.join(failed)}")
        return 1
    print(
        f"all {len(pal)} policies verified at 0° and 90° ({still} from the still band too), "
        f"and {len(pal.catches)} catches and {len(pal.shifts)} shifts as built, in {dt:.1f} s"
    )
    if args.switches:
        jumps = switch_torque_jumps(pal.policies)
        worst = max(jumps, key=lambda j: j.jump)
        print(
            f"{len(jumps)} graceful switches simulated: largest commanded torque jump "
            f"{worst.jump:.4f} N m ({worst.first} -> {worst.second} rotated "
            f"{90 * worst.rotation}°); largest tick-to-tick change elsewhere "
            f"{max(j.largest_other_step for j in jumps):.3f} N m"
        )
    return 0


def run_show(args: argparse.Namespace) -> int:
    """Run ``gracenav palette show``."""
    from gracenav.library import DEFAULT_DESIGN_PUSH
    from gracenav.library.push_fans import FAN_FLOOR, fastest_flat_speed
    from gracenav.palette import PaletteLimits, load_palette

    pal = load_palette(args.file)
    print(_table(pal))
    print(
        f"{len(pal)} policies ({len(pal.base_policies)} primitives and their larger-domain "
        f"variants), d = {pal.d} m, key {pal.key[:12]}"
    )
    print(PaletteLimits.of(pal).describe(pal.params.torque_limit))
    if pal.gains.friction_compensation:
        at = "predicted mid-period" if pal.gains.friction_midpoint else "measured"
        print(f"controller: friction fed forward at the {at} ball rate")
    else:
        print("controller: no friction feed-forward")
    fastest = fastest_flat_speed(pal)
    applies = "so it applies" if fastest > FAN_FLOOR else "so it changes no library"
    print(
        f"design push (planner.design_push, default {DEFAULT_DESIGN_PUSH:g} N s): kept room "
        f"where a reference's flat output exceeds {FAN_FLOOR:g} m/s; this palette's reach "
        f"{fastest:.3f} m/s, {applies}"
    )
    checked = [p for p in pal.policies if p.still_report is not None]
    print(
        f"still band: {sum(p.starts_from_still_band for p in checked)} of the {len(checked)} "
        "policies that start at rest verified from it too (a hold may hand over to them "
        "before its end)"
    )
    return 0
