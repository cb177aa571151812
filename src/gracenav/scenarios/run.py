"""Running a scenario: its library prepared once, every start run by the hybrid
controller (or the decoupled baseline, :mod:`gracenav.scenarios.decoupled`)."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from gracenav.errors import PlanningError
from gracenav.params import BallbotParams
from gracenav.planning.repair import ObstacleSensing
from gracenav.scenarios import region as region_module
from gracenav.scenarios.region import resolve_region, task_region, task_waypoints
from gracenav.scenarios.runs import ScenarioResult, _run_starts
from gracenav.scenarios.spec import (
    Scenario,
    _check_task_bounds,
    _check_task_states,
    apply_plant_factors,
    check_scenario,
    load_scenario_map,
)
from gracenav.sim import SimulationOptions

__all__ = ["PreparedLibrary", "check_task", "library_key", "prepare_library", "run_scenario"]


@dataclass(frozen=True)
class PreparedLibrary:
    """A scenario's map, policy library and prepares graph, built once and shared by
    runs that differ only in their task, disturbances or simulation (campaign trials).

    Attributes
    ----------
    key : str
        What the library depends on: the palette's key, the map, the footprint, the
        halving limit, the memory budget and the library seed (:func:`library_key`).
    world_map, library, graph
    seconds : float
        Wall time of building the library and the graph (s).
    max_halvings : int
        The halvings the library was allowed (``planner.max_halvings``, or chosen within
        the memory budget by :func:`check_scenario`).
    region : {"map", "task"}
        Where the library was built (``planner.region`` resolved on the map,
        :mod:`gracenav.scenarios.region`); the library's own ``world_map`` is then the
        task's region, while ``world_map`` stays the whole map (what the runs are
        measured against).
    """

    key: str
    world_map: Any = field(repr=False)
    library: Any = field(repr=False)
    graph: Any = field(repr=False)
    seconds: float
    max_halvings: int = 0
    region: Literal["map", "task"] = "map"


def library_key(scenario: Scenario, palette: Any) -> str:
    """What a scenario's library depends on, as a string (inputs only, no computed
    float): palette key, map source, footprint, halving limit (None: chosen within the
    memory budget, which then counts too), library seed, stopping allowance, design
    push (when there is one) and region (with the task's positions and the margin
    unless it is the whole map)."""
    src = scenario.map_source
    where = json.dumps(src, sort_keys=True) if isinstance(src, dict) else str(src)
    region: list[Any] = [scenario.region]
    if scenario.region != "map":
        region += [repr(scenario.region_margin), task_waypoints(scenario).tolist()]
    anchor = lattice_anchor(scenario)
    if anchor is not None:
        region += ["anchor", [repr(float(v)) for v in anchor]]
    return json.dumps(
        [
            *region,
            palette.key,
            where,
            repr(scenario.footprint_radius),
            scenario.max_halvings,
            scenario.library_seed,
            repr(scenario.speed_clearance),
            *([] if scenario.design_push == 0.0 else ["design_push", repr(scenario.design_push)]),
            *([] if scenario.max_halvings is not None else [repr(scenario.memory_limit)]),
        ]
    )


def prepare_library(scenario: Scenario, palette: Any | None = None) -> PreparedLibrary:
    """Check the scenario and build its library and graph, with the halvings
    :func:`check_scenario` allows within the scenario's memory budget (which takes the
    place of :func:`~gracenav.library.build_library`'s own, smaller-scoped check).

    Raises
    ------
    ConfigError, MapError, PlanningError
        From the map and :func:`check_scenario`, before the library is built.
    """
    from gracenav.library import build_library
    from gracenav.palette import load_palette
    from gracenav.planning.graph import build_graph

    palette = palette if palette is not None else load_palette()
    world_map = load_scenario_map(scenario)
    region: Literal["map", "task"] = resolve_region(scenario, world_map)
    where = world_map
    if region == "task":
        _check_task_bounds(scenario, world_map)
        found = task_region(
            world_map,
            task_waypoints(scenario),
            footprint_radius=scenario.footprint_radius,
            margin=scenario.region_margin,
            d=palette.d,
        )
        # No path through the task: the whole map's checks say why.
        where, region = (world_map, "map") if found is None else (found, "task")
    # Within the region the checks see what they see in the whole map: its edge is at
    # least region_margin >= footprint + 1 m from every start and goal.
    cap = region_module.REGION_POLICIES if region == "task" else None
    halvings = check_scenario(scenario, where, palette, whole_map=world_map, policy_cap=cap)
    t0 = time.perf_counter()
    library = build_library(
        palette,
        where,
        footprint_radius=scenario.footprint_radius,
        max_halvings=halvings,
        seed=scenario.library_seed,
        speed_clearance=scenario.speed_clearance,
        design_push=scenario.design_push,
        memory_limit=None,
        anchor=lattice_anchor(scenario),
    )
    graph = build_graph(library)
    return PreparedLibrary(
        key=library_key(scenario, palette),
        world_map=world_map,
        library=library,
        graph=graph,
        seconds=time.perf_counter() - t0,
        max_halvings=halvings,
        region=region,
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
    instead (:func:`gracenav.scenarios.decoupled.run_decoupled`, no library).

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
        footprint, halvings (or memory budget), library seed and palette (checked by its
        key); default: built here.

    Raises
    ------
    ConfigError, PlanningError
        From :func:`check_scenario`, before the library is built.
    ValueError
        ``prepared`` was built for another map, footprint, halving limit, memory budget,
        palette, library seed or stopping allowance.
    """
    from gracenav.execution import HybridController
    from gracenav.palette import load_palette

    palette = palette if palette is not None else load_palette()
    if scenario.planner == "decoupled":
        from gracenav.scenarios.decoupled import run_decoupled

        return run_decoupled(scenario, palette=palette, params=params, progress=progress)
    plant_params = apply_plant_factors(scenario, params if params is not None else palette.params)
    if prepared is None:
        prepared = prepare_library(scenario, palette)
    elif prepared.key != library_key(scenario, palette):
        raise ValueError(
            "prepared library was built for another map, footprint, halving limit, memory "
            "budget, library seed, speed clearance or palette than this scenario's"
        )
    else:  # the memory budget was checked when it was prepared (the key holds it)
        _check_task_states(scenario, prepared.world_map, palette)
    options = _execution_options(scenario)
    prepared = _checked(scenario, prepared, palette, options)
    world_map, library, graph = prepared.world_map, prepared.library, prepared.graph
    radius = palette.params.ball_radius  # the controller's: the robot starts where it believes

    def run(x0: np.ndarray) -> Any:
        hc = HybridController(library, graph, criterion=scenario.cost)
        sim = options.simulation
        plant = sim.plant(scenario.plant, plant_params)
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


def _checked(
    scenario: Scenario, prepared: PreparedLibrary, palette: Any, options: Any
) -> PreparedLibrary:
    """``prepared`` once the task is checked possible with it (:func:`_check_task`); a
    task impossible in its region under ``planner.region: auto`` is prepared and
    checked again on the whole map, whose library is returned.

    Raises
    ------
    PlanningError
        For a task the library (the whole map's, for ``auto``) cannot do.
    """
    try:
        _check_task(scenario, _probe(prepared, scenario), options)
    except PlanningError:
        if scenario.lattice_anchor == "auto" and lattice_anchor(scenario) is not None:
            # Impossible on the goal's lattice: the map's lattice (in the same region
            # first) decides.
            return _checked(
                dataclasses.replace(scenario, lattice_anchor="map"),
                prepare_library(dataclasses.replace(scenario, lattice_anchor="map"), palette),
                palette,
                options,
            )
        if not (prepared.region == "task" and scenario.region == "auto"):
            raise
        # A route the region leaves out: the whole map decides.
        prepared = prepare_library(dataclasses.replace(scenario, region="map"), palette)
        _check_task(scenario, _probe(prepared, scenario), options)
    return prepared


def lattice_anchor(scenario: Scenario) -> tuple[float, float] | None:
    """The point the scenario's instantiation lattice passes through
    (``planner.lattice_anchor``): the goal of a point-to-point task under ``goal``, and
    under ``auto`` when the task has no moving obstacles (the other ends of the way a
    parked cart leaves are the terminals of a goal off the lattice); else None (the
    map's minimum corner)."""
    if scenario.lattice_anchor == "map" or scenario.kind != "point_to_point":
        return None
    if scenario.lattice_anchor == "auto" and scenario.moving_obstacles:
        return None
    g = scenario.goals[0]
    return (float(g[0]), float(g[1]))


def _probe(prepared: PreparedLibrary, scenario: Scenario) -> Any:
    """A controller on the prepared library to check the task with."""
    from gracenav.execution import HybridController

    return HybridController(prepared.library, prepared.graph, criterion=scenario.cost)


def _execution_options(scenario: Scenario) -> Any:
    from gracenav.execution import ExecutionOptions

    return ExecutionOptions(
        plant=scenario.plant,
        max_time=scenario.max_time,
        simulation=SimulationOptions(
            position_noise_std=scenario.position_noise_std,
            velocity_noise_std=scenario.velocity_noise_std,
            seed=scenario.seed,
        ),
        resume_from_balancing=scenario.resume_from_balancing,
        capture=scenario.capture,
        sensing=ObstacleSensing(range=scenario.sensing_range),
        online_starts=scenario.online_starts,
        online_ends=scenario.online_ends,
        position_filter=scenario.position_filter,
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
    the task (:meth:`HybridController.reset`); the message names the key.

    The probe designs nothing online: an end designed online never makes a task
    possible, and a start designed online only where nothing else serves the start, so
    a start is probed with online starts only if it is impossible without them (a
    campaign's draws are checked here, most of them refused)."""
    from gracenav.errors import PlanningError
    from gracenav.sim import state_from_position

    bare = dataclasses.replace(options, online_starts=False, online_ends=False)

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
            try:
                hc.reset(x0, scenario.goals, options=bare)
            except PlanningError:
                if not options.online_starts:
                    raise
                hc.reset(x0, scenario.goals, options=dataclasses.replace(bare, online_starts=True))
        except PlanningError as exc:
            key = f"task.starts[{i}]" if ptp else "task.start"
            raise PlanningError(f"{scenario.source}: '{key}': {exc}") from None
