"""Simulated plants and the Plant protocol a per-tick controller drives."""

from gracenav.sim.plant import (
    CONTROL_RATE,
    DisturbablePlant,
    Model3DPlant,
    MujocoPlant,
    Plant,
    PlantKind,
    make_plant,
)

__all__ = [
    "CONTROL_RATE",
    "DisturbablePlant",
    "Model3DPlant",
    "MujocoPlant",
    "Plant",
    "PlantKind",
    "make_plant",
]
