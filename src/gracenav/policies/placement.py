"""Placing a policy on the map: the instantiated reference, and the torque jumps at
switches."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gracenav.params import BallbotParams
from gracenav.policies.policy import MotionPolicy
from gracenav.policies.primitive import FloatArray, SampledPrimitive, rotate_pairs
from gracenav.sim import Reference, simulate

__all__ = [
    "placed_positions",
]


def placed_positions(position: ArrayLike, k: int | None, origin: ArrayLike) -> FloatArray:
    """Reference x, y, ẋ, ẏ, ... (pairs on the last axis) of a primitive placed on the
    map: turned by k·90° about its start (``k`` None: already turned), its start moved
    to ``origin`` (x, y) (m). A new array."""
    out = rotate_pairs(position, k) if k is not None else np.array(position, dtype=np.float64)
    out[..., 0:2] += np.asarray(origin, dtype=np.float64)
    return out


def instantiated_reference(
    primitive: SampledPrimitive, k: int | None, origin: ArrayLike, radius: float
) -> tuple[Reference, FloatArray]:
    """A primitive placed on the map: rotated by k·90° about its start (``k`` None: it
    is already turned, as a catch placed at a heading), start moved to ``origin``
    (x, y) (m). The one placement of references: library policies, catches, shifts and
    terminal regulators all run through it.

    Returns
    -------
    Reference
        World-frame reference states and feed-forward torques at the ticks.
    position : ndarray, shape (T + 1, 6)
        World-frame x, y, ẋ, ẏ, ẍ, ÿ of the reference.
    """
    o = np.asarray(origin, dtype=np.float64)
    states = placed_positions(primitive.states, k, o / radius)
    position = placed_positions(primitive.position, k, o)
    inputs = rotate_pairs(primitive.inputs, k) if k is not None else primitive.inputs
    return Reference(states, inputs, primitive.dt), position


@dataclass(frozen=True)
class SwitchJump:
    """Commanded torque at a graceful switch from ``first`` to ``second`` (rotated by
    ``rotation``·90°): the jump at the switch tick and, for scale, the largest
    tick-to-tick change elsewhere in the run (N m)."""

    first: str
    second: str
    rotation: int
    jump: float
    largest_other_step: float


def switch_torque_jumps(
    policies: Sequence[MotionPolicy], *, params: BallbotParams | None = None
) -> list[SwitchJump]:
    """Simulate every connecting pair Φ₁ ⪰ Φ₂ (σ₁(t_f) = σ₂(0) through acceleration,
    after rotating Φ₂) from the centre of S₁ and measure the commanded torque jump at
    the switch (paper Sec. III-C (iii): φ₁(t_f1) = φ₂(0) makes it continuous)."""

    out = []
    for a in policies:
        end = a.primitive.position[-1]
        for b in policies:
            if b.gains is not a.gains and not np.array_equal(b.gains.lqr, a.gains.lqr):
                continue
            for k in range(4):
                start = rotate_pairs(b.primitive.position[0], k)
                if not np.allclose(start[2:], end[2:], rtol=0.0, atol=1e-9):
                    continue
                r = a.gains.params.ball_radius
                ref_b, _ = instantiated_reference(b.primitive, k, end[:2], r)
                ref_a = a.primitive.reference()
                joined = Reference(
                    np.concatenate([ref_a.states, ref_b.states[1:]]),
                    np.concatenate([ref_a.inputs, ref_b.inputs[1:]]),
                    ref_a.dt,
                )
                res = simulate(ref_a.states[0], joined, a.gains, params=params)
                steps = np.max(np.abs(np.diff(res.inputs, axis=0)), axis=1)
                n = a.primitive.num_ticks
                jump = float(steps[n]) if n < steps.size else 0.0
                other = float(np.max(np.delete(steps, n))) if steps.size > 1 else 0.0
                out.append(SwitchJump(a.name, b.name, k, jump, other))
    return out
