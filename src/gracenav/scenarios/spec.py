"""Scenario files: the :class:`Scenario` description, its parsing and checks, and the
limits a scenario is held to."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from gracenav._util.io import load_document
from gracenav._util.validate import Fields, require_mapping
from gracenav.errors import ConfigError
from gracenav.library import (
    DEFAULT_DESIGN_PUSH,
    DEFAULT_SPEED_CLEARANCE,
    MAX_DESIGN_PUSH,
    MAX_SPEED_CLEARANCE,
)
from gracenav.params import BallbotParams
from gracenav.planning.graph import CostCriterion, CostName
from gracenav.planning.repair import ObstacleSensing
from gracenav.scenarios.budget import (
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MEMORY_LIMIT_GIB,
    GIB,
    MAX_MEMORY_LIMIT_GIB,
    choose_halvings,
)
from gracenav.scenarios.region import DEFAULT_REGION_MARGIN, REGIONS
from gracenav.sim import Disturbance, Drag, Push
from gracenav.sim.plant import PLANT_KINDS, PlantKind
from gracenav.world.moving import MovingObstacle

__all__ = [
    "PLANNERS",
    "Scenario",
    "apply_plant_factors",
    "check_scenario",
    "load_scenario",
    "load_scenario_map",
    "parse_scenario",
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
    max_halvings : int or None
        Coverage refinement limit for the library (``planner.max_halvings``); None: the
        most, up to :data:`~gracenav.scenarios.budget.DEFAULT_MAX_HALVINGS`, that fit
        ``memory_limit`` (:func:`check_scenario` chooses).
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
    velocity_noise_std : float
        ``simulation.velocity_noise_std``: white noise on the measured ball velocity
        (m/s; default 0), which the position filter is also tuned to.
    max_time : float
        (s)
    source : str
    position_filter : bool
        ``simulation.position_filter``: both planners act on the ball position a
        steady-state Kalman filter estimates, tuned to ``position_noise_std``
        (:class:`gracenav.control.PositionEstimator`; with no noise the measurement
        passes through unchanged); default true.
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
        contains (:mod:`gracenav.execution.capture`; default true).
    library_seed : int
        Seed of the library's coverage samples (``planner.seed``), apart from the
        simulation's seed, so that trials with different noise share one library.
    speed_clearance : float
        ``planner.speed_clearance``: the library's stopping allowance (s; see
        :func:`gracenav.library.build_library`).
    design_push : float
        ``planner.design_push``: the push (N s) the library keeps room to catch where
        it moves faster than 0.8 m/s (0: none; default
        :data:`gracenav.library.DEFAULT_DESIGN_PUSH`, 8 N s; see
        :func:`gracenav.library.build_library`).
    moving_obstacles : tuple of MovingObstacle
        Obstacles not in the map, learned within ``sensing_range`` (m) of the robot.
    sensing_range : float
        (m), ``robot.sensing_range``.
    memory_limit : float
        Memory budget of a run (bytes; ``planner.memory_limit_gib`` in GiB): a library
        whose estimated peak would exceed it is refused before it is built
        (:mod:`gracenav.scenarios.budget`).
    region : {"auto", "map", "task"}
        ``planner.region``: where the library is built: the whole map, the task's region
        (within ``region_margin`` of the footprint's shortest paths through the task),
        or ``auto``: the task's region on maps larger than
        :data:`~gracenav.scenarios.region.AUTO_REGION_AREA`, falling back to the whole
        map when the task is impossible in it (:mod:`gracenav.scenarios.region`).
    region_margin : float
        ``planner.region_margin`` (m).
    lattice_anchor : {"auto", "goal", "map"}
        ``planner.lattice_anchor``: where the instantiation lattice is anchored: the
        map's minimum corner, or the goal (a rest goal of a point-to-point task is then
        a lattice point, reached by the library's own rest trims, with no terminal);
        ``auto`` is ``goal`` for point-to-point tasks without moving obstacles, falling
        back to the map's corner when the task is impossible on the goal's lattice, and
        ``map`` otherwise.
    online_starts : bool
        ``planner.online_starts``: a start at rest may take one maneuver designed and
        verified at the start onto the lattice
        (:attr:`gracenav.execution.ExecutionOptions.online_starts`); on by default.
    online_ends : bool
        ``planner.online_ends``: a single goal at rest may be reached through one
        maneuver designed and verified when the task starts, from a moving policy on
        the way straight to rest at the goal
        (:attr:`gracenav.execution.ExecutionOptions.online_ends`); on by default.
    """

    name: str
    map_source: dict[str, Any] | Path
    footprint_radius: float
    cost: CostName
    max_halvings: int | None
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
    position_filter: bool = True
    plant_factors: tuple[tuple[str, float], ...] = ()
    planner: Literal["gracenav", "decoupled"] = "gracenav"
    resume_from_balancing: bool = True
    capture: bool = True
    library_seed: int = 0
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE
    design_push: float = DEFAULT_DESIGN_PUSH
    moving_obstacles: tuple[MovingObstacle, ...] = ()
    sensing_range: float = 3.0
    memory_limit: float = DEFAULT_MEMORY_LIMIT_GIB * GIB
    region: Literal["auto", "map", "task"] = "auto"
    region_margin: float = DEFAULT_REGION_MARGIN
    lattice_anchor: Literal["auto", "goal", "map"] = "auto"
    online_starts: bool = True
    online_ends: bool = True
    velocity_noise_std: float = 0.0


#: ``planner.lattice_anchor`` values (see :class:`Scenario`).
LATTICE_ANCHORS = ("auto", "goal", "map")

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

MAX_COORDINATE = 1.0e4
"""Largest |entry| of a start or goal state (m, m/s)."""

MAX_IMPULSE_NS = 1000.0
"""Largest push impulse per axis (N s); the robot falls from far less
(docs/design/conventions.md, Falls)."""

MAX_DRAG_SPEED_MPS = 10.0
"""Largest drag velocity per axis (m/s)."""

MAX_FOOTPRINT_M = 5.0
"""Largest footprint radius (m)."""

MIN_REGION_MARGIN = 1.0
"""Smallest ``planner.region_margin`` (m): more than the footprint and a push's stopping
distance, so that checks at the task's positions and catches near the path see the
region as they would see the whole map."""

MAX_NOISE_STD_M = 1.0
"""Largest position noise standard deviation (m)."""

MAX_VELOCITY_NOISE_STD_MPS = 1.0
"""Largest velocity noise standard deviation (m/s)."""

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
            "design_push",
            "memory_limit_gib",
            "region",
            "region_margin",
            "lattice_anchor",
            "online_starts",
            "online_ends",
        }
    )
    planner_kind = planner.choice("kind", PLANNERS, "gracenav")
    cost = planner.choice("cost", [c.value for c in CostCriterion], "time")
    halvings = (
        planner.integer("max_halvings", maximum=20) if "max_halvings" in planner.data else None
    )
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
    design_push = planner.number(
        "design_push", DEFAULT_DESIGN_PUSH, minimum=0.0, maximum=MAX_DESIGN_PUSH, unit="N s"
    )
    memory_gib = planner.number(
        "memory_limit_gib",
        DEFAULT_MEMORY_LIMIT_GIB,
        positive=True,
        maximum=MAX_MEMORY_LIMIT_GIB,
        unit="GiB",
    )
    region = planner.choice("region", REGIONS, "auto")
    lattice_anchor = planner.choice("lattice_anchor", LATTICE_ANCHORS, "auto")
    online_starts = planner.boolean("online_starts", True)
    online_ends = planner.boolean("online_ends", True)
    region_margin = planner.number(
        "region_margin",
        DEFAULT_REGION_MARGIN,
        positive=True,
        maximum=MAX_COORDINATE,
        unit="m",
    )
    if region_margin < footprint + MIN_REGION_MARGIN:
        raise planner.fail(
            f"'planner.region_margin' {region_margin:g} m must be at least the footprint "
            f"radius plus {MIN_REGION_MARGIN:g} m ({footprint + MIN_REGION_MARGIN:g} m): the "
            "region must hold the robot and its catches around the path"
        )
    sim = top.sub("simulation", {})
    sim.check_keys(
        {
            "plant",
            "seed",
            "position_noise_std",
            "velocity_noise_std",
            "position_filter",
            "max_time",
            "plant_params",
        }
    )
    plant = sim.choice("plant", PLANT_KINDS, "model3d")
    plant_factors = _plant_factors(sim)
    noise = sim.number("position_noise_std", 0.0, minimum=0.0, maximum=MAX_NOISE_STD_M, unit="m")
    velocity_noise = sim.number(
        "velocity_noise_std", 0.0, minimum=0.0, maximum=MAX_VELOCITY_NOISE_STD_MPS, unit="m/s"
    )
    seed = sim.integer("seed", 0, maximum=2**32 - 1)
    position_filter = sim.boolean("position_filter", True)
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
        velocity_noise_std=velocity_noise,
        position_filter=position_filter,
        max_time=max_time,
        source=source,
        plant_factors=plant_factors,
        planner=planner_kind,  # type: ignore[arg-type]
        resume_from_balancing=resume,
        capture=capture,
        library_seed=library_seed,
        speed_clearance=speed_clearance,
        design_push=design_push,
        memory_limit=memory_gib * GIB,
        region=region,  # type: ignore[arg-type]
        region_margin=region_margin,
        lattice_anchor=lattice_anchor,  # type: ignore[arg-type]
        online_starts=online_starts,
        online_ends=online_ends,
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


def check_scenario(
    scenario: Scenario,
    world_map: Any,
    palette: Any,
    *,
    whole_map: Any = None,
    policy_cap: float | None = None,
) -> int:
    """Check a scenario against its loaded map and the palette before any heavy work,
    and choose its library's halvings.

    Refuses a library whose estimated peak memory would exceed the scenario's budget
    (``planner.memory_limit_gib``; :func:`~gracenav.scenarios.budget.choose_halvings`),
    surveillance loops that cannot fit in ``max_time``, and starts or goals outside the
    map or in an obstacle.

    ``world_map`` is the map the library is built on; ``whole_map``, when that is a
    region of it (:mod:`gracenav.scenarios.region`), the map whose cells the run holds
    too; ``policy_cap``: see :func:`~gracenav.scenarios.budget.choose_halvings`.

    Returns
    -------
    int
        The halvings of the library: ``planner.max_halvings``, or without it the most,
        up to :data:`~gracenav.scenarios.budget.DEFAULT_MAX_HALVINGS`, that fit the
        budget. (The decoupled baseline builds no library and has no memory check.)

    Raises
    ------
    ConfigError
        For an over-budget scenario; the message gives the estimate, the budget and
        what to do.
    PlanningError
        For a start or goal outside the map or in an obstacle.
    """
    given = scenario.max_halvings
    halvings = DEFAULT_MAX_HALVINGS if given is None else given
    if scenario.planner == "gracenav":
        halvings = choose_halvings(
            world_map,
            palette,
            max_halvings=given,
            memory_limit=scenario.memory_limit,
            footprint_radius=scenario.footprint_radius,
            speed_clearance=scenario.speed_clearance,
            design_push=scenario.design_push,
            source=scenario.source,
            whole_map=whole_map,
            policy_cap=policy_cap,
        ).halvings
    _check_task_states(scenario, world_map, palette)
    return halvings


def _check_task_states(scenario: Scenario, world_map: Any, palette: Any) -> None:
    """:func:`check_scenario` without the memory budget: surveillance loops within
    ``max_time``, starts and goals inside the map and clear of obstacles."""
    from gracenav.errors import PlanningError

    src = scenario.source
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
    for key, state in _task_states(scenario):
        x, y = state[0], state[1]
        _check_inside(scenario, world_map, key, x, y)
        if float(world_map.clearance(np.array([[x, y]]))[0]) < footprint:
            raise PlanningError(
                f"{src}: '{key}' ({x:g}, {y:g}) is inside an obstacle or closer to one (or "
                f"to the map edge) than the robot's footprint radius {footprint:g} m"
            )


def _task_states(scenario: Scenario) -> list[tuple[str, tuple[float, ...]]]:
    """The task's starts and goals with their keys."""
    named = [(f"task.starts[{i}]", s) for i, s in enumerate(scenario.starts)]
    if scenario.kind == "surveillance":
        named = [("task.start", scenario.starts[0])]
    named += [
        ("task.goal" if scenario.kind == "point_to_point" else f"task.goals[{i}]", g)
        for i, g in enumerate(scenario.goals)
    ]
    return named


def _check_inside(scenario: Scenario, world_map: Any, key: str, x: float, y: float) -> None:
    from gracenav.errors import PlanningError

    (x0, y0), (x1, y1) = world_map.bounds
    if not (x0 <= x <= x1 and y0 <= y <= y1):
        raise PlanningError(
            f"{scenario.source}: '{key}' ({x:g}, {y:g}) is outside the map [{x0:g}, {x1:g}] × "
            f"[{y0:g}, {y1:g}]"
        )


def _check_task_bounds(scenario: Scenario, world_map: Any) -> None:
    """The task's starts and goals inside the map (nothing computed on the grid)."""
    for key, state in _task_states(scenario):
        _check_inside(scenario, world_map, key, state[0], state[1])


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
