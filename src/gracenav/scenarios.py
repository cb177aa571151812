"""Navigation scenarios: YAML task files, running them, and their machine-readable results.

A scenario file (YAML) has these keys (SI units; positions in m, velocities in m/s)::

    name: paper Fig. 5                      # required
    map:                                    # inline geometry ...
      bounds: [[-1, -1], [3.5, 3]]
      obstacles: [{rectangle: {min: [0.75, 1.0], max: [1.25, 1.5]}}]
    # map: {ros_map: lab.yaml}              # ... or a ROS map_server file, relative to this file
    robot: {footprint_radius: 0.2}          # optional
    planner: {cost: time, max_halvings: 1}  # optional; cost: time | distance
    task:                                   # required
      kind: point_to_point                  # goal and starts: [x, y, xdot, ydot]
      goal: [2, 2, 0, 0]
      starts: [[0, 0, 0, 0], [0, 2, 0, 0]]
    # task: {kind: surveillance, start: [...], goals: [[...], ...], loops: 5}
    disturbances:                           # optional
      - {kind: push, time: 3.0, impulse: [10, 0]}                         # N s on the body
      - {kind: drag, start_time: 3, end_time: 5, velocity: [0, -0.3]}     # held and moved
    simulation: {plant: model3d, seed: 0, position_noise_std: 0.0, max_time: 120}

Unknown keys and values of the wrong type raise :class:`gracenav.errors.ConfigError`
naming the key and the file.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from gracenav._io import atomic_write_text, yaml_error_message
from gracenav.errors import ConfigError
from gracenav.simulate import Disturbance, Drag, Push, SimulationOptions

__all__ = [
    "RunSummary",
    "Scenario",
    "ScenarioResult",
    "load_scenario",
    "parse_scenario",
    "run_scenario",
    "write_outputs",
]

_TOP = {"name", "map", "robot", "planner", "task", "disturbances", "simulation"}


@dataclass(frozen=True)
class Scenario:
    """A parsed scenario (see the module docstring for the file format).

    Attributes
    ----------
    name : str
    map_source : dict or Path
        Inline geometry, or the path of a ROS map_server YAML file.
    footprint_radius : float
        (m)
    cost : {"time", "distance"}
    max_halvings : int
        Coverage refinement limit for the library.
    kind : {"point_to_point", "surveillance"}
    goals : tuple of tuple of float
        One goal for point-to-point, the repeating goals for surveillance.
    starts : tuple of tuple of float
        One run per start.
    loops : int
    disturbances : tuple of Disturbance
    plant : {"model3d", "mujoco"}
    seed : int
    position_noise_std : float
        (m)
    max_time : float
        (s)
    source : str
    """

    name: str
    map_source: dict[str, Any] | Path
    footprint_radius: float
    cost: Literal["time", "distance"]
    max_halvings: int
    kind: Literal["point_to_point", "surveillance"]
    goals: tuple[tuple[float, ...], ...]
    starts: tuple[tuple[float, ...], ...]
    loops: int
    disturbances: tuple[Disturbance, ...]
    plant: Literal["model3d", "mujoco"]
    seed: int
    position_noise_std: float
    max_time: float
    source: str = "scenario"


class _Reader:
    """Typed access to a mapping with error messages that name the key and the file."""

    def __init__(self, data: Any, where: str, source: str) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: '{where}' must be a mapping, got {type(data).__name__}")
        self.data = data
        self.where = where
        self.source = source

    def _key(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def check_keys(self, allowed: set[str]) -> None:
        unknown = sorted(str(k) for k in set(self.data) - allowed)
        if unknown:
            raise ConfigError(
                f"{self.source}: unknown key(s) {', '.join(self._key(k) for k in unknown)}; "
                f"allowed: {', '.join(sorted(allowed))}"
            )

    def get(self, key: str, default: Any = ...) -> Any:
        if key not in self.data:
            if default is ...:
                raise ConfigError(f"{self.source}: missing key '{self._key(key)}'")
            return default
        return self.data[key]

    def number(self, key: str, default: Any = ..., *, positive: bool = False) -> float:
        v = self.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{self.source}: '{self._key(key)}' must be a number, got {v!r}")
        if positive and not v > 0:
            raise ConfigError(f"{self.source}: '{self._key(key)}' must be positive, got {v!r}")
        return float(v)

    def integer(self, key: str, default: Any = ..., *, minimum: int = 0) -> int:
        v = self.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise ConfigError(
                f"{self.source}: '{self._key(key)}' must be an integer >= {minimum}, got {v!r}"
            )
        return int(v)

    def choice(self, key: str, options: Sequence[str], default: Any = ...) -> str:
        v = self.get(key, default)
        if v not in options:
            raise ConfigError(
                f"{self.source}: '{self._key(key)}' must be one of {', '.join(options)}, got {v!r}"
            )
        return str(v)

    def vector(self, key: str, n: int, value: Any = ...) -> tuple[float, ...]:
        v = self.get(key) if value is ... else value
        ok = isinstance(v, (list, tuple)) and len(v) == n
        ok = ok and all(
            not isinstance(e, bool) and isinstance(e, (int, float)) and math.isfinite(e) for e in v
        )
        if not ok:
            raise ConfigError(
                f"{self.source}: '{self._key(key)}' must be a list of {n} numbers, got {v!r}"
            )
        return tuple(float(e) for e in v)

    def sub(self, key: str, default: Any = ...) -> _Reader:
        return _Reader(self.get(key, default), self._key(key), self.source)


def parse_scenario(data: Any, *, source: str = "scenario", base: Path | None = None) -> Scenario:
    """Validate a scenario mapping (as loaded from YAML) and build a :class:`Scenario`.

    ``base`` is the folder relative to which ``map.ros_map`` is resolved.
    """
    top = _Reader(data, "", source)
    top.check_keys(_TOP)
    name = top.get("name")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{source}: 'name' must be a non-empty string, got {name!r}")
    mp = top.sub("map")
    map_source: dict[str, Any] | Path
    if "ros_map" in mp.data:
        mp.check_keys({"ros_map"})
        rel = mp.get("ros_map")
        if not isinstance(rel, str):
            raise ConfigError(f"{source}: 'map.ros_map' must be a file path, got {rel!r}")
        map_source = (base or Path(".")) / rel
    else:
        map_source = dict(mp.data)
    robot = top.sub("robot", {})
    robot.check_keys({"footprint_radius"})
    footprint = robot.number("footprint_radius", 0.2)
    if footprint < 0:
        raise ConfigError(f"{source}: 'robot.footprint_radius' must be >= 0, got {footprint!r}")
    planner = top.sub("planner", {})
    planner.check_keys({"cost", "max_halvings"})
    cost = planner.choice("cost", ("time", "distance"), "time")
    halvings = planner.integer("max_halvings", 1)
    task = top.sub("task")
    kind = task.choice("kind", ("point_to_point", "surveillance"))
    if kind == "point_to_point":
        task.check_keys({"kind", "goal", "starts"})
        goals: tuple[tuple[float, ...], ...] = (task.vector("goal", 4),)
        starts_raw = task.get("starts")
        if not isinstance(starts_raw, list) or not starts_raw:
            raise ConfigError(
                f"{source}: 'task.starts' must be a non-empty list of [x, y, xdot, ydot]"
            )
        starts = tuple(task.vector(f"starts[{i}]", 4, s) for i, s in enumerate(starts_raw))
        loops = 1
    else:
        task.check_keys({"kind", "start", "goals", "loops"})
        starts = (task.vector("start", 4),)
        goals_raw = task.get("goals")
        if not isinstance(goals_raw, list) or not goals_raw:
            raise ConfigError(
                f"{source}: 'task.goals' must be a non-empty list of [x, y, xdot, ydot]"
            )
        goals = tuple(task.vector(f"goals[{i}]", 4, g) for i, g in enumerate(goals_raw))
        loops = task.integer("loops", 1, minimum=1)
    dist_raw = top.get("disturbances", [])
    if not isinstance(dist_raw, list):
        raise ConfigError(f"{source}: 'disturbances' must be a list")
    disturbances: list[Disturbance] = []
    for i, d in enumerate(dist_raw):
        r = _Reader(d, f"disturbances[{i}]", source)
        k = r.choice("kind", ("push", "drag"))
        if k == "push":
            r.check_keys({"kind", "time", "impulse"})
            imp = r.vector("impulse", 2)
            disturbances.append(Push(time=r.number("time"), impulse=(imp[0], imp[1])))
        else:
            r.check_keys({"kind", "start_time", "end_time", "velocity"})
            t0, t1 = r.number("start_time"), r.number("end_time")
            if not t1 > t0 >= 0:
                raise ConfigError(
                    f"{source}: 'disturbances[{i}]' needs 0 <= start_time < end_time, "
                    f"got {t0} and {t1}"
                )
            v = r.vector("velocity", 2)
            disturbances.append(Drag(start_time=t0, end_time=t1, velocity=(v[0], v[1])))
    sim = top.sub("simulation", {})
    sim.check_keys({"plant", "seed", "position_noise_std", "max_time"})
    plant = sim.choice("plant", ("model3d", "mujoco"), "model3d")
    noise = sim.number("position_noise_std", 0.0)
    if noise < 0:
        raise ConfigError(f"{source}: 'simulation.position_noise_std' must be >= 0, got {noise}")
    return Scenario(
        name=name,
        map_source=map_source,
        footprint_radius=footprint,
        cost=cost,  # type: ignore[arg-type]
        max_halvings=halvings,
        kind=kind,  # type: ignore[arg-type]
        goals=goals,
        starts=starts,
        loops=loops,
        disturbances=tuple(disturbances),
        plant=plant,  # type: ignore[arg-type]
        seed=sim.integer("seed", 0),
        position_noise_std=noise,
        max_time=sim.number("max_time", 120.0, positive=True),
        source=source,
    )


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario YAML file."""
    import yaml

    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read scenario file {path}: {exc.strerror}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {yaml_error_message(exc)}") from None
    return parse_scenario(data, source=str(path), base=path.parent)


@dataclass(frozen=True)
class RunSummary:
    """Machine-readable outcome of one run (one start) of a scenario."""

    start: tuple[float, ...]
    reached_goal: bool
    stop_reason: str
    time_s: float
    path_length_m: float
    final_error_m: float
    final_speed_mps: float
    max_lean_deg: float
    max_torque: float
    max_jerk: float
    switches: int
    non_graceful_switches: int
    max_graceful_torque_jump: float
    min_clearance_m: float
    goals_reached: int
    tree_ms: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class ScenarioResult:
    """A scenario's episodes, per-run summaries and the library figures."""

    scenario: Scenario
    episodes: tuple[Any, ...]
    runs: tuple[RunSummary, ...]
    library_size: int
    graph_edges: int
    coverage: float
    library_seconds: float
    world_map: Any = field(repr=False)
    library: Any = field(repr=False)


def run_scenario(
    scenario: Scenario,
    *,
    palette: Any | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ScenarioResult:
    """Build the library on the scenario's map and run every start of its task.

    Parameters
    ----------
    scenario : Scenario
    palette : Palette, optional
        Default: the shipped palette.
    progress : callable(done, total), optional
        Called after each run.
    """
    from gracenav.execution import ExecutionOptions, HybridController
    from gracenav.graph import build_graph
    from gracenav.library import build_library
    from gracenav.palette import load_palette
    from gracenav.simulate import state_from_position
    from gracenav.world import load_map

    palette = palette if palette is not None else load_palette()
    world_map = load_map(scenario.map_source)
    t0 = time.perf_counter()
    library = build_library(
        palette,
        world_map,
        footprint_radius=scenario.footprint_radius,
        max_halvings=scenario.max_halvings,
        seed=scenario.seed,
    )
    graph = build_graph(library)
    lib_seconds = time.perf_counter() - t0
    options = ExecutionOptions(
        plant=scenario.plant,
        max_time=scenario.max_time,
        simulation=SimulationOptions(
            position_noise_std=scenario.position_noise_std, seed=scenario.seed
        ),
    )
    radius = palette.params.ball_radius
    episodes = []
    runs = []
    for i, start in enumerate(scenario.starts):
        hc = HybridController(library, graph, criterion=scenario.cost)
        x0 = state_from_position(np.asarray(start), radius)
        ep = hc.run(
            x0,
            scenario.goals,
            loops=scenario.loops,
            disturbances=scenario.disturbances,
            options=options,
        )
        episodes.append(ep)
        runs.append(_summarise(ep, start, scenario, world_map, palette))
        if progress is not None:
            progress(i + 1, len(scenario.starts))
    return ScenarioResult(
        scenario=scenario,
        episodes=tuple(episodes),
        runs=tuple(runs),
        library_size=len(library),
        graph_edges=graph.num_edges,
        coverage=float(library.coverage),
        library_seconds=lib_seconds,
        world_map=world_map,
        library=library,
    )


def _summarise(
    ep: Any, start: Sequence[float], sc: Scenario, world_map: Any, palette: Any
) -> RunSummary:
    p = ep.position_state
    goal = np.asarray(sc.goals[-1] if sc.kind == "point_to_point" else sc.goals[0])
    jumps = ep.graceful_torque_jumps()
    clearance = world_map.clearance(p[:, :2]) - sc.footprint_radius
    return RunSummary(
        start=tuple(float(v) for v in start),
        reached_goal=bool(ep.reached_goal),
        stop_reason=ep.status.value,
        time_s=float(ep.time[-1]),
        path_length_m=ep.path_length,
        final_error_m=float(np.linalg.norm(p[-1, :2] - goal[:2]))
        if sc.kind == "point_to_point"
        else float("nan"),
        final_speed_mps=float(np.linalg.norm(p[-1, 2:])),
        max_lean_deg=float(np.rad2deg(np.max(np.abs(ep.lean)))),
        max_torque=float(np.max(np.abs(ep.inputs))),
        max_jerk=float(np.max(ep.ball_jerk(palette.params))) if ep.time.size > 2 else 0.0,
        switches=ep.switches,
        non_graceful_switches=ep.non_graceful_switches,
        max_graceful_torque_jump=float(np.max(jumps)) if jumps.size else 0.0,
        min_clearance_m=float(np.min(clearance)),
        goals_reached=len(ep.goals_reached),
        tree_ms=1000.0 * float(np.median(ep.tree_seconds)) if ep.tree_seconds else 0.0,
    )


def write_outputs(result: ScenarioResult, out: str | Path, *, animation: bool = True) -> list[Path]:
    """Write summary.json, trajectory.csv, events.csv, figures and an animation into ``out``.

    Returns the written paths.
    """
    from gracenav.plotting.navigation import animate_episode, plot_lean, plot_paths

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sc = result.scenario
    summary = {
        "scenario": sc.name,
        "source": sc.source,
        "task": sc.kind,
        "plant": sc.plant,
        "library_size": result.library_size,
        "graph_edges": result.graph_edges,
        "coverage": result.coverage,
        "library_and_graph_s": result.library_seconds,
        "runs": [r.to_dict() for r in result.runs],
    }
    written = []
    path = out / "summary.json"
    atomic_write_text(path, json.dumps(summary, indent=2, allow_nan=True) + "\n")
    written.append(path)
    rows = ["run,t,x,y,xdot,ydot,lean_x,lean_y,tau_x,tau_y,ref_x,ref_y,policy"]
    for k, ep in enumerate(result.episodes):
        p = ep.position_state
        for i in range(ep.time.size):
            pol = int(ep.policy[i])
            rows.append(
                f"{k},{ep.time[i]:.6f},{p[i, 0]:.6f},{p[i, 1]:.6f},{p[i, 2]:.6f},{p[i, 3]:.6f},"
                f"{ep.lean[i, 0]:.6e},{ep.lean[i, 1]:.6e},{ep.inputs[i, 0]:.5f},"
                f"{ep.inputs[i, 1]:.5f},{ep.reference[i, 0]:.6f},{ep.reference[i, 1]:.6f},{pol}"
            )
    path = out / "trajectory.csv"
    atomic_write_text(path, "\n".join(rows) + "\n")
    written.append(path)

    def name(i: int) -> str:
        return result.library.policy(i).name if i >= 0 else ""

    ev = ["run,time,from,to,from_name,to_name,reason"]
    for k, ep in enumerate(result.episodes):
        for e in ep.events:
            ev.append(
                f"{k},{e.time:.6f},{e.from_policy},{e.to_policy},{name(e.from_policy)},"
                f"{name(e.to_policy)},{e.reason.value}"
            )
    path = out / "events.csv"
    atomic_write_text(path, "\n".join(ev) + "\n")
    written.append(path)
    written.append(plot_paths(result, out / "paths.png"))
    written.append(plot_lean(result, out / "lean.png"))
    if animation:
        written.append(animate_episode(result, 0, out / "animation.gif"))
    return written
