"""Simulation: the compiled closed loop of the Fig. 2 controllers (single runs and batches),
the disturbances, and the plants (the Plant protocol a per-tick controller drives)."""

from gracenav.sim.closed_loop import (
    DEFAULT_FALL_LEAN,
    BatchResult,
    Reference,
    SimulationOptions,
    SimulationResult,
    StopReason,
    simulate,
    simulate_batch,
)
from gracenav.sim.disturbances import (
    BodyForce,
    Disturbance,
    Drag,
    Push,
    StateJump,
)
from gracenav.sim.plant import (
    CONTROL_RATE,
    DisturbablePlant,
    Model3DPlant,
    MujocoPlant,
    Plant,
    PlantKind,
    make_plant,
)
from gracenav.sim.state import (
    position_state,
    state_from_position,
)

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
    "make_plant",
    "position_state",
    "simulate",
    "simulate_batch",
    "state_from_position",
]
