"""Ballbot dynamic models: planar (IJRR 2014 eqs. 1-5) and full 3D without yaw."""

from __future__ import annotations

from gracenav.model.ballbot3d import Ballbot3D
from gracenav.model.planar import PlanarBallbot

__all__ = ["Ballbot3D", "PlanarBallbot"]
