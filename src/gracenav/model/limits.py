"""The physical limits of a ballbot's motion, and the time bound of a task.

Two limits bound how fast the robot can cover a length L (derivation in the design
notes, ``docs/design/speed.md``):

* the top speed v_max, where friction between ball and body alone takes the whole
  torque limit: D_c + D_v v / r = τ_max, so v_max = r (τ_max − D_c) / D_v;
* the largest steady acceleration a_max at a lean limit φ_max: with the body held at
  a constant lean φ (φ̇ = φ̈ = 0) the planar model's second equation (IJRR 2014,
  eq. 1) gives (α + β cos φ) θ̈ = β g sin φ / r, so the ball accelerates at
  ẍ = r θ̈ = β g sin φ / (α + β cos φ), whatever the friction (it enters the first
  equation only, which sets the torque).

Rest to rest over L, no motion does better than accelerating at a_max to v_max,
cruising, and braking at a_max: T* = L / v_max + v_max / a_max when L ≥ v_max² / a_max
(else 2 √(L / a_max), never reaching v_max). The robot cannot reach this bound:
leaning to φ_max takes time, and cruising at v_max leaves no torque for balance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gracenav.params import BallbotParams

__all__ = ["TimeBound", "physical_time_bound", "steady_acceleration", "top_speed"]


@dataclass(frozen=True)
class TimeBound:
    """The physical time bound of a rest-to-rest motion over a length.

    Attributes
    ----------
    length : float
        Length L covered (m).
    lean_limit : float
        Lean limit φ_max (rad) the acceleration is taken at.
    v_max : float
        Top speed (m/s): friction alone takes the whole torque limit.
    a_max : float
        Steady acceleration at ``lean_limit`` (m/s²).
    bound : float
        T* (s): L / v_max + v_max / a_max, or 2 √(L / a_max) when L < v_max² / a_max.
    """

    length: float
    lean_limit: float
    v_max: float
    a_max: float
    bound: float

    @property
    def reaches_top_speed(self) -> bool:
        """Whether the bound's profile cruises at v_max (L ≥ v_max² / a_max)."""
        return self.length >= self.v_max**2 / self.a_max


def top_speed(params: BallbotParams) -> float:
    """Speed v_max (m/s) at which the friction torque D_c + D_v v / r equals the torque
    limit τ_max: r (τ_max − D_c) / D_v.

    Raises
    ------
    ValueError
        Without viscous friction (no finite top speed), or with a Coulomb friction at or
        above the torque limit (the robot cannot move).
    """
    if not params.viscous_friction > 0.0:
        raise ValueError("without viscous friction the torque limit sets no top speed")
    if not params.torque_limit > params.coulomb_friction:
        raise ValueError(
            f"the torque limit {params.torque_limit:g} N m does not exceed the Coulomb "
            f"friction {params.coulomb_friction:g} N m"
        )
    return (
        params.ball_radius
        * (params.torque_limit - params.coulomb_friction)
        / params.viscous_friction
    )


def steady_acceleration(params: BallbotParams, lean: float) -> float:
    """Ball acceleration (m/s²) with the body held at constant lean ``lean`` (rad), in
    the planar model: β g sin φ / (α + β cos φ).

    Raises
    ------
    ValueError
        For a lean outside (0, π/2).
    """
    if not 0.0 < lean < 0.5 * math.pi:
        raise ValueError(f"lean must be in (0, pi/2) rad, got {lean!r}")
    alpha, beta = params.alpha(), params.beta()
    return beta * params.gravity * math.sin(lean) / (alpha + beta * math.cos(lean))


def physical_time_bound(params: BallbotParams, length: float, *, lean_limit: float) -> TimeBound:
    """The least time (s) any motion of the robot takes over ``length`` (m), rest to
    rest, with speed at most :func:`top_speed` and acceleration at most
    :func:`steady_acceleration` at ``lean_limit`` (rad).

    Parameters
    ----------
    params : BallbotParams
        The robot (the palette's parameters).
    length : float
        Length L (m), > 0: the shortest path's length, or a straight line's.
    lean_limit : float
        The lean limit φ_max (rad) the palette's maneuvers are built to.

    Returns
    -------
    TimeBound

    Raises
    ------
    ValueError
        For a length that is not positive and finite, and as :func:`top_speed` and
        :func:`steady_acceleration`.
    """
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"length must be positive and finite, got {length!r}")
    v = top_speed(params)
    a = steady_acceleration(params, lean_limit)
    if length >= v * v / a:
        bound = length / v + v / a
    else:
        bound = 2.0 * math.sqrt(length / a)
    return TimeBound(length=length, lean_limit=lean_limit, v_max=v, a_max=a, bound=bound)
