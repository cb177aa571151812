"""Ballbot dynamic models: planar (IJRR 2014 eqs. 1-5) and full 3D without yaw."""

from __future__ import annotations

from gracenav.model.planar import PlanarBallbot

__all__ = ["PlanarBallbot"]
