"""The ball position the controllers act on, estimated from a noisy position sensor and
the measured ball rates: a steady-state Kalman filter per axis.

A ballbot measures its ball's rates well (motor encoders) and its position less well
(odometry corrected by localisation). The tracking law multiplies the position error by
its gains every tick, so white noise on the position reaches the torque, the lean and
the domain tests unfiltered: at 1024 Hz, 5 mm of it makes the state leave the small
start and goal domains of fine copies, whose catches jerk the ball (random pairs with
5 mm of noise: 19 domain exits in 103 trials). The filter predicts the ball angle θ
from the last estimate and the measured rates (trapezoidal rule over the control
period) and corrects it by the measurement with the steady-state gain

K = P⁻ / (P⁻ + R), P⁻ = (Q + √(Q² + 4 Q R)) / 2,

the fixed point of the Riccati recursion of the random walk θₖ₊₁ = θₖ + Δₖ + wₖ measured
as zₖ = θₖ + vₖ: R = (σ_p / r)² the position noise's variance, Q = (σ_v Δt / r)² +
(δ / r)² Δt what the integrated rates miss over a period (rate noise σ_v, and a drift
δ of the rolling ball's odometry, in m/√s). The rates, the lean and the lean rates pass
through as measured. With no position noise K = 1 and the measurement passes through
unchanged, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError

__all__ = ["DEFAULT_DRIFT", "PositionEstimator", "steady_state_gain"]

FloatArray = NDArray[np.float64]

#: Odometry drift (m/√s) the filter allows the integrated rates: about 5 mm over a
#: second of rolling; with 5 mm of position noise at 1024 Hz it gives K = 0.031 (a time
#: constant of 32 ms) and leaves 0.63 mm of the noise when the rates are exact.
DEFAULT_DRIFT = 0.005


def steady_state_gain(measurement_var: float, process_var: float) -> float:
    """The steady-state Kalman gain of a scalar random walk with process variance
    ``process_var`` per step, measured every step with variance ``measurement_var``
    (1 when the measurement is exact, 0 when the walk is)."""
    if measurement_var < 0.0 or process_var < 0.0:
        raise ConfigError("variances must be non-negative")
    if measurement_var == 0.0:
        return 1.0
    q, r = process_var, measurement_var
    prior = 0.5 * (q + math.sqrt(q * q + 4.0 * q * r))
    return prior / (prior + r)


class PositionEstimator:
    """The ball angles (hence position) a controller acts on: a steady-state Kalman
    filter of the measured ball angles with the measured ball rates as its input
    (module docstring). States follow :class:`gracenav.model.Ballbot3D` (θ at 0:2, θ̇
    at 4:6).

    Parameters
    ----------
    ball_radius : float
        (m)
    dt : float
        Control period (s): one :meth:`update` per tick.
    position_std : float
        Standard deviation (m) of the white noise on the measured ball position.
    rate_std : float
        Standard deviation (m/s) of the white noise on the measured ball velocity.
    drift : float
        Odometry drift (m/√s) allowed the integrated rates; > 0.

    Raises
    ------
    ConfigError
        A radius, period or drift that is not positive, or a negative noise.
    """

    def __init__(
        self,
        ball_radius: float,
        dt: float,
        position_std: float = 0.0,
        rate_std: float = 0.0,
        drift: float = DEFAULT_DRIFT,
    ) -> None:
        for name, value in (("ball_radius", ball_radius), ("dt", dt), ("drift", drift)):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"PositionEstimator: {name} must be positive, got {value!r}")
        for name, value in (("position_std", position_std), ("rate_std", rate_std)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(
                    f"PositionEstimator: {name} must be a non-negative standard deviation "
                    f"(m or m/s), got {value!r}"
                )
        self.dt = float(dt)
        r = float(ball_radius)
        self.measurement_var = (position_std / r) ** 2
        self.process_var = (rate_std * dt / r) ** 2 + (drift / r) ** 2 * dt
        #: The gain (1: the measurement passes through).
        self.gain = steady_state_gain(self.measurement_var, self.process_var)
        self._angle: FloatArray | None = None
        self._rate = np.zeros(2)

    @property
    def passes_through(self) -> bool:
        """True when the measurement is exact and returned unchanged."""
        return self.gain == 1.0

    @property
    def error_std(self) -> float:
        """The steady-state standard deviation (rad) of the estimated ball angle's error
        after each correction, √((1 − K) P⁻)."""
        k = self.gain
        if k == 1.0:
            return 0.0
        prior = k * self.measurement_var / (1.0 - k)
        return math.sqrt((1.0 - k) * prior)

    def reset(self, x: ArrayLike) -> FloatArray:
        """Start from the measured state ``x`` (returned as the first estimate)."""
        y = np.asarray(x, dtype=float)
        self._angle = y[0:2].copy()
        self._rate = y[4:6].copy()
        return y

    def update(self, x: ArrayLike) -> FloatArray:
        """The estimate for the measured state ``x`` of this tick (a new array, or ``x``
        itself when the filter passes through)."""
        y = np.asarray(x, dtype=float)
        if self.passes_through:
            return y
        if self._angle is None:
            return self.reset(y)
        rate = y[4:6]
        prior = self._angle + 0.5 * self.dt * (self._rate + rate)
        angle = prior + self.gain * (y[0:2] - prior)
        self._angle = angle
        self._rate = rate.copy()
        out = y.copy()
        out[0:2] = angle
        return out
