"""A scenario's outputs: summary.json, trajectory.csv, events.csv and figures, written
as a unit."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from gracenav._util.io import atomic_write_text
from gracenav.scenarios.runs import ScenarioResult, _json_value

__all__ = ["summary_dict", "write_outputs"]


def summary_dict(result: ScenarioResult) -> dict[str, Any]:
    """The content of ``summary.json`` (strict JSON: no NaN, None where not applicable)."""
    sc = result.scenario
    return {
        "scenario": sc.name,
        "source": sc.source,
        "task": sc.kind,
        "plant": sc.plant,
        "plant_param_factors": dict(sc.plant_factors),
        "plant_params": None if result.plant_params is None else result.plant_params.to_dict(),
        "library_size": result.library_size,
        "library_spacing_m": None if result.library is None else float(result.library.spacing),
        "library_region": _region(result),
        "speed_clearance_s": sc.speed_clearance,
        "design_push_ns": sc.design_push,
        "graph_edges": result.graph_edges,
        "coverage": _json_value(result.coverage),
        "library_and_graph_s": result.library_seconds,
        "runs": [r.to_dict() for r in result.runs],
    }


def _region(result: ScenarioResult) -> dict[str, Any] | None:
    """Where the library was built: the whole map or the task's region, with its bounds
    (m); None without a library (the decoupled baseline)."""
    if result.library is None:
        return None
    lib_map = result.library.world_map
    (x0, y0), (x1, y1) = lib_map.bounds
    return {
        "kind": "map" if lib_map is result.world_map else "task",
        "bounds_m": [[x0, y0], [x1, y1]],
    }


def write_outputs(result: ScenarioResult, out: str | Path, *, animation: bool = True) -> list[Path]:
    """Write summary.json, trajectory.csv, events.csv, figures and an animation into ``out``.

    Each file is written atomically; to publish the set as a unit, write into a
    staging directory (the ``gracenav run`` command does). Returns the written paths.
    """
    from gracenav.plotting.navigation import animate_episode, plot_lean, plot_paths

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    path = out / "summary.json"
    atomic_write_text(path, json.dumps(summary_dict(result), indent=2, allow_nan=False) + "\n")
    written.append(path)
    header = "run,t,x,y,xdot,ydot,lean_x,lean_y,tau_x,tau_y,ref_x,ref_y,policy"
    fmt = ["%d", "%.6f", "%.6f", "%.6f", "%.6f", "%.6f", "%.6e", "%.6e", "%.5f", "%.5f"]
    fmt += ["%.6f", "%.6f", "%d"]
    table = io.StringIO()
    for k, ep in enumerate(result.episodes):
        columns = (
            np.full(ep.time.size, k),
            ep.time,
            ep.position_state,
            ep.lean,
            ep.inputs,
            ep.reference[:, :2],
            ep.policy,
        )
        rows = np.column_stack(columns)
        np.savetxt(table, rows, fmt=fmt, delimiter=",")
    path = out / "trajectory.csv"
    atomic_write_text(path, header + "\n" + table.getvalue())
    written.append(path)

    def name(i: int) -> str:
        return result.library.policy(i).name if i >= 0 else ""

    events = io.StringIO()
    writer = csv.writer(events, lineterminator="\n")
    writer.writerow(["run", "time", "from", "to", "from_name", "to_name", "reason", "latency_ms"])
    for k, ep in enumerate(result.episodes):
        lines = [
            (
                e.time,
                0,
                [
                    k,
                    f"{e.time:.6f}",
                    e.from_policy,
                    e.to_policy,
                    name(e.from_policy),
                    name(e.to_policy),
                    e.reason.value,
                    "",
                ],
            )
            for e in ep.events
        ]
        lines += [  # replans: reason replan:<why>, and the wall time of the repair
            (
                rp.time,
                1,
                [
                    k,
                    f"{rp.time:.6f}",
                    "",
                    "",
                    "",
                    "",
                    f"replan:{rp.reason}",
                    f"{1000 * rp.latency_s:.3f}",
                ],
            )
            for rp in getattr(ep, "replans", ())
        ]
        writer.writerows(line for _, _, line in sorted(lines, key=lambda v: (v[0], v[1])))
    path = out / "events.csv"
    atomic_write_text(path, events.getvalue())
    written.append(path)
    written.append(plot_paths(result, out / "paths.png"))
    written.append(plot_lean(result, out / "lean.png"))
    if animation:
        written.append(animate_episode(result, 0, out / "animation.gif"))
    return written
