"""Disturbances of simulated runs: pushes (impulses on the body), body forces, state
jumps and drags (the robot held and moved), in run time."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gracenav.errors import ConfigError

__all__ = ["BodyForce", "Disturbance", "Drag", "Push", "StateJump"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Push:
    """An impulse (N s) on the body centre of mass at ``time`` (s); ``impulse`` is (ix, iy)."""

    time: float
    impulse: tuple[float, float]


@dataclass(frozen=True)
class BodyForce:
    """A constant world force (N) (fx, fy) on the body COM over [start_time, end_time)."""

    start_time: float
    end_time: float
    force: tuple[float, float]


@dataclass(frozen=True)
class StateJump:
    """A forced jump ``delta`` (8,) of the model state at ``time`` (s)."""

    time: float
    delta: tuple[float, ...]


@dataclass(frozen=True)
class Drag:
    """The robot held at its body and moved along ``velocity`` (m/s) over [start_time, end_time).

    Modelled as a strong horizontal damper on the body centre of mass toward
    ``velocity``: F = damping · (v − ṗ_COM) (damping in N s/m), which makes
    the body follow the hand's velocity whatever the controller does.
    """

    start_time: float
    end_time: float
    velocity: tuple[float, float]
    damping: float = 1000.0


Disturbance = Push | BodyForce | StateJump | Drag


def _tick(t: float, dt: float, num_ticks: int, what: str) -> int:
    n = round(t / dt)
    if not 0 <= n <= num_ticks:
        raise ConfigError(
            f"{what} time {t!r} s is outside the simulated interval [0, {num_ticks * dt}] s"
        )
    return int(n)


def _disturbance_arrays(
    disturbances: Sequence[Disturbance], dt: float, nt: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per-tick arrays for the compiled loop (zero-size when a kind is unused)."""
    force = np.zeros((0, 3))
    impulse = np.zeros((0, 3))
    jump = np.zeros((0, 8))
    tether = np.zeros((0, 3))
    gains = np.zeros(1)
    for d in disturbances:
        if isinstance(d, Push):
            if impulse.shape[0] == 0:
                impulse = np.zeros((nt + 1, 3))
            impulse[_tick(d.time, dt, nt, "push"), :2] += np.asarray(d.impulse, dtype=float)
        elif isinstance(d, StateJump):
            delta = np.asarray(d.delta, dtype=float)
            if delta.shape != (8,):
                raise ConfigError(f"StateJump.delta must have 8 entries, got {delta.shape}")
            if jump.shape[0] == 0:
                jump = np.zeros((nt + 1, 8))
            jump[_tick(d.time, dt, nt, "state jump")] += delta
        elif isinstance(d, BodyForce):
            if force.shape[0] == 0:
                force = np.zeros((max(nt, 1), 3))
            a = _tick(d.start_time, dt, nt, "force start")
            b = _tick(d.end_time, dt, nt, "force end")
            force[a:b, :2] += np.asarray(d.force, dtype=float)
        elif isinstance(d, Drag):
            if tether.shape[0] == 0:
                tether = np.zeros((max(nt, 1), 3))
            elif gains[0] != d.damping:
                raise ConfigError("all drags of one simulation must share the same damping")
            gains = np.array([d.damping], dtype=float)
            a = _tick(d.start_time, dt, nt, "drag start")
            b = _tick(d.end_time, dt, nt, "drag end")
            tether[a:b, 0] = 1.0
            tether[a:b, 1:3] = np.asarray(d.velocity, dtype=float)
        else:  # pragma: no cover - typing guards this
            raise ConfigError(f"unknown disturbance {d!r}")
    return force, impulse, jump, tether, gains
