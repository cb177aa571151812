"""``gracenav simulate ...``: closed-loop simulations of the controllers."""

from __future__ import annotations

import argparse
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.cli._common import add_params_argument, check_plant, load_params, number
from gracenav.errors import ConfigError
from gracenav.sim.plant import PLANT_KINDS

__all__ = ["register"]


MAX_DURATION_S = 600.0
"""Longest ``simulate balance`` run (s): 614 k control ticks, ≈50 MB of history."""
MAX_LEAN_DEG = 20.0
"""Initial leans must be below the fall limit (20°). Measured on the 3D model (20 s of
station keeping): the controller recovers from up to 20.4° in both planes."""
MAX_PUSH_NS = 80.0
"""Largest push impulse magnitude (N s). Measured on the 3D model from upright (bisection
over 8 directions, 20 s of station keeping): the robot recovers from 80.5 N s along an
axis and 113.8 N s along a diagonal, and falls beyond."""


def register(sub: Any) -> None:
    """Add the ``simulate`` command group to the sub-parser collection ``sub``."""
    p = sub.add_parser(
        "simulate",
        help="simulate the closed-loop ballbot",
        description="Closed-loop simulations of the balancing and tracking controllers.",
    )
    s = p.add_subparsers(dest="what", metavar="WHAT", parser_class=type(p))
    s.required = True
    b = s.add_parser(
        "balance",
        help="recover from an initial lean and keep station",
        description=(
            "Start the 3D ballbot at rest with the body leaning by --lean-deg in both planes "
            "and let the balancing and tracking controllers recover and hold the start "
            "position. Writes trajectory.csv (t, x, y, xdot, ydot, lean_x, lean_y, tau_x, "
            "tau_y; SI units, lean in rad) and balance.png (position and lean against time). "
            "A lean beyond 20° in either plane is a fall: the simulation stops there and "
            "the command exits with status 1."
        ),
    )
    b.add_argument(
        "--lean-deg",
        type=number(),
        default=5.0,
        help=f"initial lean in both planes (degrees, default 5; |lean| < {MAX_LEAN_DEG:g})",
    )
    b.add_argument(
        "--duration",
        type=number(positive=True, maximum=MAX_DURATION_S, unit="s"),
        default=6.0,
        help=f"simulated time (s, default 6, at most {MAX_DURATION_S:g})",
    )
    b.add_argument(
        "--push",
        type=number(),
        nargs=2,
        metavar=("IX", "IY"),
        default=None,
        help=f"also push the body at t = 1 s with this impulse (N s, magnitude <= {MAX_PUSH_NS:g})",
    )
    b.add_argument("--plant", choices=PLANT_KINDS, default="model3d", help="simulated plant")
    b.add_argument("--out", type=Path, required=True, help="output directory")
    add_params_argument(b)
    b.set_defaults(func=run_balance)


def run_balance(args: argparse.Namespace) -> int:
    """Run ``gracenav simulate balance``."""
    import sys

    from gracenav._util.io import OutputDir, atomic_write_text
    from gracenav.control import design_gains
    from gracenav.params import BallbotParams
    from gracenav.plotting.timeseries import plot_balance
    from gracenav.sim import (
        Disturbance,
        Push,
        Reference,
        SimulationOptions,
        StopReason,
        simulate,
        state_from_position,
    )

    if not abs(args.lean_deg) < MAX_LEAN_DEG:
        raise ConfigError(
            f"--lean-deg must be within ±{MAX_LEAN_DEG:g} degrees (beyond, the robot has "
            f"fallen), got {args.lean_deg:g}"
        )
    disturbances: list[Disturbance] = []
    if args.push is not None:
        magnitude = math.hypot(*args.push)
        if magnitude > MAX_PUSH_NS:
            raise ConfigError(
                f"--push {args.push[0]:g} {args.push[1]:g} is {magnitude:.3g} N s; the robot "
                f"recovers from pushes up to {MAX_PUSH_NS:g} N s (measured), so at most that"
            )
        if args.duration <= 1.0:
            raise ConfigError("--push needs --duration longer than 1 s (the push is at t = 1 s)")
        disturbances.append(Push(time=1.0, impulse=(args.push[0], args.push[1])))
    check_plant(args.plant)
    loaded = load_params(args)
    params = loaded if loaded is not None else BallbotParams()
    options = SimulationOptions()
    with OutputDir(args.out) as out:
        lean = np.deg2rad([args.lean_deg, args.lean_deg])
        x0 = state_from_position(np.zeros(4), params.ball_radius, lean=lean)
        result = simulate(
            x0,
            Reference.hold((0.0, 0.0), args.duration, params=params),
            design_gains(),  # the nominal controller, also on a --params robot
            params=params,
            plant=args.plant,
            disturbances=disturbances,
            options=options,
        )
        p = result.position_state
        table = np.column_stack([result.time, p, result.lean, result.inputs])
        text = io.StringIO()
        np.savetxt(text, table, fmt="%.9g", delimiter=",")
        header = "t,x,y,xdot,ydot,lean_x,lean_y,tau_x,tau_y\n"
        atomic_write_text(out.staging / "trajectory.csv", header + text.getvalue())
        plot_balance(
            result.time,
            p[:, :2],
            result.lean,
            out.staging / "balance.png",
            title=f"Recovery from {args.lean_deg:g}° lean ({args.plant})",
        )
    dest: Path = args.out
    final = float(np.hypot(*p[-1, :2]))
    distance = f"{final * 1000:.1f} mm" if math.isfinite(final) else "undefined"
    print(
        f"max lean {np.rad2deg(result.max_lean):.2f}°, max torque {result.max_torque:.1f} N m, "
        f"final distance from start {distance}; wrote {dest / 'trajectory.csv'} "
        f"and {dest / 'balance.png'}"
    )
    if result.stop_reason is StopReason.FELL:
        why = (
            f"lean beyond {math.degrees(options.fall_lean):g}°"
            if np.all(np.isfinite(result.states[-1]))
            else "the simulation diverged: are the --params physical?"
        )
        print(
            f"gracenav: fell: the robot fell over at t = {result.time[-1]:.3f} s ({why})",
            file=sys.stderr,
        )
        return 1
    return 0
