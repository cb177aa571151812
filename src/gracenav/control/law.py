"""The Fig. 2 control law, one tick at a time: what a robot's control loop evaluates
every 1/1024 s for the reference of the running policy."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from gracenav.control.gains import ControllerGains

__all__ = ["TrackingLaw"]

FloatArray = NDArray[np.float64]


class TrackingLaw:
    """The Fig. 2 cascade (outer position/velocity loop, inner lean loop, friction
    compensation), one control tick at a time, compiled.

    Parameters
    ----------
    gains : ControllerGains
        The controller (its ``params`` are the robot as the controller knows it: the
        radius of the position state and the torque limit it saturates at).

    Notes
    -----
    Calling it with the measured state x (8,), the reference state (8,) and feed-forward
    torque (2,) (N m) of this tick, and optionally an outer domain D'(t) as centre (4,)
    and shape (4, 4) (zero-size arrays for none), returns the saturated torque (2,) and
    the domain value (p − c)ᵀ P (p − c) of the position state p (> 1: outside). With
    ``gains.friction_midpoint`` the reference state of the next tick (``x_next``;
    default: this tick's, a reference at rest) predicts the ball rate the friction is
    fed forward at.
    """

    def __init__(self, gains: ControllerGains) -> None:
        from gracenav.model.ballbot3d import Ballbot3D
        from gracenav.model.friction import friction_constants

        p = gains.params
        self.radius = float(Ballbot3D(p).constants()[0])
        self.friction = friction_constants(p)
        self.k = gains.kernel_arrays()
        self.max_comp = float(gains.max_lean_compensation)
        from gracenav import _kernels

        self.friction_comp = _kernels.friction_mode(
            gains.friction_compensation, gains.friction_midpoint
        )
        self.torque_limit = float(p.torque_limit)
        self._tick = _kernels.tracking_tick

    def __call__(
        self,
        x: FloatArray,
        x_ref: FloatArray,
        tau_ff: FloatArray,
        c: FloatArray,
        shape: FloatArray,
        x_next: FloatArray | None = None,
    ) -> tuple[FloatArray, float]:
        """Saturated torque (2,) and the D'(t) value of ``x`` (0 without a domain)."""
        out = np.empty(2)
        val = self._tick(
            self.radius,
            self.friction,
            self.k,
            self.max_comp,
            self.friction_comp,
            self.torque_limit,
            x,
            x_ref,
            x_ref if x_next is None else x_next,
            tau_ff,
            c,
            shape,
            out,
        )
        return out, float(val)
