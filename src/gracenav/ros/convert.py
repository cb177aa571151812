"""The message conventions of gracenav's nodes, in numpy (no rclpy): the model state
from odometry and IMU readings and back, and the ball torques as a torque vector.

Frames follow REP-103/105: ``map`` (the world), ``odom`` (the odometry frame; gracenav
assumes it coincides with ``map``: the ballbot has no yaw and the nodes no
localisation), ``base_link`` (the ball's centre). The 3D model's state is
x = [θ_x, θ_y, φ_x, φ_y, θ̇_x, θ̇_y, φ̇_x, φ̇_y] (ball angles relative to the body and body
lean, rad and rad/s); the ball's position is r (θ + φ).

* Odometry: position (x, y) (m) and velocity (ẋ, ẏ) (m/s) of the ball.
* IMU: orientation = the body lean as :func:`gracenav.scenarios.mcap_log.lean_quaternion`
  (R_y(φ_x) R_x(−φ_y): the body axis leans toward +x by φ_x, toward +y by φ_y);
  angular velocity = (−φ̇_y, φ̇_x, 0) rad/s, the lean rates as a rotation-rate vector.
* Command: the generalised ball torques (τ_x, τ_y) (N m, on θ_x and θ_y) as the torque
  vector on the ball in ``base_link``: rolling toward +x turns the ball about +y, so
  torque = (−τ_y, τ_x, 0).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.scenarios.mcap_log import lean_from_quaternion, lean_quaternion
from gracenav.sim.state import position_state, state_from_position

__all__ = [
    "finite",
    "imu_from_state",
    "lean_from_quaternion",
    "lean_quaternion",
    "noise_from_covariance",
    "odometry_from_state",
    "seconds_stamp",
    "stamp_seconds",
    "state_from_readings",
    "torque_from_vector",
    "vector_from_torque",
]

FloatArray = NDArray[np.float64]


def odometry_from_state(x: ArrayLike, radius: float) -> FloatArray:
    """Ball position and velocity (x, y, ẋ, ẏ) (m, m/s) of the model state ``x`` (8,)."""
    return position_state(np.asarray(x, dtype=float), radius)


def imu_from_state(x: ArrayLike) -> tuple[tuple[float, float, float, float], FloatArray]:
    """Body orientation (x, y, z, w) and angular velocity (3,) (rad/s) of ``x`` (8,)."""
    s = np.asarray(x, dtype=float)
    return lean_quaternion(s[2:4]), np.array([-s[7], s[6], 0.0])


def state_from_readings(
    position_state: ArrayLike,
    orientation: Sequence[float],
    angular_velocity: ArrayLike,
    radius: float,
) -> FloatArray:
    """The model state (8,) of an odometry reading (x, y, ẋ, ẏ) and an IMU reading
    (orientation (x, y, z, w), angular velocity (3,)), for a ball of ``radius`` (m)."""
    lean = lean_from_quaternion(orientation)
    w = np.asarray(angular_velocity, dtype=float)
    rate = np.array([w[1], -w[0]])
    return state_from_position(np.asarray(position_state, dtype=float), radius, lean, rate)


def vector_from_torque(torque: ArrayLike) -> FloatArray:
    """The torque vector (3,) (N m, ``base_link``) of generalised torques (τ_x, τ_y)."""
    t = np.asarray(torque, dtype=float)
    return np.array([-t[1], t[0], 0.0])


def torque_from_vector(vector: ArrayLike) -> FloatArray:
    """The generalised torques (τ_x, τ_y) (N m) of a torque vector (3,) on the ball."""
    v = np.asarray(vector, dtype=float)
    return np.array([v[1], -v[0]])


def finite(*values: float | ArrayLike) -> bool:
    """Whether every number given is finite."""
    return all(bool(np.all(np.isfinite(np.asarray(v, dtype=float)))) for v in values)


def noise_from_covariance(
    pose_covariance: ArrayLike, twist_covariance: ArrayLike
) -> tuple[float, float] | None:
    """The standard deviations (m, m/s) of the ball position and velocity that an
    Odometry message's covariances state (each 6 × 6 row-major, REP-103 order x, y, z,
    roll, pitch, yaw): per quantity the larger of the x and y variances' square roots.
    None if one of the four variances is negative or not finite (not a variance)."""
    pose = np.asarray(pose_covariance, dtype=float).reshape(-1)
    twist = np.asarray(twist_covariance, dtype=float).reshape(-1)
    if pose.size != 36 or twist.size != 36:
        return None
    var = np.array([pose[0], pose[7], twist[0], twist[7]])
    if not (np.all(np.isfinite(var)) and np.all(var >= 0.0)):
        return None
    return float(np.sqrt(max(var[0], var[1]))), float(np.sqrt(max(var[2], var[3])))


def stamp_seconds(sec: int, nanosec: int) -> float:
    """A ROS time stamp in seconds."""
    return float(sec) + 1e-9 * float(nanosec)


def seconds_stamp(t: float) -> tuple[int, int]:
    """Seconds as a ROS time stamp (sec, nanosec)."""
    ns = round(t * 1e9)
    return ns // 1_000_000_000, ns % 1_000_000_000
