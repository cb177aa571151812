"""Named indices of the 3D model's configuration and state vectors.

Configuration q = [θ_x, θ_y, φ_x, φ_y]; state x = [q, q̇] (positions before
velocities); input τ = [τ_x, τ_y]. See docs/design/conventions.md for the conventions.
"""

from __future__ import annotations

__all__ = [
    "NQ",
    "NU",
    "NX",
    "PHI",
    "PHI_X",
    "PHI_X_DOT",
    "PHI_Y",
    "PHI_Y_DOT",
    "POSITION_STATE_NAMES",
    "STATE_NAMES",
    "THETA",
    "THETA_X",
    "THETA_X_DOT",
    "THETA_Y",
    "THETA_Y_DOT",
]

NQ = 4
NX = 8
NU = 2

THETA_X, THETA_Y, PHI_X, PHI_Y = 0, 1, 2, 3
THETA_X_DOT, THETA_Y_DOT, PHI_X_DOT, PHI_Y_DOT = 4, 5, 6, 7

THETA = slice(0, 2)
PHI = slice(2, 4)

STATE_NAMES = (
    "theta_x",
    "theta_y",
    "phi_x",
    "phi_y",
    "theta_x_dot",
    "theta_y_dot",
    "phi_x_dot",
    "phi_y_dot",
)
POSITION_STATE_NAMES = ("x", "y", "xdot", "ydot")
