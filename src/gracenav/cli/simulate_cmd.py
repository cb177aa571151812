"""``gracenav simulate ...``: closed-loop simulations of the controllers."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.errors import ConfigError

__all__ = ["register"]


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


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
            "tau_y; SI units, lean in rad) and balance.png (position and lean against time)."
        ),
    )
    b.add_argument(
        "--lean-deg",
        type=_finite,
        default=5.0,
        help="initial lean in both planes (degrees, default 5)",
    )
    b.add_argument("--duration", type=_positive, default=6.0, help="simulated time (s, default 6)")
    b.add_argument(
        "--push",
        type=_finite,
        nargs=2,
        metavar=("IX", "IY"),
        default=None,
        help="also push the body at t = 1 s with this impulse (N s)",
    )
    b.add_argument(
        "--plant", choices=("model3d", "mujoco"), default="model3d", help="simulated plant"
    )
    b.add_argument("--out", type=Path, required=True, help="output directory")
    b.set_defaults(func=run_balance)


def run_balance(args: argparse.Namespace) -> int:
    """Run ``gracenav simulate balance``."""
    from gracenav._io import atomic_write_text
    from gracenav.params import BallbotParams
    from gracenav.plotting.timeseries import plot_balance
    from gracenav.simulate import Disturbance, Push, Reference, simulate, state_from_position

    if abs(args.lean_deg) >= 30.0:
        raise ConfigError(f"--lean-deg must be within ±30 degrees, got {args.lean_deg}")
    params = BallbotParams()
    lean = np.deg2rad([args.lean_deg, args.lean_deg])
    x0 = state_from_position(np.zeros(4), params.ball_radius, lean=lean)
    disturbances: list[Disturbance] = []
    if args.push is not None:
        if args.duration <= 1.0:
            raise ConfigError("--push needs --duration longer than 1 s")
        disturbances.append(Push(time=1.0, impulse=(args.push[0], args.push[1])))
    result = simulate(
        x0,
        Reference.hold((0.0, 0.0), args.duration, params=params),
        plant=args.plant,
        disturbances=disturbances,
    )
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    p = result.position_state
    table = np.column_stack([result.time, p, result.lean, result.inputs])
    header = "t,x,y,xdot,ydot,lean_x,lean_y,tau_x,tau_y"
    lines = [header] + [",".join(f"{v:.9g}" for v in row) for row in table]
    atomic_write_text(out / "trajectory.csv", "\n".join(lines) + "\n")
    plot_balance(
        result.time,
        p[:, :2],
        result.lean,
        out / "balance.png",
        title=f"Recovery from {args.lean_deg:g}° lean ({args.plant})",
    )
    final = float(np.hypot(*p[-1, :2]))
    print(
        f"max lean {np.rad2deg(result.max_lean):.2f}°, max torque {result.max_torque:.1f} N m, "
        f"final distance from start {final * 1000:.1f} mm; wrote {out / 'trajectory.csv'} "
        f"and {out / 'balance.png'}"
    )
    return 0
