"""Per-trial inputs drawn from a seed spawned from the campaign seed."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from gracenav.campaign.spec import Campaign

__all__ = ["draw_trial", "trial_scenario"]


def draw_trial(campaign: Campaign, index: int) -> dict[str, Any]:
    """The inputs of trial ``index``: a JSON-ready dict.

    Trial ``index`` uses child ``index`` of ``SeedSequence(campaign.seed)``, so its
    inputs depend on nothing else (not the number of workers, not the order).
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
    inputs["noise_std_m"] = float(campaign.noise_std[int(rng.integers(len(campaign.noise_std)))])
    for name, lo, hi in campaign.plant_params:
        inputs[f"factor_{name}"] = float(rng.uniform(lo, hi))
    return inputs


def trial_scenario(campaign: Campaign, inputs: dict[str, Any]) -> dict[str, Any]:
    """The scenario document of one trial: the base with the drawn inputs applied."""
    doc = copy.deepcopy(campaign.scenario)
    task = doc.get("task", {})
    if isinstance(task, dict) and "starts" in task and task["starts"]:
        task["starts"] = [task["starts"][0]]
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
