"""Smoothness figures of a run: the ball's jerk from the true state.

The jerk is the second time derivative of the true ball velocity (the plant's state,
r (θ̇ + φ̇) on each axis, never what the controller measured), estimated at every tick
by a Savitzky–Golay fit: a polynomial of degree :data:`JERK_POLYORDER` fitted by least
squares to the velocity over a centred window of :data:`JERK_WINDOW_S`, differentiated
twice. Only ticks with a full window inside the run are estimated, so the first and
last half-window of a run carry no figure.

Why a window rather than differences tick to tick: the commanded torque is held over a
control period, so the ball's acceleration steps at every tick where the torque
changes. A difference of accelerations over one period then reads each step as
Δa × the control rate (a step of 1 m/s² is 1024 m/s³ at 1024 Hz): it measures the
control rate, and with position noise the torque's chatter that the sensor causes
(600–800 m/s³ on an unpushed run with 5 mm of noise), not the motion. The window
keeps what the robot does on the time scale of its maneuvers (the jerk of a sinusoid
of 2 Hz within 2 %, ``tests/test_smoothness.py``) and leaves out the tick-to-tick
chatter.

A push is an impulse: the velocity steps between two ticks, by the push's doing.
Every tick whose window (widened by one control period on each side for the push's
rounding to a tick) holds a push is left out: :data:`JERK_WINDOW_S` around each push.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["JERK_POLYORDER", "JERK_WINDOW_S", "JerkProfile", "jerk_profile", "planned_jerk"]

FloatArray = NDArray[np.float64]

JERK_WINDOW_S = 0.3
"""Width (s) of the window the velocity is fitted over."""

JERK_POLYORDER = 4
"""Degree of the polynomial fitted to the velocity in each window."""


@dataclass(frozen=True)
class JerkProfile:
    """The ball's jerk magnitude at the ticks that have a figure.

    Attributes
    ----------
    time : ndarray, shape (M,)
        Tick times (s) with a full window inside the run and no push in it.
    jerk : ndarray, shape (M,)
        Jerk magnitude ‖(x⃛, y⃛)‖ (m/s³) at those ticks.
    """

    time: FloatArray
    jerk: FloatArray

    @property
    def max(self) -> float:
        """Largest jerk (m/s³); 0 with no tick."""
        return float(np.max(self.jerk)) if self.jerk.size else 0.0

    @property
    def p95(self) -> float:
        """95th percentile of the jerk over the ticks (m/s³, linear interpolation);
        0 with no tick."""
        return float(np.percentile(self.jerk, 95.0)) if self.jerk.size else 0.0


def jerk_profile(
    time: ArrayLike,
    velocity: ArrayLike,
    *,
    breaks: Sequence[float] = (),
    window: float = JERK_WINDOW_S,
    polyorder: int = JERK_POLYORDER,
) -> JerkProfile:
    """The jerk of a velocity sampled at evenly spaced ticks.

    Parameters
    ----------
    time : array_like, shape (N,)
        Tick times (s), evenly spaced (relative spread of the steps below 1e-6).
    velocity : array_like, shape (N, D)
        Velocity (m/s) at each tick, D axes (the ball's x and y: D = 2).
    breaks : sequence of float
        Times (s) where the velocity steps from outside (pushes): ticks whose window
        holds one, widened by one tick each side, are left out.
    window : float
        Width (s) of the centred fitting window; the number of ticks in it is the
        nearest odd number to ``window`` / step.
    polyorder : int
        Degree of the fitted polynomial (>= 2: the jerk is its second derivative).

    Returns
    -------
    JerkProfile
        Empty when the run is shorter than one window.

    Raises
    ------
    ValueError
        For shapes that do not match, unevenly spaced ticks, ``polyorder`` < 2, or a
        window of fewer ticks than ``polyorder`` + 2.
    """
    from scipy.signal import savgol_filter

    t = np.asarray(time, dtype=float)
    v = np.asarray(velocity, dtype=float)
    if t.ndim != 1 or v.ndim != 2 or v.shape[0] != t.shape[0]:
        raise ValueError(f"time (N,) and velocity (N, D) expected, got {t.shape}, {v.shape}")
    if polyorder < 2:
        raise ValueError(f"polyorder must be >= 2 (jerk is the second derivative), got {polyorder}")
    empty = JerkProfile(np.zeros(0), np.zeros(0))
    if t.size < 2:
        return empty
    steps = np.diff(t)
    dt = float(np.mean(steps))
    if not (dt > 0.0 and np.all(np.abs(steps - dt) <= 1e-6 * dt)):
        raise ValueError("the ticks must be evenly spaced in increasing time")
    half = round(0.5 * window / dt)
    n = 2 * half + 1
    if n < polyorder + 2:
        raise ValueError(
            f"a window of {window!r} s holds {n} ticks, fewer than polyorder + 2 = "
            f"{polyorder + 2}: widen it"
        )
    if t.size < n:
        return empty
    j = savgol_filter(v, n, polyorder, deriv=2, delta=dt, axis=0, mode="interp")
    keep = np.zeros(t.size, dtype=bool)
    keep[half : t.size - half] = True
    reach = half * dt + dt  # a break within the window, or one tick off it
    for b in breaks:
        keep &= np.abs(t - b) > reach
    return JerkProfile(t[keep].copy(), np.asarray(np.linalg.norm(j[keep], axis=1)))


def planned_jerk(velocity: ArrayLike, dt: float) -> float:
    """Largest jerk (m/s³) of a planned motion's velocity, as a run's summary measures it,
    with the trims before and after it held for a window each side (constant velocity),
    so that its ends count.

    Parameters
    ----------
    velocity : array_like, shape (N, D)
        Velocity (m/s) at ticks ``dt`` apart (a primitive's or maneuver's plan).
    dt : float
        Tick (s).
    """
    v = np.asarray(velocity, dtype=float)
    pad = round(JERK_WINDOW_S / dt)
    v = np.vstack([np.repeat(v[:1], pad, axis=0), v, np.repeat(v[-1:], pad, axis=0)])
    return jerk_profile(np.arange(len(v)) * dt, v).max
