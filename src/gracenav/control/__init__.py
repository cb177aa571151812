"""Balancing and tracking controllers of the paper's Fig. 2: gains, the control rate, the
per-tick law.
"""

from gracenav.control.gains import (
    CONTROL_RATE,
    ControllerGains,
    LQRWeights,
    design_gains,
    lqr,
    planar_to_position_coordinates,
)

__all__ = [
    "CONTROL_RATE",
    "ControllerGains",
    "LQRWeights",
    "design_gains",
    "lqr",
    "planar_to_position_coordinates",
]
