"""Navigation scenarios: YAML task files, running them, and their machine-readable results.

A scenario file (YAML) has these keys (SI units; positions in m, velocities in m/s)::

    name: paper Fig. 5                      # required
    map:                                    # inline geometry ...
      bounds: [[-1, -1], [3.5, 3]]
      obstacles: [{rectangle: {min: [0.75, 1.0], max: [1.25, 1.5]}}]
    # map: {ros_map: lab.yaml}              # ... or a ROS map_server file, relative to this file
    robot: {footprint_radius: 0.2, sensing_range: 3.0}  # optional (m)
    planner: {cost: time, max_halvings: 1}  # optional; cost: time | distance
    # planner: {speed_clearance: 0.1}       # stopping allowance (s): moving policies keep
    #   0.1 s x their speed more room toward obstacles ahead (0: the paper's instantiation)
    # planner: {kind: decoupled}            # the plan-then-track baseline (gracenav.baseline)
    # planner: {resume_from_balancing: false, capture: true, seed: 0}  # the paper's
    #   recovery; catches placed at the state (gracenav.capture); library seed
    task:                                   # required
      kind: point_to_point                  # goal and starts: [x, y, xdot, ydot]
      goal: [2, 2, 0, 0]
      starts: [[0, 0, 0, 0], [0, 2, 0, 0]]
    # task: {kind: surveillance, start: [...], goals: [[...], ...], loops: 5}
    moving_obstacles:                       # optional: people, carts (discs), unknown in advance
      - {name: person, radius: 0.25, path: [[3, 0.5], [3, 2.5]], speed: 1.0, appear: 2}
      - {name: cart, radius: 0.35, path: [[5, 1.5]], appear: 3, leave: 8}   # stands 5 s
    disturbances:                           # optional
      - {kind: push, time: 3.0, impulse: [10, 0]}                         # N s on the body
      - {kind: drag, start_time: 3, end_time: 5, velocity: [0, -0.3]}     # held and moved
    simulation: {plant: model3d, seed: 0, position_noise_std: 0.0, max_time: 120,
                 plant_params: {ball_radius: 1.02, body_mass: 0.8}}  # factors, optional

``simulation.plant_params`` scales the simulated robot's physical parameters
(:data:`PLANT_FACTOR_FIELDS`, :class:`~gracenav.params.BallbotParams` names) by
dimensionless factors within :data:`PLANT_FACTOR_RANGE`; the controllers keep the
palette's design (model mismatch).

The file is UTF-8 YAML without duplicate keys. Unknown keys, values of the wrong type
and values beyond the limits below (``MAX_*``: runs, loops, simulated time, library size)
raise :class:`gracenav.errors.ConfigError` naming the file and the key path, before any
heavy work.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from gracenav._io import atomic_write_text, load_document
from gracenav._validate import Fields, require_mapping
from gracenav.control import CONTROL_RATE
from gracenav.errors import ConfigError
from gracenav.graph import CostCriterion, CostName
from gracenav.library import DEFAULT_SPEED_CLEARANCE, MAX_SPEED_CLEARANCE
from gracenav.params import BallbotParams
from gracenav.replanning import ObstacleSensing
from gracenav.sim.plant import PLANT_KINDS, PlantKind
from gracenav.simulate import Disturbance, Drag, Push, SimulationOptions
from gracenav.world.moving import MovingObstacle, moving_clearance

__all__ = [
    "PLANNERS",
    "PreparedLibrary",
    "RunSummary",
    "Scenario",
    "ScenarioResult",
    "apply_plant_factors",
    "check_scenario",
    "check_task",
    "estimate_instantiations",
    "library_key",
    "load_scenario",
    "load_scenario_map",
    "parse_scenario",
    "prepare_library",
    "run_scenario",
    "summary_dict",
    "write_outputs",
]


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
    plant_factors : tuple of (str, float)
        Factors (dimensionless) of the simulated plant's parameters, by
        :class:`~gracenav.params.BallbotParams` field name, in file order; empty: the
        plant has the parameters it is given (see :func:`run_scenario`).
    planner : {"gracenav", "decoupled"}
        ``gracenav``: the verified policy library and hybrid controller; ``decoupled``:
        the plan-then-track baseline of :mod:`gracenav.baseline`.
    resume_from_balancing : bool
        See :class:`~gracenav.execution.ExecutionOptions`; False is the paper's
        behaviour (no unverified balancing-mode fallback).
    capture : bool
        ``planner.capture``: place a verified catch at a state no library policy
        contains (:mod:`gracenav.capture`; default true).
    library_seed : int
        Seed of the library's coverage samples (``planner.seed``), apart from the
        simulation's seed, so that trials with different noise share one library.
    speed_clearance : float
        ``planner.speed_clearance``: the library's stopping allowance (s; see
        :func:`gracenav.library.build_library`).
    moving_obstacles : tuple of MovingObstacle
        Obstacles not in the map, learned within ``sensing_range`` (m) of the robot.
    sensing_range : float
        (m), ``robot.sensing_range``.
    """

    name: str
    map_source: dict[str, Any] | Path
    footprint_radius: float
    cost: CostName
    max_halvings: int
    kind: Literal["point_to_point", "surveillance"]
    goals: tuple[tuple[float, ...], ...]
    starts: tuple[tuple[float, ...], ...]
    loops: int
    disturbances: tuple[Disturbance, ...]
    plant: PlantKind
    seed: int
    position_noise_std: float
    max_time: float
    source: str = "scenario"
    plant_factors: tuple[tuple[str, float], ...] = ()
    planner: Literal["gracenav", "decoupled"] = "gracenav"
    resume_from_balancing: bool = True
    capture: bool = True
    library_seed: int = 0
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE
    moving_obstacles: tuple[MovingObstacle, ...] = ()
    sensing_range: float = 3.0


_TOP = (
    "name",
    "map",
    "robot",
    "planner",
    "task",
    "disturbances",
    "moving_obstacles",
    "simulation",
)
PLANNERS = ("gracenav", "decoupled")
"""Values of ``planner.kind``."""

# -- limits ----------------------------------------------------------------------------
# Every number of a scenario is checked against these before any heavy work, so that a
# typo (an extra zero, a wrong unit) is refused with an estimate instead of running for
# hours or exhausting memory.
MAX_STARTS = 100
"""Most runs (starts) of one point-to-point scenario."""
MAX_GOALS = 100
"""Most goals of one surveillance loop."""
MAX_LOOPS = 10_000
"""Most surveillance loops."""
MAX_DISTURBANCES = 100
"""Most disturbances of one scenario."""
MAX_MOVING_OBSTACLES = 50
"""Most moving obstacles of one scenario."""
MAX_PATH_POINTS = 100
"""Most waypoints of one moving obstacle's path."""
MAX_SIMULATED_TIME_S = 1800.0
"""Budget of simulated time over all runs, max_time × starts (s): 1.8 M control ticks,
about 250 MB of recorded history and a few minutes of computing."""
MAX_INSTANTIATIONS = 2_000_000
"""Budget of policy instantiations tried by the library over all halvings (lattice
points × orientations × palette policies): the 50 m × 50 m office at one pass tries
1.56 M (≈2 s, ≈330 MiB)."""
MAX_COORDINATE = 1.0e4
"""Largest |entry| of a start or goal state (m, m/s)."""
MAX_IMPULSE_NS = 1000.0
"""Largest push impulse per axis (N s); the robot falls from far less (README)."""
MAX_DRAG_SPEED_MPS = 10.0
"""Largest drag velocity per axis (m/s)."""
MAX_FOOTPRINT_M = 5.0
"""Largest footprint radius (m)."""
MAX_NOISE_STD_M = 1.0
"""Largest position noise standard deviation (m)."""
PLANT_FACTOR_RANGE = (0.5, 2.0)
"""Allowed factors of ``simulation.plant_params`` (dimensionless, inclusive): half to
twice the nominal value, a model error far beyond what a robot's data sheet leaves."""
PLANT_FACTOR_FIELDS = (
    "ball_radius",
    "ball_mass",
    "ball_inertia",
    "body_mass",
    "body_com_height",
    "body_inertia_x",
    "body_inertia_y",
    "body_inertia_z",
    "coulomb_friction",
    "viscous_friction",
    "torque_limit",
)
"""The plant parameters ``simulation.plant_params`` may scale: the robot's physical
properties. Not gravity, the friction model's smoothing or the drawn body radius."""


def parse_scenario(data: Any, *, source: str = "scenario", base: Path | None = None) -> Scenario:
    """Validate a scenario mapping (as loaded from YAML) and build a :class:`Scenario`.

    ``base`` is the folder relative to which ``map.ros_map`` is resolved. Values are
    checked against the module's limits (``MAX_*``).

    Raises
    ------
    ConfigError
        Naming ``source`` and the key path of the first invalid value.
    """
    require_mapping(data, source, "scenario", _TOP)
    top = Fields(data, "", source)
    top.check_keys(_TOP)
    name = top.string("name")
    mp = top.sub("map")
    map_source: dict[str, Any] | Path
    if "ros_map" in mp.data:
        mp.check_keys({"ros_map"})
        map_source = mp.file("ros_map", base or Path("."), must_exist=False)
    else:
        map_source = dict(mp.data)  # checked by the map loader (size limit included)
    robot = top.sub("robot", {})
    robot.check_keys({"footprint_radius", "sensing_range"})
    footprint = robot.number(
        "footprint_radius", 0.2, minimum=0.0, maximum=MAX_FOOTPRINT_M, unit="m"
    )
    sensing_range = robot.number(
        "sensing_range", ObstacleSensing().range, positive=True, maximum=100.0, unit="m"
    )
    planner = top.sub("planner", {})
    planner.check_keys(
        {
            "kind",
            "cost",
            "max_halvings",
            "resume_from_balancing",
            "capture",
            "seed",
            "speed_clearance",
        }
    )
    planner_kind = planner.choice("kind", PLANNERS, "gracenav")
    cost = planner.choice("cost", [c.value for c in CostCriterion], "time")
    halvings = planner.integer("max_halvings", 1, maximum=20)
    resume = planner.boolean("resume_from_balancing", True)
    capture = planner.boolean("capture", True)
    library_seed = planner.integer("seed", 0, maximum=2**32 - 1)
    speed_clearance = planner.number(
        "speed_clearance",
        DEFAULT_SPEED_CLEARANCE,
        minimum=0.0,
        maximum=MAX_SPEED_CLEARANCE,
        unit="s",
    )
    sim = top.sub("simulation", {})
    sim.check_keys({"plant", "seed", "position_noise_std", "max_time", "plant_params"})
    plant = sim.choice("plant", PLANT_KINDS, "model3d")
    plant_factors = _plant_factors(sim)
    noise = sim.number("position_noise_std", 0.0, minimum=0.0, maximum=MAX_NOISE_STD_M, unit="m")
    seed = sim.integer("seed", 0, maximum=2**32 - 1)
    max_time = sim.number("max_time", 120.0, positive=True, unit="s")
    task = top.sub("task")
    kind = task.choice("kind", ("point_to_point", "surveillance"))
    state = "[x, y, xdot, ydot]"
    if kind == "point_to_point":
        task.check_keys({"kind", "goal", "starts"})
        goals: tuple[tuple[float, ...], ...] = (
            task.vector("goal", 4, bound=MAX_COORDINATE, what=state),
        )
        starts = task.points(
            "starts", dim=4, min_len=1, max_len=MAX_STARTS, bound=MAX_COORDINATE, what=state
        )
        loops = 1
    else:
        task.check_keys({"kind", "start", "goals", "loops"})
        starts = (task.vector("start", 4, bound=MAX_COORDINATE, what=state),)
        goals = task.points(
            "goals", dim=4, min_len=1, max_len=MAX_GOALS, bound=MAX_COORDINATE, what=state
        )
        loops = task.integer("loops", 1, minimum=1, maximum=MAX_LOOPS)
    total = max_time * len(starts)
    if total > MAX_SIMULATED_TIME_S:
        raise top.fail(
            f"'simulation.max_time' {max_time:g} s × {len(starts)} run(s) = {total:g} s of "
            f"simulated time, more than the budget of {MAX_SIMULATED_TIME_S:g} s (about "
            f"{MAX_SIMULATED_TIME_S * 1024 / 1e6:.1f} M control ticks); lower max_time or "
            "split the starts over several scenarios"
        )
    dist_raw = top.items(
        "disturbances", [], max_len=MAX_DISTURBANCES, what="{kind: push | drag, ...}"
    )
    disturbances: list[Disturbance] = []
    for i, d in enumerate(dist_raw):
        r = Fields(d, f"disturbances[{i}]", source)
        k = r.choice("kind", ("push", "drag"))
        if k == "push":
            r.check_keys({"kind", "time", "impulse"})
            t = r.number("time", minimum=0.0, unit="s")
            if t >= max_time:
                raise r.fail(
                    f"'{r.path('time')}' {t:g} s is not before simulation.max_time "
                    f"({max_time:g} s): the push would never apply"
                )
            imp = r.vector("impulse", 2, bound=MAX_IMPULSE_NS, what="[ix, iy] (N s)")
            disturbances.append(Push(time=t, impulse=(imp[0], imp[1])))
        else:
            r.check_keys({"kind", "start_time", "end_time", "velocity"})
            t0 = r.number("start_time", minimum=0.0, unit="s")
            t1 = r.number("end_time", minimum=0.0, unit="s")
            if not t1 > t0:
                raise r.fail(
                    f"'disturbances[{i}]' needs 0 <= start_time < end_time, got {t0:g} and {t1:g}"
                )
            if t0 >= max_time:
                raise r.fail(
                    f"'{r.path('start_time')}' {t0:g} s is not before simulation.max_time "
                    f"({max_time:g} s): the drag would never apply"
                )
            v = r.vector("velocity", 2, bound=MAX_DRAG_SPEED_MPS, what="[vx, vy] (m/s)")
            disturbances.append(Drag(start_time=t0, end_time=t1, velocity=(v[0], v[1])))
    moving = _moving_obstacles(top, max_time)
    return Scenario(
        moving_obstacles=moving,
        sensing_range=sensing_range,
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
        seed=seed,
        position_noise_std=noise,
        max_time=max_time,
        source=source,
        plant_factors=plant_factors,
        planner=planner_kind,  # type: ignore[arg-type]
        resume_from_balancing=resume,
        capture=capture,
        library_seed=library_seed,
        speed_clearance=speed_clearance,
    )


def _moving_obstacles(top: Fields, max_time: float) -> tuple[MovingObstacle, ...]:
    raw = top.items(
        "moving_obstacles",
        [],
        max_len=MAX_MOVING_OBSTACLES,
        what="{radius, path, speed, appear, leave}",
    )
    out = []
    for i, d in enumerate(raw):
        r = Fields(d, f"moving_obstacles[{i}]", top.source)
        r.check_keys({"name", "radius", "path", "speed", "appear", "leave"})
        name = r.string("name", f"obstacle {i}")
        radius = r.number("radius", positive=True, maximum=MAX_FOOTPRINT_M, unit="m")
        path = r.points(
            "path", min_len=1, max_len=MAX_PATH_POINTS, bound=MAX_COORDINATE, what="[x, y]"
        )
        speed = r.number("speed", 0.0, minimum=0.0, maximum=MAX_DRAG_SPEED_MPS, unit="m/s")
        appear = r.number("appear", 0.0, minimum=0.0, unit="s")
        leave = (
            r.number("leave", math.inf, minimum=0.0, unit="s") if "leave" in r.data else math.inf
        )
        if appear >= max_time:
            raise r.fail(
                f"'{r.path('appear')}' {appear:g} s is not before simulation.max_time "
                f"({max_time:g} s): the obstacle would never appear"
            )
        if not leave > appear:
            raise r.fail(f"'{r.path('leave')}' {leave:g} s must come after appear ({appear:g} s)")
        out.append(
            MovingObstacle(
                radius=radius,
                path=tuple((float(x), float(y)) for x, y in path),
                speed=speed,
                appear=appear,
                leave=leave,
                name=name,
            )
        )
    return tuple(out)


def _plant_factors(sim: Fields) -> tuple[tuple[str, float], ...]:
    """``simulation.plant_params``: factors by field name, each in PLANT_FACTOR_RANGE."""
    factors = sim.sub("plant_params", {})
    factors.check_keys(PLANT_FACTOR_FIELDS)
    low, high = PLANT_FACTOR_RANGE
    return tuple((str(k), factors.number(str(k), minimum=low, maximum=high)) for k in factors.data)


def apply_plant_factors(scenario: Scenario, base: BallbotParams) -> BallbotParams:
    """The simulated plant's parameters: ``base`` with the scenario's
    ``simulation.plant_params`` factors applied (``base`` itself without factors)."""
    if not scenario.plant_factors:
        return base
    return dataclasses.replace(base, **{k: getattr(base, k) * f for k, f in scenario.plant_factors})


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario YAML file (UTF-8, no duplicate keys).

    Raises
    ------
    ConfigError
        If the file cannot be read or decoded, is not valid YAML or not a valid
        scenario; the message names the file.
    """
    path = Path(path)
    data = load_document(path, "scenario file")
    return parse_scenario(data, source=str(path), base=path.parent)


def estimate_instantiations(world_map: Any, palette: Any, max_halvings: int) -> tuple[int, int]:
    """Policy instantiations the library would try with ``max_halvings`` on ``world_map``
    (lattice points × 4 orientations × palette policies, summed over the spacings
    d, d/2, ...), and the largest number of halvings within :data:`MAX_INSTANTIATIONS`
    (−1 if even one pass exceeds it)."""
    (x0, y0), (x1, y1) = world_map.bounds
    w, h = x1 - x0, y1 - y0
    total = 0
    allowed = -1
    for k in range(max_halvings + 1):
        s = palette.d / 2**k
        total += (math.floor(w / s) + 1) * (math.floor(h / s) + 1) * 4 * len(palette)
        if total <= MAX_INSTANTIATIONS:
            allowed = k
    return total, allowed


def check_scenario(scenario: Scenario, world_map: Any, palette: Any) -> None:
    """Check a scenario against its loaded map and the palette before any heavy work.

    Refuses a library refinement (``max_halvings``) whose instantiations would exceed
    :data:`MAX_INSTANTIATIONS`, surveillance loops that cannot fit in ``max_time``, and
    starts or goals outside the map or in an obstacle.

    Raises
    ------
    ConfigError
        For an over-budget scenario; the message gives the estimate and the limit.
    PlanningError
        For a start or goal outside the map or in an obstacle.
    """
    from gracenav.errors import PlanningError

    src = scenario.source
    (x0, y0), (x1, y1) = world_map.bounds
    w, h = x1 - x0, y1 - y0
    total, allowed = estimate_instantiations(world_map, palette, scenario.max_halvings)
    if total > MAX_INSTANTIATIONS:
        hint = (
            f"use planner.max_halvings <= {allowed}"
            if allowed >= 0
            else "use a smaller map (even one pass exceeds it)"
        )
        raise ConfigError(
            f"{src}: 'planner.max_halvings' {scenario.max_halvings} on this {w:g} m × {h:g} m "
            f"map would try about {total:.3g} policy instantiations (lattice spacing down to "
            f"{100 * palette.d / 2**scenario.max_halvings:.3g} cm), more than the budget of "
            f"{MAX_INSTANTIATIONS:.0e}; {hint}"
        )
    if scenario.kind == "surveillance":
        shortest = min(float(p.primitive.duration) for p in palette.policies)
        need = scenario.loops * len(scenario.goals) * shortest
        if need > scenario.max_time:
            fit = int(scenario.max_time // (len(scenario.goals) * shortest))
            hint = f"use loops <= {fit} or raise max_time" if fit else "raise max_time"
            raise ConfigError(
                f"{src}: 'task.loops' {scenario.loops} loops of {len(scenario.goals)} goal(s) "
                f"need at least {need:.3g} s (every policy lasts >= {shortest:g} s), more than "
                f"simulation.max_time = {scenario.max_time:g} s; {hint}"
            )
    footprint = scenario.footprint_radius
    named = [(f"task.starts[{i}]", s) for i, s in enumerate(scenario.starts)]
    if scenario.kind == "surveillance":
        named = [("task.start", scenario.starts[0])]
    named += [
        ("task.goal" if scenario.kind == "point_to_point" else f"task.goals[{i}]", g)
        for i, g in enumerate(scenario.goals)
    ]
    for key, state in named:
        x, y = state[0], state[1]
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            raise PlanningError(
                f"{src}: '{key}' ({x:g}, {y:g}) is outside the map [{x0:g}, {x1:g}] × "
                f"[{y0:g}, {y1:g}]"
            )
        if float(world_map.clearance(np.array([[x, y]]))[0]) < footprint:
            raise PlanningError(
                f"{src}: '{key}' ({x:g}, {y:g}) is inside an obstacle or closer to one (or "
                f"to the map edge) than the robot's footprint radius {footprint:g} m"
            )


@dataclass(frozen=True)
class RunSummary:
    """Machine-readable outcome of one run (one start) of a scenario.

    Every quantity's name ends with its unit (``_s``, ``_m``, ``_mps``, ``_deg``, ``_nm``
    (N m), ``_mps3`` (m/s³), ``_ms``); ``final_error_m`` is None for surveillance (no
    single goal). ``max_jerk_mps3`` leaves out the ticks within two control periods of a
    push (the impulse is a velocity step from outside).

    The simulated robot passes through obstacles (the plant has no contact model), so a
    run is judged on its footprint too: ``contact`` is true if the footprint overlapped
    an obstacle or the map edge at some tick (``min_clearance_m`` < 0; the first such
    time is ``contact_time_s``), and such a run never counts as ``reached_goal``.
    ``stop_reason`` is what the hybrid controller reported (:class:`TaskStatus`
    values); :attr:`outcome` is the verdict: ``contact`` for a run with contact,
    ``stop_reason`` otherwise. ``verified_recoveries`` counts switches after a domain
    exit straight into a policy whose start domain contains the state, ``captures``
    those of them into a catch placed at the state (:mod:`gracenav.capture`);
    ``balancing_s`` is the time spent in balancing mode, the unverified last resort.
    With moving obstacles, the clearance and contact are measured against their true
    positions too; ``replans`` counts the tree repairs (median and largest wall time in
    ``replan_ms_median``, ``replan_ms_max``) and ``blocked_s`` the time spent holding
    while no way to the goal was free.
    """

    start: tuple[float, ...]
    reached_goal: bool
    stop_reason: str
    time_s: float
    path_length_m: float
    final_error_m: float | None
    final_speed_mps: float
    max_lean_deg: float
    max_torque_nm: float
    max_jerk_mps3: float
    switches: int
    non_graceful_switches: int
    max_graceful_torque_jump_nm: float
    min_clearance_m: float
    goals_reached: int
    tree_ms: float
    contact: bool = False
    contact_time_s: float | None = None
    verified_recoveries: int = 0
    captures: int = 0
    balancing_s: float = 0.0
    replans: int = 0
    replan_ms_median: float = 0.0
    replan_ms_max: float = 0.0
    blocked_s: float = 0.0

    def __post_init__(self) -> None:
        if self.contact and self.reached_goal:
            raise ValueError("a run with contact cannot have reached its goal")

    @property
    def outcome(self) -> str:
        """``"contact"`` if the footprint touched an obstacle, else ``stop_reason``
        (``goal_reached``, ``loops_completed``, ``no_policy``, ``timeout``,
        ``no_progress``, ``fell``)."""
        return "contact" if self.contact else self.stop_reason

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (strict JSON: a non-finite number becomes None): ``start``,
        ``reached_goal``, ``outcome``, ``stop_reason``, ``contact``, ``contact_time_s``,
        then the measures."""
        head = ("start", "reached_goal", "outcome", "stop_reason", "contact", "contact_time_s")
        values = {k: getattr(self, k) for k in head}
        values.update({k: getattr(self, k) for k in self.__dataclass_fields__ if k not in head})
        return {k: _json_value(v) for k, v in values.items()}


def _json_value(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (list, tuple)):
        return [_json_value(e) for e in v]
    return v


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
    plant_params: BallbotParams | None = None
    """The simulated plant's parameters (None: the palette's)."""


@dataclass(frozen=True)
class PreparedLibrary:
    """A scenario's map, policy library and prepares graph, built once and shared by
    runs that differ only in their task, disturbances or simulation (campaign trials).

    Attributes
    ----------
    key : str
        What the library depends on: the palette's key, the map, the footprint, the
        halving limit and the library seed (:func:`library_key`).
    world_map, library, graph
    seconds : float
        Wall time of building the library and the graph (s).
    """

    key: str
    world_map: Any = field(repr=False)
    library: Any = field(repr=False)
    graph: Any = field(repr=False)
    seconds: float


def library_key(scenario: Scenario, palette: Any) -> str:
    """What a scenario's library depends on, as a string (inputs only, no computed
    float): palette key, map source, footprint, halving limit, library seed and
    stopping allowance."""
    src = scenario.map_source
    where = json.dumps(src, sort_keys=True) if isinstance(src, dict) else str(src)
    return json.dumps(
        [
            palette.key,
            where,
            repr(scenario.footprint_radius),
            scenario.max_halvings,
            scenario.library_seed,
            repr(scenario.speed_clearance),
        ]
    )


def load_scenario_map(scenario: Scenario) -> Any:
    """The scenario's map; an inline map's error names the scenario and the key path
    under ``map``.

    Raises
    ------
    MapError
    """
    from gracenav.errors import MapError
    from gracenav.world import load_map
    from gracenav.world.occupancy import INLINE

    try:
        return load_map(scenario.map_source)
    except MapError as exc:
        if not isinstance(scenario.map_source, dict):
            raise
        msg = str(exc)
        head = f"{INLINE}: '"
        if msg.startswith(head):
            where = "'map." + msg[len(head) :]
        else:
            where = msg.replace(INLINE, "'map'", 1)
        raise MapError(f"{scenario.source}: {where}") from None


def prepare_library(scenario: Scenario, palette: Any | None = None) -> PreparedLibrary:
    """Check the scenario and build its library and graph.

    Raises
    ------
    ConfigError, MapError, PlanningError
        From the map and :func:`check_scenario`, before the library is built.
    """
    from gracenav.graph import build_graph
    from gracenav.library import build_library
    from gracenav.palette import load_palette

    palette = palette if palette is not None else load_palette()
    world_map = load_scenario_map(scenario)
    check_scenario(scenario, world_map, palette)
    t0 = time.perf_counter()
    library = build_library(
        palette,
        world_map,
        footprint_radius=scenario.footprint_radius,
        max_halvings=scenario.max_halvings,
        seed=scenario.library_seed,
        speed_clearance=scenario.speed_clearance,
    )
    graph = build_graph(library)
    return PreparedLibrary(
        key=library_key(scenario, palette),
        world_map=world_map,
        library=library,
        graph=graph,
        seconds=time.perf_counter() - t0,
    )


def run_scenario(
    scenario: Scenario,
    *,
    palette: Any | None = None,
    params: BallbotParams | None = None,
    progress: Callable[[int, int], None] | None = None,
    prepared: PreparedLibrary | None = None,
) -> ScenarioResult:
    """Build the library on the scenario's map and run every start of its task.

    A scenario with ``planner.kind: decoupled`` runs the plan-then-track baseline
    instead (:func:`gracenav.baseline.run_decoupled`, no library).

    Parameters
    ----------
    scenario : Scenario
    palette : Palette, optional
        Default: the shipped palette.
    params : BallbotParams, optional
        Physical parameters of the simulated robot (default: the palette's), to which
        the scenario's ``simulation.plant_params`` factors then apply (they scale these
        parameters, not the palette's); the controllers keep the palette's design, so
        different values test robustness.
        Each run starts where the controller believes the start is (encoder angles
        times its nominal ball radius); with another ``ball_radius`` the episode's
        position states (the plant's) differ from it by the ratio of the radii.
    progress : callable(done, total), optional
        Called after each run.
    prepared : PreparedLibrary, optional
        The library of an earlier :func:`prepare_library` call for the same map,
        footprint, halvings, library seed and palette (checked by its key); default:
        built here.

    Raises
    ------
    ConfigError, PlanningError
        From :func:`check_scenario`, before the library is built.
    ValueError
        ``prepared`` was built for another map, footprint, palette, library seed or
        stopping allowance.
    """
    from gracenav.execution import HybridController
    from gracenav.palette import load_palette
    from gracenav.sim import make_plant

    palette = palette if palette is not None else load_palette()
    if scenario.planner == "decoupled":
        from gracenav.baseline import run_decoupled

        return run_decoupled(scenario, palette=palette, params=params, progress=progress)
    plant_params = apply_plant_factors(scenario, params if params is not None else palette.params)
    if prepared is None:
        prepared = prepare_library(scenario, palette)
    elif prepared.key != library_key(scenario, palette):
        raise ValueError(
            "prepared library was built for another map, footprint, halving limit, library "
            "seed, speed clearance or palette than this scenario's"
        )
    else:
        check_scenario(scenario, prepared.world_map, palette)
    world_map, library, graph = prepared.world_map, prepared.library, prepared.graph
    options = _execution_options(scenario)
    radius = palette.params.ball_radius  # the controller's: the robot starts where it believes
    probe = HybridController(library, graph, criterion=scenario.cost)
    _check_task(scenario, probe, options)

    def run(x0: np.ndarray) -> Any:
        hc = HybridController(library, graph, criterion=scenario.cost)
        sim = options.simulation
        plant = make_plant(
            scenario.plant,
            plant_params,
            substeps=sim.substeps,
            position_noise_std=sim.position_noise_std,
            velocity_noise_std=sim.velocity_noise_std,
            seed=sim.seed,
        )
        return hc.run(
            x0,
            scenario.goals,
            loops=scenario.loops,
            disturbances=scenario.disturbances,
            options=options,
            moving_obstacles=scenario.moving_obstacles,
            plant=plant,
        )

    episodes, runs = _run_starts(scenario, world_map, plant_params, radius, run, progress)
    return ScenarioResult(
        scenario=scenario,
        episodes=episodes,
        runs=runs,
        library_size=len(library),
        graph_edges=graph.num_edges,
        coverage=float(library.coverage),
        library_seconds=prepared.seconds,
        world_map=world_map,
        library=library,
        plant_params=plant_params,
    )


def _run_starts(
    scenario: Scenario,
    world_map: Any,
    plant_params: BallbotParams,
    radius: float,
    run: Callable[[np.ndarray], Any],
    progress: Callable[[int, int], None] | None,
) -> tuple[tuple[Any, ...], tuple[RunSummary, ...]]:
    """Run every start of the task with ``run`` (plant state (8,) → Episode), each
    starting where the controller believes it is (``radius``: its ball radius, m), and
    summarise the runs on ``world_map`` for ``plant_params``; ``progress`` after each."""
    from gracenav.simulate import state_from_position

    episodes = []
    runs = []
    for i, start in enumerate(scenario.starts):
        ep = run(state_from_position(np.asarray(start), radius))
        episodes.append(ep)
        runs.append(_summarise(ep, start, scenario, world_map, plant_params))
        if progress is not None:
            progress(i + 1, len(scenario.starts))
    return tuple(episodes), tuple(runs)


def _execution_options(scenario: Scenario) -> Any:
    from gracenav.execution import ExecutionOptions

    return ExecutionOptions(
        plant=scenario.plant,
        max_time=scenario.max_time,
        simulation=SimulationOptions(
            position_noise_std=scenario.position_noise_std, seed=scenario.seed
        ),
        resume_from_balancing=scenario.resume_from_balancing,
        capture=scenario.capture,
        sensing=ObstacleSensing(range=scenario.sensing_range),
    )


def check_task(scenario: Scenario, prepared: PreparedLibrary, palette: Any | None = None) -> None:
    """Check that every goal and every start of the scenario's task is possible with the
    library ``prepared`` (as :func:`run_scenario` does before its first run).

    Raises
    ------
    PlanningError
        Naming the key of the first impossible goal or start and why.
    """
    from gracenav.execution import HybridController
    from gracenav.palette import load_palette

    palette = palette if palette is not None else load_palette()
    hc = HybridController(prepared.library, prepared.graph, criterion=scenario.cost)
    _check_task(scenario, hc, _execution_options(scenario))


def _check_task(scenario: Scenario, hc: Any, options: Any) -> None:
    """Every goal and every start must be possible before the first run starts: a bad
    third start should not cost the first two runs. Each start is probed by starting
    the task (:meth:`HybridController.reset`); the message names the key."""
    from gracenav.errors import PlanningError
    from gracenav.simulate import state_from_position

    ptp = scenario.kind == "point_to_point"
    for j, goal in enumerate(scenario.goals):
        try:
            hc.goal_policy(goal)
        except PlanningError as exc:
            key = "task.goal" if ptp else f"task.goals[{j}]"
            raise PlanningError(f"{scenario.source}: '{key}': {exc}") from None
    for i, start in enumerate(scenario.starts):
        x0 = state_from_position(np.asarray(start), hc.gains.params.ball_radius)
        try:
            hc.reset(x0, scenario.goals, options=options)
        except PlanningError as exc:
            key = f"task.starts[{i}]" if ptp else "task.start"
            raise PlanningError(f"{scenario.source}: '{key}': {exc}") from None


def _summarise(
    ep: Any, start: Sequence[float], sc: Scenario, world_map: Any, params: BallbotParams
) -> RunSummary:
    p = ep.position_state
    goal = np.asarray(sc.goals[-1] if sc.kind == "point_to_point" else sc.goals[0])
    jumps = ep.graceful_torque_jumps()
    clearance = world_map.clearance(p[:, :2]) - sc.footprint_radius
    if sc.moving_obstacles:  # at their true positions, tick by tick
        moving = moving_clearance(sc.moving_obstacles, p[:, :2], ep.time) - sc.footprint_radius
        clearance = np.minimum(clearance, moving)
    latencies = [1000.0 * e.latency_s for e in ep.replans]
    touching = np.flatnonzero(clearance < 0.0)
    contact = bool(touching.size)
    return RunSummary(
        start=tuple(float(v) for v in start),
        reached_goal=bool(ep.reached_goal) and not contact,
        stop_reason=ep.status.value,
        time_s=float(ep.time[-1]),
        path_length_m=ep.path_length,
        final_error_m=float(np.linalg.norm(p[-1, :2] - goal[:2]))
        if sc.kind == "point_to_point"
        else None,
        final_speed_mps=float(np.linalg.norm(p[-1, 2:])),
        max_lean_deg=float(np.rad2deg(np.max(np.abs(ep.lean)))),
        max_torque_nm=float(np.max(np.abs(ep.inputs))),
        max_jerk_mps3=_max_jerk(ep, sc.disturbances, params),
        switches=ep.switches,
        non_graceful_switches=ep.non_graceful_switches,
        max_graceful_torque_jump_nm=float(np.max(jumps)) if jumps.size else 0.0,
        min_clearance_m=float(np.min(clearance)),
        goals_reached=len(ep.goals_reached),
        tree_ms=1000.0 * float(np.median(ep.tree_seconds)) if ep.tree_seconds else 0.0,
        contact=contact,
        contact_time_s=float(ep.time[touching[0]]) if contact else None,
        verified_recoveries=ep.verified_recoveries,
        captures=sum(1 for e in ep.events if e.reason.value == "capture"),
        balancing_s=ep.balancing_time,
        replans=len(ep.replans),
        replan_ms_median=float(np.median(latencies)) if latencies else 0.0,
        replan_ms_max=float(np.max(latencies)) if latencies else 0.0,
        blocked_s=ep.blocked_time,
    )


_PUSH_JERK_WINDOW_S = 2.0 / CONTROL_RATE
"""Jerk samples this close (s) to a push are left out of ``max_jerk_mps3``."""


def _max_jerk(ep: Any, disturbances: Sequence[Disturbance], params: BallbotParams) -> float:
    """Largest ball jerk (m/s³) of the run, leaving out the ticks of each push: an
    impulse steps the velocity, an input from outside rather than the robot's motion
    (its jerk is the impulse over a tick squared), which would hide every difference
    between planners."""
    if ep.time.size <= 2:
        return 0.0
    jerk = ep.ball_jerk(params)
    mid = 0.5 * (ep.time[1:] + ep.time[:-1])
    keep = np.ones(jerk.shape, dtype=bool)
    for d in disturbances:
        if isinstance(d, Push):
            keep &= np.abs(mid - d.time) > _PUSH_JERK_WINDOW_S
    return float(np.max(jerk[keep])) if np.any(keep) else 0.0


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
        "speed_clearance_s": sc.speed_clearance,
        "graph_edges": result.graph_edges,
        "coverage": _json_value(result.coverage),
        "library_and_graph_s": result.library_seconds,
        "runs": [r.to_dict() for r in result.runs],
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

    ev = ["run,time,from,to,from_name,to_name,reason,latency_ms"]
    for k, ep in enumerate(result.episodes):
        lines = [
            (
                e.time,
                0,
                f"{k},{e.time:.6f},{e.from_policy},{e.to_policy},{name(e.from_policy)},"
                f"{name(e.to_policy)},{e.reason.value},",
            )
            for e in ep.events
        ]
        lines += [  # replans: reason replan:<why>, and the wall time of the repair
            (rp.time, 1, f"{k},{rp.time:.6f},,,,,replan:{rp.reason},{1000 * rp.latency_s:.3f}")
            for rp in getattr(ep, "replans", ())
        ]
        ev += [line for _, _, line in sorted(lines, key=lambda v: (v[0], v[1]))]
    path = out / "events.csv"
    atomic_write_text(path, "\n".join(ev) + "\n")
    written.append(path)
    written.append(plot_paths(result, out / "paths.png"))
    written.append(plot_lean(result, out / "lean.png"))
    if animation:
        written.append(animate_episode(result, 0, out / "animation.gif"))
    return written
