"""``gracenav plot ...``: the paper's figures."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``plot`` command group."""
    p = sub.add_parser(
        "plot",
        help="draw the paper's figures",
        description="Draw figures as PNG files (angles in degrees, lengths in metres).",
    )
    s = p.add_subparsers(dest="what", metavar="WHAT", parser_class=type(p))
    s.required = True
    pr = s.add_parser(
        "primitives",
        help="XY paths of the motion primitive set Σ(d) (paper Fig. 3(a))",
        description="Plan (or load from the cache) the primitive set and draw its XY paths.",
    )
    pr.add_argument("--d", type=float, default=0.5, help="distance parameter d (m, default 0.5)")
    pr.add_argument("--out", type=Path, required=True, help="output PNG file")
    pr.set_defaults(func=run_primitives)
    dm = s.add_parser(
        "domain",
        help="XY projection of one policy's S, D'(t) and G (paper Fig. 3(b))",
        description="Draw the XY projection of the start domain S, the outer domain D'(t) "
        "over the primitive, and the goal domain G of the named palette policy.",
    )
    dm.add_argument("name", help="policy name (see `gracenav palette show`)")
    dm.add_argument("--file", type=Path, default=None, help="palette file (default: shipped)")
    dm.add_argument("--out", type=Path, required=True, help="output PNG file")
    dm.set_defaults(func=run_domain)
    lb = s.add_parser(
        "library",
        help="the policy library on a map: start domains (paper Fig. 4 style)",
        description="Instantiate the palette on MAP (inline-geometry YAML/JSON or a ROS "
        "map_server YAML) and draw the map, obstacles and the library's start domains; "
        "--coverage shows where sampled position states are not covered.",
    )
    lb.add_argument("map", type=Path, help="map file")
    lb.add_argument("--out", type=Path, required=True, help="output PNG file")
    lb.add_argument("--coverage", action="store_true", help="draw the coverage view")
    lb.add_argument(
        "--footprint", type=float, default=0.2, help="robot footprint radius (m, default 0.2)"
    )
    lb.add_argument(
        "--max-halvings", type=int, default=1, help="coverage refinement limit (default 1)"
    )
    lb.set_defaults(func=run_library)


def run_primitives(args: argparse.Namespace) -> int:
    """Run ``gracenav plot primitives``."""
    from gracenav.plotting.primitives import plot_primitives
    from gracenav.primitives import primitive_set

    out = plot_primitives(primitive_set(d=args.d), args.out)
    print(f"wrote {out}")
    return 0


def run_domain(args: argparse.Namespace) -> int:
    """Run ``gracenav plot domain``."""
    from gracenav.palette import load_palette
    from gracenav.plotting.domains import plot_domain

    pal = load_palette(args.file)
    out = plot_domain(pal[args.name], args.out)
    print(f"wrote {out}")
    return 0


def run_library(args: argparse.Namespace) -> int:
    """Run ``gracenav plot library``."""
    from gracenav.library import build_library
    from gracenav.palette import load_palette
    from gracenav.plotting.library import plot_library
    from gracenav.world import load_map

    lib = build_library(
        load_palette(),
        load_map(args.map),
        footprint_radius=args.footprint,
        max_halvings=args.max_halvings,
    )
    out = plot_library(lib, args.out, coverage=args.coverage)
    print(f"{len(lib)} library policies, coverage {100 * lib.coverage:.1f} %; wrote {out}")
    return 0
