"""Balancing and tracking controllers of the paper's Fig. 2: their gains
(:mod:`~gracenav.control.gains`), the control rate, the law evaluated every tick
(:class:`TrackingLaw`), and the ball position it acts on (:class:`PositionEstimator`)."""

from gracenav.control.estimation import PositionEstimator
from gracenav.control.gains import (
    CONTROL_RATE,
    ControllerGains,
    LQRWeights,
    design_gains,
    lqr,
    planar_to_position_coordinates,
)
from gracenav.control.law import TrackingLaw

__all__ = [
    "CONTROL_RATE",
    "ControllerGains",
    "LQRWeights",
    "PositionEstimator",
    "TrackingLaw",
    "design_gains",
    "lqr",
    "planar_to_position_coordinates",
]
