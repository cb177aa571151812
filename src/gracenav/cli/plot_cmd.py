"""``gracenav plot ...``: the paper's figures."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from gracenav.cli._common import (
    add_palette_argument,
    add_params_argument,
    check_figure_path,
    check_plant,
    number,
    save_figure,
)
from gracenav.errors import ConfigError

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``plot`` command group."""
    p = sub.add_parser(
        "plot",
        help="draw the paper's figures",
        description=(
            "Draw figures (angles in degrees, lengths in metres); the format follows the "
            "--out suffix (.png, .pdf, .svg, ...)."
        ),
    )
    s = p.add_subparsers(dest="what", metavar="WHAT", parser_class=type(p))
    s.required = True
    pr = s.add_parser(
        "primitives",
        help="XY paths of the motion primitive set Σ(d) (paper Fig. 3(a))",
        description="Plan (or load from the cache) the primitive set and draw its XY paths.",
    )
    pr.add_argument(
        "--d",
        type=number(minimum=0.1, maximum=2.0, unit="m"),
        default=0.5,
        help="distance parameter d (m, default 0.5, in [0.1, 2])",
    )
    pr.add_argument(
        "--reference",
        choices=("limited", "nonic"),
        default="limited",
        help=(
            "the maneuvers' references: those of the default palette (limited, the ball's "
            "jerk within 3 m/s³; default) or the nonics of the nonic palette"
        ),
    )
    pr.add_argument("--out", type=Path, required=True, help="output PNG file")
    pr.set_defaults(func=run_primitives)
    dm = s.add_parser(
        "domain",
        help="XY projection of one policy's S, D'(t) and G (paper Fig. 3(b))",
        description="Draw the XY projection of the start domain S, the outer domain D'(t) "
        "over the primitive, and the goal domain G of the named palette policy.",
    )
    dm.add_argument("name", help="policy name (see `gracenav palette show`)")
    add_palette_argument(dm, "--file")
    dm.add_argument("--out", type=Path, required=True, help="output PNG file")
    dm.set_defaults(func=run_domain)
    lb = s.add_parser(
        "library",
        help="the policy library on a map: start domains (paper Fig. 4 style)",
        description="Instantiate the palette on MAP (inline-geometry YAML/JSON or a ROS "
        "map_server YAML) and draw the map, obstacles and the library's start domains; "
        "--coverage adds where sampled position states lie in no start domain, the "
        "largest domain scale placed at each point, and where they are covered once "
        "captures (catches placed at the state, then shifts onto a rest trim) count.",
    )
    lb.add_argument("map", type=Path, help="map file")
    lb.add_argument("--out", type=Path, required=True, help="output PNG file")
    lb.add_argument(
        "--coverage",
        action="store_true",
        help="add the coverage panels (start domains alone, domain scale, with captures; "
        "the last plans a capture for every sampled state no start domain holds)",
    )
    lb.add_argument(
        "--footprint",
        type=number(minimum=0.0, maximum=5.0, unit="m"),
        default=0.2,
        help="robot footprint radius (m, default 0.2)",
    )
    lb.add_argument(
        "--max-halvings",
        type=number(integer=True, minimum=0, maximum=20),
        default=None,
        help="coverage refinement limit (default: the most, up to 1, whose estimated "
        "memory fits --memory-limit-gib)",
    )
    # The scenarios' defaults (gracenav.scenarios.DEFAULT_MEMORY_LIMIT_GIB,
    # MAX_MEMORY_LIMIT_GIB), written out: importing them would load the library at --help.
    lb.add_argument(
        "--memory-limit-gib",
        type=number(positive=True, maximum=1024.0, unit="GiB"),
        default=2.0,
        help="memory budget (GiB, default 2): a library whose estimated peak would exceed "
        "it is refused before it is built",
    )
    lb.set_defaults(func=run_library)
    rc = s.add_parser(
        "recovery",
        help="disturbance recovery of one scenario run (paper Fig. 7 style)",
        description="Run one start of SCENARIO (which must have a push or a drag under "
        "'disturbances') and draw the map, the path, each push as an arrow from where it "
        "acted (length proportional to the impulse, labelled in N s) and each drag as the "
        "hand's displacement, the start domains of the policies executed from the "
        "disturbance until the motion is graceful again, the outer domains D'(t) the state "
        "left, and the hybrid controller's switches (graceful: dots, forced: crosses).",
    )
    rc.add_argument("scenario", type=Path, help="scenario YAML file")
    rc.add_argument("--out", type=Path, required=True, help="output PNG file")
    rc.add_argument(
        "--run",
        type=number(integer=True, minimum=1),
        default=1,
        help="which start of the scenario to run and draw (1-based, default 1)",
    )
    add_params_argument(rc)
    add_palette_argument(rc)
    rc.set_defaults(func=run_recovery)


def run_primitives(args: argparse.Namespace) -> int:
    """Run ``gracenav plot primitives``."""
    from gracenav.palette import PaletteLimits
    from gracenav.plotting.primitives import plot_primitives
    from gracenav.primitives import PrimitiveSetOptions, primitive_set

    out = check_figure_path(args.out)
    if args.reference == "limited":
        options = PaletteLimits().primitive_options()
    else:
        options = PrimitiveSetOptions(reference="nonic")
    prims = primitive_set(d=args.d, options=options)
    save_figure(out, lambda tmp: plot_primitives(prims, tmp))
    print(f"wrote {out}")
    return 0


def run_domain(args: argparse.Namespace) -> int:
    """Run ``gracenav plot domain``."""
    from gracenav.palette import load_palette
    from gracenav.plotting.domains import plot_domain

    out = check_figure_path(args.out)
    pal = load_palette(args.file)
    policy = pal[args.name]
    save_figure(out, lambda tmp: plot_domain(policy, tmp))
    print(f"wrote {out}")
    return 0


def run_library(args: argparse.Namespace) -> int:
    """Run ``gracenav plot library``."""
    from gracenav.library import build_library
    from gracenav.palette import load_palette
    from gracenav.plotting.library import plot_library
    from gracenav.scenarios import choose_halvings
    from gracenav.world import load_map

    out = check_figure_path(args.out)
    palette = load_palette()
    world_map = load_map(args.map)
    halvings = choose_halvings(
        world_map,
        palette,
        max_halvings=args.max_halvings,
        memory_limit=args.memory_limit_gib * 2**30,
        footprint_radius=args.footprint,
        source=str(args.map),
        keys=("--max-halvings", "--memory-limit-gib"),
    ).halvings
    lib = build_library(
        palette,
        world_map,
        footprint_radius=args.footprint,
        max_halvings=halvings,
        memory_limit=None,  # checked above, against the command's budget
    )
    save_figure(out, lambda tmp: plot_library(lib, tmp, coverage=args.coverage, progress=True))
    print(f"{len(lib)} library policies, coverage {100 * lib.coverage:.1f} %; wrote {out}")
    return 0


def run_recovery(args: argparse.Namespace) -> int:
    """Run ``gracenav plot recovery``."""
    import dataclasses

    from gracenav.cli._common import load_params
    from gracenav.palette import load_palette
    from gracenav.plotting.recovery import plot_recovery
    from gracenav.scenarios import load_scenario, run_scenario

    out = check_figure_path(args.out)
    sc = load_scenario(args.scenario)
    if not sc.disturbances:
        raise ConfigError(
            f"{sc.source}: the scenario has no disturbances; a recovery figure needs a push "
            "or a drag under 'disturbances'"
        )
    if args.run > len(sc.starts):
        raise ConfigError(
            f"--run {args.run}: {sc.source} has {len(sc.starts)} start(s); use --run 1"
            + (f" to {len(sc.starts)}" if len(sc.starts) > 1 else "")
        )
    check_plant(sc.plant, f"{sc.source}: simulation.plant")
    params = load_params(args)
    palette = load_palette(args.palette)
    one = dataclasses.replace(sc, starts=sc.starts[args.run - 1 : args.run])
    result = run_scenario(one, palette=palette, params=params)
    summary = result.runs[0]
    try:
        save_figure(out, lambda tmp: plot_recovery(result, tmp))
    except ValueError as exc:  # no disturbance acted before the run ended
        raise ConfigError(f"{sc.source}: {exc}") from None
    print(
        f"run {args.run}: {summary.outcome} at {summary.time_s:.2f} s, switches "
        f"{summary.switches} ({summary.non_graceful_switches} forced); wrote {out}"
    )
    return 0
