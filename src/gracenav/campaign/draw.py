"""Per-trial inputs drawn from a seed spawned from the campaign seed."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gracenav.campaign.spec import Campaign

__all__ = ["MAX_PAIR_ATTEMPTS", "draw_trial", "trial_scenario"]

MAX_PAIR_ATTEMPTS = 1000
"""Most start/goal pairs drawn for one trial before the campaign is refused."""

PairCheck = Callable[[list[float], list[float]], bool]
"""Whether a drawn (start, goal) pair is a possible task: ``(start, goal) -> bool``."""


def _free_cells(scenario: dict[str, Any], clearance: float) -> np.ndarray:
    """Cell centres (m), shape (k, 2), whose clearance is at least ``clearance``."""
    import json

    return _free_cells_cached(json.dumps(scenario.get("map"), sort_keys=True), clearance)


@functools.lru_cache(maxsize=8)
def _free_cells_cached(map_json: str, clearance: float) -> np.ndarray:
    import json

    from gracenav.world import load_map

    m = json.loads(map_json)
    world = load_map(m.get("ros_map", m) if isinstance(m, dict) else m)
    centres = world.cell_centers().reshape(-1, 2)
    ok = world.clearance_grid.reshape(-1) >= clearance
    return np.asarray(centres[ok], dtype=float)


def _draw_pair(
    campaign: Campaign, rng: np.random.Generator, index: int, accept: PairCheck | None
) -> tuple[list[float], list[float], int]:
    from gracenav.errors import ConfigError

    assert campaign.pairs is not None
    clearance, min_dist = campaign.pairs
    cells = _free_cells(campaign.scenario, clearance)
    if len(cells) == 0:
        raise ConfigError(
            f"{campaign.name}: 'pairs.clearance' {clearance:g} m: no free cell of the map "
            "is that far from every obstacle; lower it"
        )
    far = 0
    for attempt in range(1, MAX_PAIR_ATTEMPTS + 1):
        a, b = cells[rng.integers(len(cells), size=2)]
        if float(np.hypot(*(a - b))) < min_dist:
            continue
        far += 1
        start, goal = [float(a[0]), float(a[1])], [float(b[0]), float(b[1])]
        if accept is None or accept(start, goal):
            return start, goal, attempt
    if far == 0:
        raise ConfigError(
            f"{campaign.name}: trial {index}: no start/goal pair at least "
            f"'pairs.min_distance' {min_dist:g} m apart in {MAX_PAIR_ATTEMPTS} draws; lower it"
        )
    raise ConfigError(
        f"{campaign.name}: trial {index}: none of {far} start/goal pairs drawn was a possible "
        "task (start outside coverage or goal too close to an obstacle); raise "
        "'pairs.clearance'"
    )


def draw_trial(campaign: Campaign, index: int, accept: PairCheck | None = None) -> dict[str, Any]:
    """The inputs of trial ``index``: a JSON-ready dict.

    Trial ``index`` uses child ``index`` of ``SeedSequence(campaign.seed)``, so its
    inputs depend on nothing else (not the number of workers, not the order, not the
    planner). Random start/goal pairs are drawn again until ``accept`` takes one (at
    most :data:`MAX_PAIR_ATTEMPTS` draws); ``pair_draws`` records how many it took.

    Raises
    ------
    ConfigError
        No acceptable pair in :data:`MAX_PAIR_ATTEMPTS` draws.
    """
    child = np.random.SeedSequence(campaign.seed).spawn(index + 1)[index]
    rng = np.random.default_rng(child)
    inputs: dict[str, Any] = {"trial": index, "sim_seed": int(rng.integers(0, 2**31 - 1))}
    if campaign.push_impulse is not None:
        mag = float(rng.uniform(*campaign.push_impulse))
        ang = float(rng.uniform(0.0, 2.0 * math.pi))
        inputs["impulse_ns"] = mag
        inputs["impulse_dir_rad"] = ang
        inputs["push_time_s"] = float(rng.uniform(*campaign.push_time))
    if campaign.pairs is not None:
        start, goal, draws = _draw_pair(campaign, rng, index, accept)
        inputs.update(
            start_x=start[0], start_y=start[1], goal_x=goal[0], goal_y=goal[1], pair_draws=draws
        )
    inputs["noise_std_m"] = float(campaign.noise_std[int(rng.integers(len(campaign.noise_std)))])
    for name, lo, hi in campaign.plant_params:
        inputs[f"factor_{name}"] = float(rng.uniform(lo, hi))
    return inputs


def trial_scenario(
    campaign: Campaign, inputs: dict[str, Any], planner: str = "gracenav"
) -> dict[str, Any]:
    """The scenario document of one trial: the base with the drawn inputs and the
    planner (:data:`~gracenav.campaign.spec.PLANNERS`) applied."""
    doc = copy.deepcopy(campaign.scenario)
    plan = dict(doc.get("planner") or {})
    plan["kind"] = "decoupled" if planner == "decoupled" else "gracenav"
    if planner == "gracenav_paper":
        plan["resume_from_balancing"] = False
    doc["planner"] = plan
    task = doc.get("task", {})
    if isinstance(task, dict) and "starts" in task and task["starts"]:
        task["starts"] = [task["starts"][0]]
    if "start_x" in inputs and isinstance(task, dict):
        task["starts"] = [[inputs["start_x"], inputs["start_y"], 0.0, 0.0]]
        task["goal"] = [inputs["goal_x"], inputs["goal_y"], 0.0, 0.0]
    sim = dict(doc.get("simulation") or {})
    sim["seed"] = inputs["sim_seed"]
    sim["position_noise_std"] = inputs["noise_std_m"]
    factors = {k[len("factor_") :]: v for k, v in inputs.items() if k.startswith("factor_")}
    if factors:
        sim["plant_params"] = {**(sim.get("plant_params") or {}), **factors}
    doc["simulation"] = sim
    if "impulse_ns" in inputs:
        mag, ang = inputs["impulse_ns"], inputs["impulse_dir_rad"]
        push = {
            "kind": "push",
            "time": inputs["push_time_s"],
            "impulse": [mag * math.cos(ang), mag * math.sin(ang)],
        }
        doc["disturbances"] = [*(doc.get("disturbances") or []), push]
    return doc
