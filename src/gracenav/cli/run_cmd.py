"""``gracenav run`` and ``gracenav demo``: navigation scenarios end to end."""

from __future__ import annotations

import argparse
import sys
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["register"]


def register(sub: Any) -> None:
    """Add the ``run`` and ``demo`` commands."""
    r = sub.add_parser(
        "run",
        help="run a navigation scenario (YAML) and write results and figures",
        description=(
            "Build the motion policy library on the scenario's map, plan single-goal trees "
            "and execute the task with the hybrid controller on the simulated robot. Writes "
            "DIR/summary.json (per run: start, reached_goal, time_s, path_length_m, "
            "final_error_m, max_lean_deg, max_torque, max_jerk, switches, "
            "non_graceful_switches, min_clearance_m, stop_reason), DIR/trajectory.csv, "
            "DIR/events.csv (the switch log), DIR/paths.png, DIR/lean.png and "
            "DIR/animation.gif. The scenario format is described in README.md."
        ),
    )
    r.add_argument("scenario", type=Path, help="scenario YAML file")
    r.add_argument("--out", type=Path, required=True, help="output directory")
    r.add_argument(
        "--plant",
        choices=("model3d", "mujoco"),
        default=None,
        help="override the scenario's simulated plant",
    )
    r.add_argument("--no-animation", action="store_true", help="skip the GIF (faster)")
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
    d.set_defaults(func=run_demo)


def _execute(scenario_path: Path, out: Path, plant: str | None, animation: bool) -> int:
    import dataclasses

    from gracenav.scenarios import load_scenario, run_scenario, write_outputs

    sc = load_scenario(scenario_path)
    if plant is not None:
        sc = dataclasses.replace(sc, plant=plant)  # type: ignore[arg-type]
    total = len(sc.starts)

    def progress(done: int, n: int) -> None:
        bar = "#" * done + "." * (n - done)
        print(f"\rrunning {sc.name}: [{bar}] {done}/{n}", end="", file=sys.stderr, flush=True)

    progress(0, total)
    result = run_scenario(sc, progress=progress)
    print(file=sys.stderr)
    written = write_outputs(result, out, animation=animation)
    print(
        f"library: {result.library_size} policies, {result.graph_edges} edges, coverage "
        f"{100 * result.coverage:.1f} %, built in {1000 * result.library_seconds:.0f} ms"
    )
    for k, run in enumerate(result.runs):
        state = "reached goal" if run.reached_goal else f"stopped ({run.stop_reason})"
        err = (
            ""
            if run.final_error_m != run.final_error_m
            else f", error {run.final_error_m * 1000:.1f} mm"
        )
        print(
            f"run {k + 1} from {run.start[:2]}: {state} in {run.time_s:.2f} s{err}, "
            f"max lean {run.max_lean_deg:.2f}°, switches {run.switches} "
            f"({run.non_graceful_switches} non-graceful)"
        )
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0 if all(r.reached_goal for r in result.runs) else 1


def run_run(args: argparse.Namespace) -> int:
    """Run ``gracenav run``."""
    return _execute(args.scenario, args.out, args.plant, not args.no_animation)


def run_demo(args: argparse.Namespace) -> int:
    """Run ``gracenav demo``."""
    path = Path(
        str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml")
    )
    return _execute(path, args.out, None, True)
