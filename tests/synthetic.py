"""Synthetic palettes for the library and graph tests: primitives with septic
position references (smooth through jerk, fast to build), wrapped as policies."""

from __future__ import annotations

import numpy as np

from gracenav.control import ControllerGains
from gracenav.palette import Palette
from gracenav.params import BallbotParams
from gracenav.policies import (
    DomainRadii,
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
    VerificationOptions,
)

DT = 1.0 / 64.0
GAINS = ControllerGains(lqr=np.ones((2, 4)))


def septic(p1: float, v0: float, v1: float, duration: float, t: np.ndarray) -> np.ndarray:
    """p, ṗ, p̈, p⃛ of the septic from (0, v0, 0, 0) to (p1, v1, 0, 0) over ``duration``."""
    k = np.arange(4, 8)
    T = duration
    a = np.array(
        [T**k, k * T ** (k - 1), k * (k - 1) * T ** (k - 2), k * (k - 1) * (k - 2) * T ** (k - 3)]
    )
    c = np.linalg.solve(a, [p1 - v0 * T, v1 - v0, 0.0, 0.0])[:, None]
    tt, kk = t[None, :], k[:, None]
    return np.array(
        [
            v0 * t + np.sum(c * tt**kk, axis=0),
            v0 + np.sum(c * kk * tt ** (kk - 1), axis=0),
            np.sum(c * kk * (kk - 1) * tt ** (kk - 2), axis=0),
            np.sum(c * kk * (kk - 1) * (kk - 2) * tt ** (kk - 3), axis=0),
        ]
    )


def primitive(
    name: str,
    disp: tuple[float, float],
    v0: tuple[float, float] = (0.0, 0.0),
    v1: tuple[float, float] = (0.0, 0.0),
    duration: float = 1.0,
    kind: PrimitiveKind = PrimitiveKind.MANEUVER,
) -> SampledPrimitive:
    n = round(duration / DT)
    t = np.arange(n + 1) * DT
    ax = septic(disp[0], v0[0], v1[0], duration, t)
    ay = septic(disp[1], v0[1], v1[1], duration, t)
    pos = np.column_stack([ax[0], ay[0], ax[1], ay[1], ax[2], ay[2]])
    lean = np.column_stack([ax[2], ay[2]]) / 9.81
    rate = np.column_stack([ax[3], ay[3]]) / 9.81
    states = np.column_stack([pos[:, :2] / 0.1 - lean, lean, pos[:, 2:4] / 0.1 - rate, rate])
    return SampledPrimitive(
        name=name,
        kind=kind,
        duration=n * DT,
        dt=DT,
        displacement=np.array(disp, dtype=float),
        start_velocity=np.array(v0, dtype=float),
        end_velocity=np.array(v1, dtype=float),
        states=states,
        accelerations=np.zeros((n + 1, 4)),
        inputs=np.zeros((n + 1, 2)),
        position=pos,
    )


def policy(
    prim: SampledPrimitive,
    start: tuple[float, float] = (0.2, 0.2),
    goal: tuple[float, float] = (0.1, 0.1),
    outer: tuple[float, float] = (1.5, 2.0),
    *,
    gains: ControllerGains = GAINS,
    correlation: float = 0.0,
) -> MotionPolicy:
    """A policy of ``prim`` with start/goal extents (m, m/s) and outer factors."""
    return MotionPolicy(
        prim, gains, DomainRadii(*start), DomainRadii(*goal), outer, correlation=correlation
    )


def palette(*policies: MotionPolicy, d: float = 0.5) -> Palette:
    return Palette(
        policies=tuple(policies),
        rejected=(),
        duplicates=(),
        d=d,
        params=BallbotParams(),
        options=VerificationOptions(),
        key="test",
    )
