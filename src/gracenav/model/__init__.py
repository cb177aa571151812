"""Ballbot dynamic models: planar (IJRR 2014 eqs. 1-5) and full 3D without yaw, and the
physical limits of the motion (top speed, steady acceleration, time bound)."""

from __future__ import annotations

from gracenav.model.ballbot3d import Ballbot3D
from gracenav.model.limits import (
    TimeBound,
    physical_time_bound,
    steady_acceleration,
    top_speed,
)
from gracenav.model.planar import PlanarBallbot

__all__ = [
    "Ballbot3D",
    "PlanarBallbot",
    "TimeBound",
    "physical_time_bound",
    "steady_acceleration",
    "top_speed",
]
