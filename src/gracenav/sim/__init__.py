"""Simulation: the compiled closed loop of the Fig. 2 controllers (single runs and batches),
the disturbances, and the plants (the Plant protocol a per-tick controller drives).

Names are imported on first use, so ``import gracenav.sim.plant`` (the command line's
plant kinds) does not load the compiled closed loop and scipy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gracenav.control import CONTROL_RATE
    from gracenav.sim.closed_loop import (
        DEFAULT_FALL_LEAN,
        BatchResult,
        Reference,
        SimulationOptions,
        SimulationResult,
        StopReason,
        limit_batch_threads,
        simulate,
        simulate_batch,
    )
    from gracenav.sim.disturbances import BodyForce, Disturbance, Drag, Push, StateJump
    from gracenav.sim.plant import (
        DisturbablePlant,
        Model3DPlant,
        MujocoPlant,
        Plant,
        PlantKind,
        make_plant,
    )
    from gracenav.sim.state import position_state, state_from_position

_LAZY = {
    "BatchResult": "gracenav.sim.closed_loop",
    "BodyForce": "gracenav.sim.disturbances",
    "CONTROL_RATE": "gracenav.control",
    "DEFAULT_FALL_LEAN": "gracenav.sim.closed_loop",
    "DisturbablePlant": "gracenav.sim.plant",
    "Disturbance": "gracenav.sim.disturbances",
    "Drag": "gracenav.sim.disturbances",
    "Model3DPlant": "gracenav.sim.plant",
    "MujocoPlant": "gracenav.sim.plant",
    "Plant": "gracenav.sim.plant",
    "PlantKind": "gracenav.sim.plant",
    "Push": "gracenav.sim.disturbances",
    "Reference": "gracenav.sim.closed_loop",
    "SimulationOptions": "gracenav.sim.closed_loop",
    "SimulationResult": "gracenav.sim.closed_loop",
    "StateJump": "gracenav.sim.disturbances",
    "StopReason": "gracenav.sim.closed_loop",
    "limit_batch_threads": "gracenav.sim.closed_loop",
    "make_plant": "gracenav.sim.plant",
    "position_state": "gracenav.sim.state",
    "simulate": "gracenav.sim.closed_loop",
    "simulate_batch": "gracenav.sim.closed_loop",
    "state_from_position": "gracenav.sim.state",
}

__all__ = [
    "CONTROL_RATE",
    "DEFAULT_FALL_LEAN",
    "BatchResult",
    "BodyForce",
    "DisturbablePlant",
    "Disturbance",
    "Drag",
    "Model3DPlant",
    "MujocoPlant",
    "Plant",
    "PlantKind",
    "Push",
    "Reference",
    "SimulationOptions",
    "SimulationResult",
    "StateJump",
    "StopReason",
    "limit_batch_threads",
    "make_plant",
    "position_state",
    "simulate",
    "simulate_batch",
    "state_from_position",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'gracenav.sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
