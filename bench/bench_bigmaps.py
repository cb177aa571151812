"""Big maps through ``gracenav run``: peak memory against the budget, and the time from
the start of the process to the first control command.

Two maps, generated with seeds and saved as ROS map_server files in a temporary folder:

* ``warehouse``: ``warehouse_map(30.0, 50.0, resolution=0.03, seed=1)``, 1667 × 1000
  cells;
* ``office``: ``office_map(100.0, resolution=0.05, seed=1)``, 2000 × 2000 cells.

Each gets a point-to-point scenario with default settings (no ``planner`` section: the
halvings are chosen within the 2 GiB memory budget) from a rest start to a rest goal
3–6 m away (seeded, clearance >= footprint + 0.5 m, connected for the footprint), run
with ``gracenav run SCENARIO.yaml --out DIR`` (figures and animation included) in its
own process. That process is this script with ``--child``: it times the stages (map,
checks and memory estimate, library, graph, the controller up to its first command)
by wrapping their functions, then calls the command line's ``main``. The peak is the
process's ``ru_maxrss`` (``os.wait4``), the figure ``/usr/bin/time -v`` reports as
"Maximum resident set size"; times are wall clock from just before the process is
started.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python bench/bench_bigmaps.py [--only office]
        [--memory-limit-gib 2] [--max-halvings N] [--profile 25] [--keep DIR]

``--profile N`` prints the N functions with the most cumulative time up to the first
command (cProfile, which slows the run down).
"""

from __future__ import annotations

import argparse
import json
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

CASES = ("warehouse", "office")
FOOT = 0.2  # m, the scenario default
_MARK = "BENCH_BIGMAPS "


def make_case(case: str, folder: Path, seed: int = 1) -> Path:
    """Generate the map of ``case``, save it as a ROS map and write a scenario with a
    seeded point-to-point task; return the scenario's path."""
    import numpy as np
    import yaml

    from gracenav.world import footprint_connected, office_map, save_ros_map, warehouse_map

    if case == "warehouse":
        world = warehouse_map(30.0, 50.0, resolution=0.03, seed=seed)
    else:
        world = office_map(100.0, resolution=0.05, seed=seed)
    save_ros_map(world, folder / f"{case}_map.yaml")
    rng = np.random.default_rng(seed)
    (x0, y0), (x1, y1) = world.bounds
    for _ in range(10_000):
        p = rng.uniform((x0, y0), (x1, y1))
        a, d = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(3.0, 6.0)
        pts = np.round(np.array([p, p + d * np.array([np.cos(a), np.sin(a)])]) / 0.5) * 0.5
        if np.any(pts < (x0, y0)) or np.any(pts > (x1, y1)):
            continue
        if np.any(world.clearance(pts) < FOOT + 0.5):
            continue
        if footprint_connected(world, pts[0], pts[1], FOOT):
            break
    else:  # pragma: no cover - the seeded maps have such pairs
        raise RuntimeError(f"no task found on the {case} map")
    start, goal = (pts[0].tolist(), pts[1].tolist())
    scenario = {
        "name": f"{case} point-to-point",
        "map": {"ros_map": f"{case}_map.yaml"},
        "task": {"kind": "point_to_point", "goal": [*goal, 0.0, 0.0], "starts": [[*start, 0, 0]]},
    }
    path = folder / f"{case}.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


def child(scenario: str, out: str, profile: int) -> int:
    """``gracenav run SCENARIO --out OUT`` with its stages timed (seconds since the
    parent's ``BENCH_T0``); the marks are printed as one JSON line on stderr."""
    t0 = float(os.environ["BENCH_T0"])
    marks: dict[str, Any] = {"python": time.time() - t0}
    prof = None
    if profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    import gracenav.library as library_mod
    import gracenav.planning.graph as graph_mod
    import gracenav.scenarios.run as run_mod
    import gracenav.scenarios.spec as spec_mod
    from gracenav.cli import main
    from gracenav.execution import controller as controller_mod

    marks["imports"] = time.time() - t0

    def timed(owner: Any, name: str, key: str, keep: Any = None) -> None:
        inner = getattr(owner, name)

        def wrapper(*args: Any, **kwargs: Any) -> Any:
            marks.setdefault(f"{key}_start", time.time() - t0)
            out = inner(*args, **kwargs)
            marks.setdefault(f"{key}_end", time.time() - t0)
            if keep is not None:
                keep(out)
            return out

        setattr(owner, name, wrapper)

    def estimate(est: Any) -> None:
        marks["halvings"] = est.halvings
        marks["estimate_bytes"] = est.bytes
        marks["estimate_policies"] = est.policies

    timed(run_mod, "load_scenario_map", "map")
    timed(spec_mod, "choose_halvings", "budget", estimate)
    timed(library_mod, "build_library", "library", lambda lib: marks.update(policies=len(lib)))
    timed(graph_mod, "build_graph", "graph")
    timed(controller_mod.HybridController, "reset", "reset")
    step = controller_mod.HybridController.step

    def first_step(self: Any, *args: Any, **kwargs: Any) -> Any:
        if "first_command" not in marks:
            marks["first_command"] = time.time() - t0
            if prof is not None:
                import io
                import pstats

                prof.disable()
                text = io.StringIO()
                pstats.Stats(prof, stream=text).sort_stats("cumulative").print_stats(profile)
                marks["profile"] = text.getvalue()
        return step(self, *args, **kwargs)

    controller_mod.HybridController.step = first_step  # type: ignore[method-assign]
    status = main(["run", scenario, "--out", out])
    marks["end"] = time.time() - t0
    marks["status"] = status
    print(_MARK + json.dumps(marks), file=sys.stderr, flush=True)
    return status


def run_case(scenario: Path, out: Path, profile: int, timeout: float) -> tuple[dict[str, Any], str]:
    """Run the child on ``scenario``; its marks with ``peak_kib`` (ru_maxrss), and the
    command's output."""
    log = out.with_suffix(".log")
    env = {**os.environ, "BENCH_T0": repr(time.time())}
    cmd = [sys.executable, os.path.abspath(__file__), "--child", str(scenario), str(out)]
    cmd += ["--profile", str(profile)]
    with open(log, "w") as fo:
        proc = subprocess.Popen(cmd, stdout=fo, stderr=subprocess.STDOUT, env=env)
        deadline = time.monotonic() + timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                proc.kill()
                _, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)
    text = log.read_text()
    marks: dict[str, Any] = {}
    for line in text.splitlines():
        if line.startswith(_MARK):
            marks = json.loads(line[len(_MARK) :])
    marks["peak_kib"] = usage.ru_maxrss
    marks["returncode"] = proc.returncode
    shown = "\n".join(ln for ln in text.splitlines() if not ln.startswith(_MARK))
    return marks, shown


def _span(m: dict[str, Any], a: str, b: str) -> str:
    return f"{m[b] - m[a]:.2f}" if a in m and b in m else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=CASES, help="run one map only")
    ap.add_argument("--seed", type=int, default=1, help="seed of the maps and tasks")
    ap.add_argument("--memory-limit-gib", type=float, help="planner.memory_limit_gib")
    ap.add_argument("--max-halvings", type=int, help="planner.max_halvings (default: chosen)")
    ap.add_argument("--profile", type=int, default=0, help="print the top N of cProfile")
    ap.add_argument("--timeout", type=float, default=900.0, help="time limit per map (s)")
    ap.add_argument("--keep", type=Path, help="write maps, scenarios and outputs here")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        sys.exit(child(args.child[0], args.child[1], args.profile))
    import yaml

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep if args.keep is not None else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        rows = []
        for case in CASES:
            if args.only not in (None, case):
                continue
            path = make_case(case, folder, args.seed)
            doc = yaml.safe_load(path.read_text())
            planner = {}
            if args.memory_limit_gib is not None:
                planner["memory_limit_gib"] = args.memory_limit_gib
            if args.max_halvings is not None:
                planner["max_halvings"] = args.max_halvings
            if planner:
                doc["planner"] = planner
                path.write_text(yaml.safe_dump(doc, sort_keys=False))
            task = doc["task"]
            print(f"== {case}: {path.name}, start {task['starts'][0][:2]}, goal {task['goal'][:2]}")
            out = folder / f"{case}_out"
            shutil.rmtree(out, ignore_errors=True)  # gracenav run refuses an existing DIR
            marks, shown = run_case(path, out, args.profile, args.timeout)
            for line in shown.splitlines():
                if line.startswith(("library:", "run ", "gracenav:")):
                    print(f"  {line}")
            rows.append((case, marks))
    print()
    print(
        f"{'map':<9} {'halv':>4} {'estimate':>8} {'peak RSS':>8} {'policies':>9} "
        f"{'python':>6} {'imports':>7} {'palette':>7} {'map':>5} {'budget':>6} {'library':>7} "
        f"{'graph':>5} {'controller':>10} {'1st cmd':>7} {'total':>6} {'status':>6}"
    )
    print(
        f"{'':<9} {'':>4} {'GiB':>8} {'GiB':>8} {'':>9} {'s':>6} {'s':>7} {'s':>7} {'s':>5} "
        f"{'s':>6} {'s':>7} {'s':>5} {'s':>10} {'s':>7} {'s':>6}"
    )
    for case, m in rows:
        est = m.get("estimate_bytes")
        first = m.get("first_command")
        print(
            f"{case:<9} {m.get('halvings', '-')!s:>4} "
            f"{'-' if est is None else f'{est / 2**30:.3f}':>8} "
            f"{m['peak_kib'] / 2**20:>8.3f} {m.get('policies', '-')!s:>9} "
            f"{m.get('python', float('nan')):>6.2f} "
            f"{_span(m, 'python', 'imports'):>7} {_span(m, 'imports', 'map_start'):>7} "
            f"{_span(m, 'map_start', 'map_end'):>5} "
            f"{_span(m, 'budget_start', 'budget_end'):>6} "
            f"{_span(m, 'library_start', 'library_end'):>7} "
            f"{_span(m, 'graph_start', 'graph_end'):>5} "
            f"{_span(m, 'graph_end', 'first_command'):>10} "
            f"{'-' if first is None else f'{first:.2f}':>7} "
            f"{m.get('end', float('nan')):>6.1f} {m['returncode']!s:>6}"
        )
    print(
        "estimate: gracenav.scenarios.estimate_run_memory of the halvings chosen; peak RSS: "
        "ru_maxrss of the command's process; times from just before the process started: "
        "python = interpreter up, imports = gracenav's modules, palette = the scenario and "
        "the palette read, controller = from the graph "
        "to the first command (stored reversed graph, catches, first plans)"
    )
    for case, m in rows:
        if "profile" in m:
            print(f"\n== {case}: cProfile up to the first command")
            print(m["profile"])


if __name__ == "__main__":
    main()
