"""``gracenav ros sim``: the 3D model of the ballbot (:class:`gracenav.sim.Model3DPlant`)
as a ROS 2 node.

Every control tick (1/1024 s of simulated time) it publishes ``/clock``
(rosgraph_msgs/Clock), ``/imu`` (sensor_msgs/Imu, frame ``base_link``: lean and lean
rate) and ``/odom`` (nav_msgs/Odometry, frame ``odom``, child ``base_link``: the ball's
position and velocity), all stamped with the simulated time, then waits for the
command of that tick on ``/gracenav/cmd_torque`` (geometry_msgs/WrenchStamped with the
same stamp; lockstep: simulated time stands still until it comes, and the state is sent
again every ``resend`` s of wall time meanwhile) and advances by one tick with it held.
With ``lockstep`` false it runs in real time instead, holding the latest command.
Pushes (geometry_msgs/Vector3Stamped, an impulse in N s in ``map``/``odom``) on
``/gracenav/push`` act at the next tick. With ``map_file`` it also publishes the map on
``/map`` (nav_msgs/OccupancyGrid, transient local), as a map server would.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from gracenav.errors import ConfigError
from gracenav.ros import convert
from gracenav.ros.node import (
    grid_message,
    seconds,
    signals_ask_to_stop,
    start_rclpy,
    stop_requested,
    transient_local_qos,
)

__all__ = ["PARAMETERS", "run_sim"]

#: The node's ROS parameters and their defaults.
PARAMETERS: dict[str, Any] = {
    "map_file": "",
    "start": [0.0, 0.0],
    "lockstep": True,
    "resend": 0.1,
    "substeps": 1,
    "max_sim_time": 0.0,  # s; 0: no limit
    "fall_lean_deg": 20.0,
}


class _Sim:
    def __init__(self, rclpy: Any, overrides: dict[str, Any]) -> None:
        from geometry_msgs.msg import Vector3Stamped, WrenchStamped
        from nav_msgs.msg import OccupancyGrid, Odometry
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Imu

        from gracenav.control import CONTROL_RATE
        from gracenav.palette import load_palette
        from gracenav.sim import Model3DPlant, state_from_position

        node = Node(
            "gracenav_sim",
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
        self.node = node
        for name, default in PARAMETERS.items():
            node.declare_parameter(name, default)
        par = {name: node.get_parameter(name).value for name in PARAMETERS}
        start = [float(v) for v in par["start"]]
        if len(start) != 2 or not convert.finite(start):
            raise ConfigError(f"parameter start is [x, y] (m), got {start!r}")
        self.lockstep = bool(par["lockstep"])
        self.resend = float(par["resend"])
        self.max_sim_time = float(par["max_sim_time"])
        self.fall_lean = math.radians(float(par["fall_lean_deg"]))
        params = load_palette().params
        self.plant = Model3DPlant(params, substeps=int(par["substeps"]))
        self.radius = float(params.ball_radius)
        self.plant.reset(state_from_position(np.r_[start, 0.0, 0.0], self.radius))
        self.dt = 1.0 / CONTROL_RATE
        self.tick = 0
        self.torque = np.zeros(2)
        self._cmd_tick = -1
        self._pushes: list[np.ndarray] = []
        self._fell = False
        self._rejections: dict[str, float] = {}
        self.logger = node.get_logger()
        self._Odometry, self._Imu, self._Clock = Odometry, Imu, Clock
        self.odom_pub = node.create_publisher(Odometry, "/odom", 10)
        self.imu_pub = node.create_publisher(Imu, "/imu", 10)
        self.clock_pub = node.create_publisher(Clock, "/clock", 10)
        node.create_subscription(WrenchStamped, "/gracenav/cmd_torque", self._on_cmd, 10)
        node.create_subscription(Vector3Stamped, "/gracenav/push", self._on_push, 10)
        if par["map_file"]:
            from gracenav.ros.navigate import _load_map_file

            self.map_pub = node.create_publisher(OccupancyGrid, "/map", transient_local_qos())
            self.map_pub.publish(grid_message(_load_map_file(str(par["map_file"]))))
        self.wall_start: float | None = None
        self.done = False

    def _reject(self, what: str, why: str) -> None:
        now = time.monotonic()
        key = f"{what}: {why}"
        if now - self._rejections.get(key, -math.inf) >= 2.0:
            self._rejections[key] = now
            self.logger.warning(f"{key}; dropped")

    def _on_cmd(self, msg: Any) -> None:
        if msg.header.frame_id != "base_link":
            self._reject(
                "/gracenav/cmd_torque", f"frame_id {msg.header.frame_id!r} is not 'base_link'"
            )
            return
        w = msg.wrench.torque
        vec = np.array([w.x, w.y, w.z])
        if not np.all(np.isfinite(vec)):
            self._reject("/gracenav/cmd_torque", "the torque is not finite (holding the last one)")
            return
        k = round(seconds(msg.header) / self.dt)
        if self.lockstep and k < self._cmd_tick:
            return  # an older tick's command
        self._cmd_tick = k
        self.torque = convert.torque_from_vector(vec)

    def _on_push(self, msg: Any) -> None:
        if msg.header.frame_id not in ("map", "odom"):
            self._reject("/gracenav/push", f"frame_id {msg.header.frame_id!r} is not 'map'")
            return
        v = np.array([msg.vector.x, msg.vector.y])
        if not np.all(np.isfinite(v)):
            self._reject("/gracenav/push", "the impulse is not finite")
            return
        self._pushes.append(v)

    def publish_state(self) -> None:
        t = self.tick * self.dt
        x = self.plant.state()
        clock = self._Clock()
        ns = round(t * 1e9)
        clock.clock.sec, clock.clock.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        self.clock_pub.publish(clock)
        quat, rate = convert.imu_from_state(x)
        imu = self._Imu()
        imu.header.frame_id = "base_link"
        imu.header.stamp = clock.clock
        imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = quat
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = (
            float(v) for v in rate
        )
        imu.linear_acceleration_covariance[0] = -1.0  # not provided
        self.imu_pub.publish(imu)
        p = convert.odometry_from_state(x, self.radius)
        odom = self._Odometry()
        odom.header.frame_id = "odom"
        odom.header.stamp = clock.clock
        odom.child_frame_id = "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y = float(p[0]), float(p[1])
        odom.pose.pose.position.z = self.radius
        odom.pose.pose.orientation = imu.orientation
        odom.twist.twist.linear.x, odom.twist.twist.linear.y = float(p[2]), float(p[3])
        odom.twist.twist.angular = imu.angular_velocity
        self.odom_pub.publish(odom)

    def advance(self) -> None:
        for impulse in self._pushes:
            t = self.tick * self.dt
            self.logger.info(f"push of ({impulse[0]:.3g}, {impulse[1]:.3g}) N s at t = {t:.3f} s")
            self.plant.push(impulse)
        self._pushes.clear()
        self.plant.advance(self.torque, self.dt)
        self.tick += 1
        lean = self.plant.state()[2:4]
        if not self._fell and float(np.hypot(*lean)) > self.fall_lean:
            self._fell = True
            self.logger.error(f"the robot fell (lean beyond {math.degrees(self.fall_lean):g}°)")
        if self.max_sim_time > 0 and self.tick * self.dt >= self.max_sim_time:
            self.done = True

    def run(self, rclpy: Any) -> None:
        from rclpy.executors import SingleThreadedExecutor

        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        self.wall_start = time.monotonic()
        try:
            while rclpy.ok() and not self.done and not stop_requested():
                self.publish_state()
                sent = time.monotonic()
                if self.lockstep:
                    while self._cmd_tick < self.tick and rclpy.ok() and not stop_requested():
                        executor.spin_once(timeout_sec=0.02)
                        if time.monotonic() - sent >= self.resend and self._cmd_tick < self.tick:
                            self.publish_state()  # for a controller that joined late
                            sent = time.monotonic()
                else:
                    due = self.wall_start + (self.tick + 1) * self.dt
                    while time.monotonic() < due and not stop_requested():
                        executor.spin_once(timeout_sec=max(0.0, due - time.monotonic()))
                if not stop_requested():
                    self.advance()
        finally:
            executor.remove_node(self.node)
            executor.shutdown(timeout_sec=0.5)

    def close(self) -> None:
        elapsed = time.monotonic() - (self.wall_start or time.monotonic())
        sim = self.tick * self.dt
        if elapsed > 0:
            self.logger.info(
                f"simulated {sim:.2f} s in {elapsed:.2f} s: {self.tick / elapsed:.0f} ticks per "
                f"second ({sim / elapsed:.2f}x real time)"
            )
        self.node.destroy_node()


def run_sim(overrides: dict[str, Any], ros_args: Sequence[str] = ()) -> int:
    """Run the simulated robot until SIGINT (or ``max_sim_time``); 0 after a clean
    shutdown."""
    rclpy = start_rclpy(ros_args)
    sim = None
    try:
        sim = _Sim(rclpy, overrides)
        with signals_ask_to_stop():
            sim.run(rclpy)
    except KeyboardInterrupt:
        pass
    finally:
        if sim is not None:
            sim.close()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
