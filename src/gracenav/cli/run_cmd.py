"""``gracenav run`` and ``gracenav demo``: navigation scenarios end to end."""

from __future__ import annotations

import argparse
import sys
from importlib import resources
from pathlib import Path
from typing import Any

from gracenav.cli._common import add_palette_argument, add_params_argument, check_plant
from gracenav.sim.plant import PLANT_KINDS, PlantKind

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``run`` and ``demo`` commands."""
    r = sub.add_parser(
        "run",
        help="run a navigation scenario (YAML) and write results and figures",
        description=(
            "Build the motion policy library on the scenario's map, plan single-goal trees "
            "and execute the task with the hybrid controller on the simulated robot. Writes "
            "DIR/summary.json (per run: start, reached_goal, outcome, stop_reason, contact, "
            "contact_time_s, time_s, path_length_m, final_error_m, max_lean_deg, "
            "max_torque_nm, max_jerk_mps3, p95_jerk_mps3, switches, non_graceful_switches, "
            "min_clearance_m, ...), DIR/trajectory.csv, "
            "DIR/events.csv (the switch log), DIR/paths.png, DIR/lean.png and "
            "DIR/animation.gif. The files are written together: DIR is replaced only when "
            "all are complete, and a second run into the same DIR is refused. A run whose "
            "robot leans beyond 20° stops as fallen (stop_reason fell, exit status 1); a "
            "run whose footprint touched an obstacle or the map edge (the simulated robot "
            "passes through them) has outcome contact, does not count as reaching its goal "
            "and the command exits with status 1. "
            "The scenario's simulation.plant_params factors scale the simulated robot's "
            "parameters (the --params file's if given). "
            "The scenario format is described in docs/scenarios.md."
        ),
    )
    r.add_argument("scenario", type=Path, help="scenario YAML file")
    r.add_argument("--out", type=Path, required=True, help="output directory")
    r.add_argument(
        "--plant",
        choices=PLANT_KINDS,
        default=None,
        help="override the scenario's simulated plant",
    )
    r.add_argument("--no-animation", action="store_true", help="skip the GIF (faster)")
    add_log_argument(r)
    add_params_argument(r)
    add_palette_argument(r)
    r.set_defaults(func=run_run)
    d = sub.add_parser(
        "demo",
        help="run the paper's Fig. 5 point-point scenario into ./out/demo",
        description=(
            "Run the shipped scenario of the paper's Fig. 5 (goal (2 m, 2 m) at rest from "
            "four starts around two obstacles) and write its results and figures to "
            "./out/demo (or --out)."
        ),
    )
    d.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    d.add_argument("--no-animation", action="store_true", help="skip the GIF (faster)")
    add_log_argument(d)
    add_params_argument(d)
    add_palette_argument(d)
    d.set_defaults(func=run_demo)


def add_log_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--log FILE.mcap`` (the runs as an MCAP file Foxglove opens)."""
    parser.add_argument(
        "--log",
        type=Path,
        default=None,
        metavar="FILE.mcap",
        help=(
            "also write the runs to an MCAP file that Foxglove opens: the map, the robot "
            "(map -> base_link), its state, lean, torque and reference at 128 Hz, each "
            "policy's domains while it runs, events and pushes (see docs/ros.md); needs "
            "pip install 'gracenav[log]'"
        ),
    )


def check_log_path(path: Path | None) -> None:
    """Refuse a ``--log`` that cannot be written before any work (suffix, folder, the
    optional dependency)."""
    import importlib.util

    from gracenav.errors import ConfigError, OutputError

    if path is None:
        return
    if path.suffix.lower() == ".rrd":
        raise OutputError(f"--log {path}: Rerun files are not written; write an .mcap file instead")
    if path.suffix.lower() != ".mcap":
        raise OutputError(f"--log {path}: the file name must end in .mcap")
    if path.is_dir():
        raise OutputError(f"--log {path} is a directory; give a file name such as run.mcap")
    if importlib.util.find_spec("mcap") is None:
        raise ConfigError("--log needs the optional dependency mcap: pip install 'gracenav[log]'")


def _execute(
    scenario_path: Path,
    out: Path,
    plant: PlantKind | None,
    animation: bool,
    params_path: Path | None,
    palette_path: str | Path | None = None,
    log_path: Path | None = None,
) -> int:
    import dataclasses

    from gracenav._util.io import OutputDir
    from gracenav._util.progress import Progress
    from gracenav.params import BallbotParams
    from gracenav.scenarios import load_scenario, run_scenario, write_outputs

    check_log_path(log_path)
    sc = load_scenario(scenario_path)
    if plant is not None:
        sc = dataclasses.replace(sc, plant=plant)
    check_plant(sc.plant, "--plant" if plant is not None else f"{sc.source}: simulation.plant")
    params = None if params_path is None else BallbotParams.load_overrides(params_path)
    from gracenav.palette import load_palette

    palette = load_palette(palette_path)  # before the output directory is touched
    with OutputDir(out) as staging:
        with Progress(len(sc.starts), f"{sc.name}: library") as bar:

            def progress(done: int, n: int) -> None:
                bar.set_label(f"{sc.name}: runs")
                bar.update(1)

            result = run_scenario(sc, palette=palette, params=params, progress=progress)
            bar.set_label(f"{sc.name}: writing")
            written = write_outputs(result, staging.staging, animation=animation)
            if log_path is not None:
                from gracenav.scenarios.mcap_log import write_scenario_log

                bar.set_label(f"{sc.name}: log")
                write_scenario_log(result, log_path)
    written = [out / p.name for p in written]
    if log_path is not None:
        written.append(log_path)
    spacing = "" if result.library is None else f" (lattice spacing {result.library.spacing:g} m)"
    if result.library is not None and result.library.world_map is not result.world_map:
        (x0, y0), (x1, y1) = result.library.world_map.bounds
        spacing += f" on the task's region {x1 - x0:g} m × {y1 - y0:g} m"
    print(
        f"library: {result.library_size} policies{spacing}, {result.graph_edges} edges, "
        f"coverage {100 * result.coverage:.1f} %, built in {1000 * result.library_seconds:.0f} ms"
    )
    fell = []
    contact = []
    for k, run in enumerate(result.runs):
        if run.reached_goal:
            state = f"reached goal in {run.time_s:.2f} s"
        else:
            state = f"stopped ({run.stop_reason}) at {run.time_s:.2f} s"
        if run.contact:
            state = f"touched an obstacle at t = {run.contact_time_s:.2f} s, {state}"
        err = "" if run.final_error_m is None else f", error {run.final_error_m * 1000:.1f} mm"
        start = ", ".join(f"{v:g}" for v in run.start[:2])
        print(
            f"run {k + 1} from ({start}): {state}{err}, "
            f"max lean {run.max_lean_deg:.2f}°, jerk max {run.max_jerk_mps3:.1f} / "
            f"p95 {run.p95_jerk_mps3:.1f} m/s³, switches {run.switches} "
            f"({run.non_graceful_switches} non-graceful)"
        )
        if run.stop_reason == "fell":
            fell.append(f"run {k + 1} at t = {run.time_s:.2f} s")
        if run.contact:
            contact.append(
                f"run {k + 1} at t = {run.contact_time_s:.2f} s "
                f"(min clearance {1000 * run.min_clearance_m:.0f} mm)"
            )
    print(f"wrote {', '.join(str(p) for p in written)}")
    if fell:
        print(
            f"gracenav: fell: the robot fell over (lean beyond {_fall_limit_deg():g}°) in "
            f"{'; '.join(fell)}",
            file=sys.stderr,
        )
    if contact:
        print(
            "gracenav: contact: the robot's footprint touched an obstacle or the map edge "
            f"in {'; '.join(contact)}; such a run does not count as reaching its goal "
            "(outcome contact in summary.json)",
            file=sys.stderr,
        )
    return 0 if all(r.reached_goal for r in result.runs) else 1


def _fall_limit_deg() -> float:
    import math

    from gracenav.sim import DEFAULT_FALL_LEAN

    return math.degrees(DEFAULT_FALL_LEAN)


def run_run(args: argparse.Namespace) -> int:
    """Run ``gracenav run``."""
    return _execute(
        args.scenario,
        args.out,
        args.plant,
        not args.no_animation,
        args.params,
        args.palette,
        args.log,
    )


def run_demo(args: argparse.Namespace) -> int:
    """Run ``gracenav demo``."""
    path = Path(
        str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml")
    )
    return _execute(
        path, args.out, None, not args.no_animation, args.params, args.palette, args.log
    )
