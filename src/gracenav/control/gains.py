"""Balancing and tracking controllers of the paper's Fig. 2.

The architecture, per plane i ∈ {x, y} (the two planes of the 3D model)::

    desired position ─► tracking controller ─► lean compensation φ_c ─┐
    planned lean φ_plan (shape trajectory planner) ─────────────────────┴─► φ_d = φ_plan + φ_c
    φ_d ─► balancing controller ─► motor torque τ (+ feed-forward and friction compensation)

* The **tracking controller** acts on the position-state error of its plane,
  φ_c = k_p (p_ref − p) + k_v (ṗ_ref − ṗ), saturated to ±``max_lean_compensation``.
* The **balancing controller** tracks the desired lean,
  τ = τ_ff − k_φ (φ − φ_d) − k_φ̇ (φ̇ − φ̇_plan) + D(θ̇) − D(θ̇_plan),
  where τ_ff is the plan's torque (which already contains the friction
  D(θ̇_plan) at the planned ball rate) and D the friction model evaluated on
  the *measured* relative ball rate: this is the friction compensation that
  removes the Coulomb dead zone.

The gains come from a continuous-time LQR on the linearised, frictionless
planar model of each plane in the coordinates s = [p, φ, ṗ, φ̇] with
p = r_w (θ + φ). An LQR gain K = [k1, k2, k3, k4] (u = −K e) factors exactly
into the cascade above with k_φ = k2, k_φ̇ = k4, k_p = k1/k2, k_v = k3/k2,
so without saturation the cascade *is* the LQR. The gains are time-invariant
and shared by every motion policy, which makes every pair of policies'
control laws gracefully composable (φ₁(t_f1) = φ₂(0)) by construction.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from gracenav.errors import ConfigError
from gracenav.model.planar import PlanarBallbot
from gracenav.params import BallbotParams

CONTROL_RATE = 1024.0
"""The control rate (Hz) of every controller of the package, the rate the palette's
policies are verified at: one tick is 1/1024 s, a step exact in binary, so tick times
k/1024 add up without rounding. Simulations, references and the hybrid controller
all tick at it."""

__all__ = [
    "ControllerGains",
    "LQRWeights",
    "design_gains",
    "lqr",
    "planar_to_position_coordinates",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LQRWeights:
    """Diagonal LQR weights for one plane, in coordinates s = [p, φ, ṗ, φ̇].

    The defaults place the closed-loop position poles near −1.6 ± 0.7j rad/s
    and the lean poles near −4.6 and −13 rad/s on the CMU ballbot.

    Parameters
    ----------
    position : float
        Weight on ball position error (1/m²).
    lean : float
        Weight on lean error (1/rad²).
    velocity : float
        Weight on ball velocity error (s²/m²).
    lean_rate : float
        Weight on lean rate error (s²/rad²).
    torque : float
        Weight on torque (1/(N m)²).
    """

    position: float = 200.0
    lean: float = 500.0
    velocity: float = 50.0
    lean_rate: float = 10.0
    torque: float = 0.1

    def __post_init__(self) -> None:
        for name in ("position", "lean", "velocity", "lean_rate"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f"LQRWeights.{name} must be >= 0, got {getattr(self, name)!r}")
        if not self.torque > 0.0:
            raise ConfigError(f"LQRWeights.torque must be > 0, got {self.torque!r}")


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the Fig. 2 cascade for both planes.

    Attributes
    ----------
    lqr : ndarray, shape (2, 4)
        Row i is the LQR gain K of plane i (0: x, 1: y) on s = [p, φ, ṗ, φ̇],
        units [N m/m, N m/rad, N m s/m, N m s/rad].
    max_lean_compensation : float
        Saturation of the tracking controller's lean compensation (rad).
    friction_compensation : bool
        Feed the friction model forward on the measured ball rate.
    friction_midpoint : bool
        Feed it forward at the rate predicted for the middle of the control period
        instead: the measured rate plus half the reference's change over the period.
        The torque is held over the period while the plant's friction follows the ball
        rate within it; where the rate crosses zero the smoothed Coulomb term changes by
        2 D_c within a few tens of periods, and the measured rate's feed-forward, half
        a period behind it all along, leaves a pulse of the ball's acceleration there
        (≈ 0.3 m/s³ of jerk on the smooth palette's maneuvers,
        docs/design/controllers.md). Off by default: the shipped palettes are verified
        with the measured rate's.
    params : BallbotParams
        The (nominal) parameters the gains and the friction compensation use.
    weights : LQRWeights or None
        The LQR weights ``lqr`` was designed with by :func:`design_gains`; None for
        gains given by hand. Together with ``params``, ``max_lean_compensation`` and
        ``friction_compensation`` (and ``friction_midpoint`` when set) these are the
        controller's *design inputs* (:meth:`design_inputs`), what caches are keyed by:
        ``lqr`` itself is a LAPACK result whose last bits vary between numpy/scipy
        builds.
    """

    lqr: FloatArray
    params: BallbotParams = field(default_factory=BallbotParams)
    max_lean_compensation: float = float(np.deg2rad(5.0))
    friction_compensation: bool = True
    weights: LQRWeights | None = None
    friction_midpoint: bool = False

    def __post_init__(self) -> None:
        k = np.array(self.lqr, dtype=float)
        if k.shape != (2, 4) or not np.all(np.isfinite(k)):
            raise ConfigError(f"ControllerGains.lqr must be a finite (2, 4) array, got {k.shape}")
        k.setflags(write=False)
        object.__setattr__(self, "lqr", k)

    @property
    def lean(self) -> FloatArray:
        """k_φ per plane (N m/rad), shape (2,)."""
        return self.lqr[:, 1]

    @property
    def lean_rate(self) -> FloatArray:
        """k_φ̇ per plane (N m s/rad), shape (2,)."""
        return self.lqr[:, 3]

    @property
    def tracking_position(self) -> FloatArray:
        """k_p = k1/k2 per plane: lean compensation per metre of error (rad/m), shape (2,)."""
        return self.lqr[:, 0] / self.lqr[:, 1]

    @property
    def tracking_velocity(self) -> FloatArray:
        """k_v = k3/k2 per plane: lean compensation per m/s of error (rad s/m), shape (2,)."""
        return self.lqr[:, 2] / self.lqr[:, 1]

    def design_inputs(self) -> dict[str, Any]:
        """What the gains are designed from, as plain data (no computed floats).

        Gains given by hand (``weights`` None) have no design; their ``lqr`` is then
        an input itself and is included as given.
        """
        return {
            "params": self.params.to_dict(),
            "weights": None if self.weights is None else dataclasses.asdict(self.weights),
            "lqr": self.lqr.tolist() if self.weights is None else None,
            "max_lean_compensation": self.max_lean_compensation,
            "friction_compensation": self.friction_compensation,
            # Only when set, so that the keys of palettes built before it stand.
            **({"friction_midpoint": True} if self.friction_midpoint else {}),
        }

    def relative_difference(self, other: ControllerGains) -> float:
        """Largest entry of |K − K_other| over the largest entry of |K_other| (per plane)."""
        scale = np.max(np.abs(other.lqr), axis=1)
        return float(np.max(np.max(np.abs(self.lqr - other.lqr), axis=1) / scale))

    def kernel_arrays(self) -> FloatArray:
        """Pack for the compiled closed loop: rows k_p, k_v, k_φ, k_φ̇ per plane, shape (2, 4)."""
        return np.stack(
            [self.tracking_position, self.tracking_velocity, self.lean, self.lean_rate], axis=1
        )


def lqr(
    a: FloatArray, b: FloatArray, q: FloatArray, r: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Continuous-time infinite-horizon LQR.

    Parameters
    ----------
    a : ndarray, shape (n, n)
    b : ndarray, shape (n, m)
    q : ndarray, shape (n, n)
    r : ndarray, shape (m, m)

    Returns
    -------
    K : ndarray, shape (m, n)
        Gain of u = −K x.
    P : ndarray, shape (n, n)
        Stabilising solution of the continuous algebraic Riccati equation.
    """
    p = scipy.linalg.solve_continuous_are(a, b, q, r)
    k = np.linalg.solve(r, b.T @ p)
    return k, p


def planar_to_position_coordinates(radius: float) -> FloatArray:
    """Matrix T with [p, φ, ṗ, φ̇] = T [θ, φ, θ̇, φ̇], p = r_w (θ + φ); shape (4, 4)."""
    r = radius
    return np.array([[r, r, 0, 0], [0, 1, 0, 0], [0, 0, r, r], [0, 0, 0, 1]], dtype=float)


def design_gains(
    params: BallbotParams | None = None,
    weights: LQRWeights | None = None,
    *,
    max_lean_compensation: float = float(np.deg2rad(5.0)),
    friction_compensation: bool = True,
    friction_midpoint: bool = False,
) -> ControllerGains:
    """Design the cascade gains by LQR on each plane's linearised planar model.

    Parameters
    ----------
    params : BallbotParams, optional
        Nominal parameters (defaults: CMU ballbot).
    weights : LQRWeights, optional
        LQR weights, the same for both planes.
    max_lean_compensation : float
        Saturation of the lean compensation (rad).
    friction_compensation : bool
        Whether the balancing controller feeds friction forward.
    friction_midpoint : bool
        Whether it does so at the rate predicted for the middle of the control period
        (:attr:`ControllerGains.friction_midpoint`).

    Returns
    -------
    ControllerGains
    """
    params = params if params is not None else BallbotParams()
    weights = weights if weights is not None else LQRWeights()
    q = np.diag([weights.position, weights.lean, weights.velocity, weights.lean_rate])
    r = np.array([[weights.torque]])
    t = planar_to_position_coordinates(params.ball_radius)
    rows = []
    for plane in ("x", "y"):
        a, b = PlanarBallbot(params, plane=plane).linearize()
        k, _ = lqr(t @ a @ np.linalg.inv(t), t @ b, q, r)
        rows.append(k[0])
    return ControllerGains(
        lqr=np.array(rows),
        params=params,
        max_lean_compensation=max_lean_compensation,
        friction_compensation=friction_compensation,
        weights=weights,
        friction_midpoint=friction_midpoint,
    )
