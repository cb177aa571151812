"""A point-to-point scenario run with the decoupled baseline instead of the library."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from gracenav.baseline.options import DecoupledOptions, motion_limits
from gracenav.baseline.path import grid_path
from gracenav.baseline.tracking import track_decoupled
from gracenav.errors import ConfigError, PlanningError
from gracenav.params import BallbotParams

if TYPE_CHECKING:
    from gracenav.execution import Episode
    from gracenav.palette import Palette
    from gracenav.scenarios.runs import ScenarioResult
    from gracenav.scenarios.spec import Scenario

__all__ = ["run_decoupled"]


def run_decoupled(
    scenario: Scenario,
    *,
    palette: Palette | None = None,
    params: BallbotParams | None = None,
    progress: Callable[[int, int], None] | None = None,
    options: DecoupledOptions | None = None,
) -> ScenarioResult:
    """Run a point-to-point scenario with the decoupled baseline instead of the library.

    Same map loading and checks, plant (``params`` with the scenario's plant factors),
    disturbances, noise, seed, ``max_time``, goal tolerance and run summaries as
    :func:`gracenav.scenarios.run_scenario`, so the metrics compare one to one. The
    result has no library (``library=None``, size 0, 0 edges, coverage NaN);
    ``library_seconds`` is the median planning time of the first plans (s) and
    ``tree_ms`` of each run the median planning time of its plans.

    Raises
    ------
    ConfigError
        For a surveillance task (the baseline does point-to-point only), and as
        :func:`~gracenav.scenarios.check_scenario`.
    PlanningError
        As :func:`~gracenav.scenarios.check_scenario`, and for a goal no collision-free
        path reaches from a start (naming the key).
    """
    from gracenav.execution import ExecutionOptions
    from gracenav.palette import load_palette
    from gracenav.scenarios.runs import ScenarioResult, _run_starts
    from gracenav.scenarios.spec import apply_plant_factors, check_scenario, load_scenario_map
    from gracenav.sim import SimulationOptions

    if scenario.kind != "point_to_point":
        raise ConfigError(
            f"{scenario.source}: 'task.kind' surveillance is not supported by the decoupled "
            "baseline (point-to-point only); use the gracenav planner for surveillance"
        )
    palette = palette if palette is not None else load_palette()
    plant_params = apply_plant_factors(scenario, params if params is not None else palette.params)
    if scenario.moving_obstacles:
        raise ConfigError(
            f"{scenario.source}: 'moving_obstacles' are not supported by the decoupled "
            "baseline (it plans once on the static map); use the gracenav planner"
        )
    world_map = load_scenario_map(scenario)
    check_scenario(scenario, world_map, palette)
    options = options if options is not None else DecoupledOptions()
    if not scenario.position_filter:
        options = dataclasses.replace(options, position_filter=False)
    limits = motion_limits(palette, options)
    sim = SimulationOptions(
        position_noise_std=scenario.position_noise_std,
        velocity_noise_std=scenario.velocity_noise_std,
        seed=scenario.seed,
    )
    tolerance = ExecutionOptions().goal_tolerance
    radius = palette.params.ball_radius
    goal = scenario.goals[0]
    for i, start in enumerate(scenario.starts):  # every start plannable before any run
        try:
            grid_path(world_map, start[:2], goal[:2], scenario.footprint_radius)
        except PlanningError as exc:
            raise PlanningError(f"{scenario.source}: 'task.starts[{i}]': {exc}") from None
    first_plan: list[float] = []  # planning time (s) of each run's first plan

    def run(x0: np.ndarray) -> Episode:
        ep, plans = track_decoupled(
            world_map,
            x0,
            goal,
            footprint_radius=scenario.footprint_radius,
            gains=palette.gains,
            limits=limits,
            plant_params=plant_params,
            plant=scenario.plant,
            disturbances=scenario.disturbances,
            max_time=scenario.max_time,
            goal_tolerance=tolerance,
            simulation=sim,
            options=options,
        )
        first_plan.append(plans[0].seconds if plans else 0.0)
        return ep

    episodes, runs = _run_starts(scenario, world_map, plant_params, radius, run, progress)
    return ScenarioResult(
        scenario=scenario,
        episodes=episodes,
        runs=runs,
        library_size=0,
        graph_edges=0,
        coverage=float("nan"),
        library_seconds=float(np.median(first_plan)),
        world_map=world_map,
        library=None,
        plant_params=plant_params,
    )
