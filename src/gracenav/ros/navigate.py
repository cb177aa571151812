"""``gracenav ros navigate``: the hybrid controller as a ROS 2 node.

Subscribes to ``/odom`` (nav_msgs/Odometry: ball position and velocity, frame ``odom``
or ``map``), ``/imu`` (sensor_msgs/Imu: body lean and lean rate, frame ``base_link``),
``/map`` (nav_msgs/OccupancyGrid, transient local; unless ``map_file`` is given),
``/goal_pose`` (geometry_msgs/PoseStamped, frame ``map``: a goal at rest) and
``/gracenav/route`` (nav_msgs/Path: a surveillance route, ``loops`` times, cruising at
``route_speed`` along each pose's heading). Publishes, once per odometry/IMU pair with
matching stamps (the control tick), ``/gracenav/cmd_torque`` (geometry_msgs/
WrenchStamped, frame ``base_link``, stamped with the state's stamp: the torque vector
on the ball, :mod:`gracenav.ros.convert`), and on every switch ``/gracenav/plan``
(nav_msgs/Path) and ``/gracenav/domains`` (visualization_msgs/MarkerArray), once
``/gracenav/library`` (MarkerArray, transient local), and ``/gracenav/status``
(std_msgs/String, one JSON object) at 2 Hz and on every change. See docs/ros.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gracenav.errors import ConfigError
from gracenav.ros import convert
from gracenav.ros.core import NavigatorCore, NavigatorOptions
from gracenav.ros.node import (
    seconds,
    signals_ask_to_stop,
    spin_until,
    stamp,
    start_rclpy,
    transient_local_qos,
    wall,
    world_map_from_grid,
)

__all__ = ["PARAMETERS", "run_navigator"]

#: The node's ROS parameters and their defaults (a YAML ``--params-file`` or ``-p``).
PARAMETERS: dict[str, Any] = {
    "map_file": "",
    "palette": "",  # a palette file or a shipped palette's name; "": the default
    "goal": [0.0],  # [x, y] (m); [0.0] (one number) for none
    "route": [0.0],  # [x, y, x, y, ...] (m) of a surveillance route; [0.0] for none
    "route_speed": 0.0,
    "loops": 1,
    "footprint_radius": 0.2,
    "max_halvings": 1,
    "cost": "time",
    "max_time": 120.0,
    "goal_tolerance": 0.05,
    "state_timeout": 0.1,
    "stop_timeout": 0.5,
    "sync_tolerance": 0.5e-3,
    "position_noise_std": 0.0,
    "noise_from_covariance": False,
    "log_file": "",
    "exit_when_done": False,
}

_FRAMES_ODOM = ("odom", "map")
_FRAMES_BASE = ("base_link",)


def _load_map_file(path: str) -> Any:
    """A map from a scenario file (its ``map``) or a map file (map_server YAML, inline)."""
    from gracenav._util.io import load_document
    from gracenav.world import load_map

    doc = load_document(path, "map_file")
    if isinstance(doc, dict) and "task" in doc and "map" in doc:
        from gracenav.scenarios import load_scenario, load_scenario_map

        return load_scenario_map(load_scenario(path))
    return load_map(path)


class _Navigator:
    """The node: wiring between ROS messages and :class:`NavigatorCore`."""

    def __init__(self, rclpy: Any, overrides: dict[str, Any]) -> None:
        from geometry_msgs.msg import PoseStamped, Vector3Stamped, WrenchStamped
        from nav_msgs.msg import OccupancyGrid, Odometry
        from nav_msgs.msg import Path as PathMsg
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import Imu
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        from gracenav.palette import load_palette

        self.rclpy = rclpy
        node = Node(
            "gracenav_navigator",
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
        self.node = node
        for name, default in PARAMETERS.items():
            node.declare_parameter(name, default)
        par = {name: node.get_parameter(name).value for name in PARAMETERS}
        self.par = par
        self.options = NavigatorOptions(
            footprint_radius=float(par["footprint_radius"]),
            max_halvings=int(par["max_halvings"]),
            cost=str(par["cost"]),
            max_time=float(par["max_time"]),
            goal_tolerance=float(par["goal_tolerance"]),
            state_timeout=float(par["state_timeout"]),
            stop_timeout=float(par["stop_timeout"]),
            position_noise_std=float(par["position_noise_std"]),
        )
        self.sync = float(par["sync_tolerance"])
        self.noise_from_covariance = bool(par["noise_from_covariance"])
        self.exit_when_done = bool(par["exit_when_done"])
        self.logger = node.get_logger()
        recorder = None
        if par["log_file"]:
            from gracenav.scenarios.mcap_log import McapRunLog

            recorder = McapRunLog(par["log_file"])
        palette = load_palette(str(par["palette"]) or None)
        self.core = NavigatorCore(palette, self.options, log=self._log, recorder=recorder)
        self.radius = self.core.radius
        self._Wrench, self._Path, self._String = WrenchStamped, PathMsg, String
        self._MarkerArray = MarkerArray
        self.cmd_pub = node.create_publisher(WrenchStamped, "/gracenav/cmd_torque", 10)
        self.plan_pub = node.create_publisher(PathMsg, "/gracenav/plan", 1)
        self.domains_pub = node.create_publisher(MarkerArray, "/gracenav/domains", 1)
        self.library_pub = node.create_publisher(
            MarkerArray, "/gracenav/library", transient_local_qos()
        )
        self.status_pub = node.create_publisher(String, "/gracenav/status", 10)
        node.create_subscription(Odometry, "/odom", self._guarded(self._on_odom), 10)
        node.create_subscription(Imu, "/imu", self._guarded(self._on_imu), 10)
        node.create_subscription(PoseStamped, "/goal_pose", self._guarded(self._on_goal), 10)
        node.create_subscription(PathMsg, "/gracenav/route", self._guarded(self._on_route), 10)
        node.create_subscription(Vector3Stamped, "/gracenav/push", self._guarded(self._on_push), 10)
        self._odom: tuple[float, np.ndarray] | None = None
        self._imu: tuple[float, tuple[float, float, float, float], np.ndarray] | None = None
        self._last_tick = -math.inf
        self._status_text = ""
        self._library_sent = False
        self.done = False
        self.finished: str | None = None
        if par["map_file"]:
            self.core.set_map(_load_map_file(str(par["map_file"])))
        else:
            node.create_subscription(
                OccupancyGrid, "/map", self._guarded(self._on_map), transient_local_qos()
            )
            self._log("info", "waiting for a map on /map")
        goal = [float(v) for v in par["goal"]]
        route = [float(v) for v in par["route"]]
        if len(goal) == 2:
            self.core.request_goals([np.array([goal[0], goal[1], 0.0, 0.0])])
        elif len(goal) > 1:
            raise ConfigError(f"parameter goal is [x, y] (m), got {goal!r}")
        if len(route) >= 2:
            if len(route) % 2:
                raise ConfigError(f"parameter route is [x, y, x, y, ...] (m), got {route!r}")
            pts = np.asarray(route, dtype=float).reshape(-1, 2)
            self.core.request_goals(_route_goals(pts, float(par["route_speed"])), int(par["loops"]))
        timer = self._guarded(lambda _: self._on_timer())
        node.create_timer(0.05, lambda: timer(None))
        self._status_count = 0

    # -- logging -----------------------------------------------------------------------
    def _log(self, level: str, message: str) -> None:
        # one call site per severity: rclpy's logger refuses two at one site
        if level == "error":
            self.logger.error(message)
        elif level == "warn":
            self.logger.warning(message)
        else:
            self.logger.info(message)

    def _guarded(self, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """``callback`` with any exception logged instead of ending the node (the
        command then stays what it was: held)."""

        def run(msg: Any) -> None:
            try:
                callback(msg)
            except Exception as exc:  # a bad message or a bug never ends the node
                self._log("error", f"{callback.__name__}: {type(exc).__name__}: {exc}")

        return run

    # -- inputs ------------------------------------------------------------------------
    def _on_map(self, msg: Any) -> None:
        if self.core.world_map is not None:
            self.core.reject("/map", "a map is in use already (restart the node for another)")
            return
        try:
            wm = world_map_from_grid(msg)
        except Exception as exc:  # a bad message never ends the node
            self.core.reject("/map", str(exc))
            return
        self._log("info", f"map received: {wm.occupied.shape[1]} x {wm.occupied.shape[0]} cells")
        self.core.set_map(wm)

    def _on_odom(self, msg: Any) -> None:
        frame = msg.header.frame_id
        if frame not in _FRAMES_ODOM:
            self.core.reject("/odom", f"frame_id {frame!r} is not 'odom' or 'map'")
            return
        p, v = msg.pose.pose.position, msg.twist.twist.linear
        ps = np.array([p.x, p.y, v.x, v.y])
        if not np.all(np.isfinite(ps)):
            self.core.reject("/odom", "position or velocity is not finite")
            return
        if self.noise_from_covariance:
            noise = convert.noise_from_covariance(msg.pose.covariance, msg.twist.covariance)
            if noise is None:
                self.core.reject(
                    "/odom", "a position or velocity variance is negative or not finite"
                )
                return
            self.core.set_noise(*noise)
        self._odom = (seconds(msg.header), ps)
        self._try_tick()

    def _on_imu(self, msg: Any) -> None:
        frame = msg.header.frame_id
        if frame not in _FRAMES_BASE:
            self.core.reject("/imu", f"frame_id {frame!r} is not 'base_link'")
            return
        q, w = msg.orientation, msg.angular_velocity
        quat = (q.x, q.y, q.z, q.w)
        rate = np.array([w.x, w.y, w.z])
        if not (convert.finite(quat, rate) and any(quat)):
            self.core.reject("/imu", "orientation or angular velocity is not finite")
            return
        self._imu = (seconds(msg.header), quat, rate)
        self._try_tick()

    def _try_tick(self) -> None:
        if self._odom is None or self._imu is None:
            return
        t, ps = self._odom
        if abs(t - self._imu[0]) > self.sync or t <= self._last_tick:
            return
        self._last_tick = t
        t_in = time.perf_counter()
        x = convert.state_from_readings(ps, self._imu[1], self._imu[2], self.radius)
        tick = self.core.control(t, x)
        self._publish_torque(t, tick.torque)
        self.core.note_tick_time(time.perf_counter() - t_in)
        if tick.switched:
            self._publish_plan(t)
        if tick.finished is not None:
            self._publish_status(force=True)
            self.finished = tick.finished
            if self.exit_when_done:
                self.done = True

    def _on_goal(self, msg: Any) -> None:
        if msg.header.frame_id not in ("map", "odom"):
            self.core.reject("/goal_pose", f"frame_id {msg.header.frame_id!r} is not 'map'")
            return
        p = msg.pose.position
        if not convert.finite(p.x, p.y):
            self.core.reject("/goal_pose", "the position is not finite")
            return
        self._log("info", f"goal ({p.x:.3g}, {p.y:.3g}) m received")
        self.core.request_goals([np.array([p.x, p.y, 0.0, 0.0])])

    def _on_route(self, msg: Any) -> None:
        if msg.header.frame_id not in ("map", "odom") or not msg.poses:
            self.core.reject("/gracenav/route", "an empty route or a frame other than 'map'")
            return
        pts = np.array([[ps.pose.position.x, ps.pose.position.y] for ps in msg.poses])
        if not np.all(np.isfinite(pts)):
            self.core.reject("/gracenav/route", "a pose is not finite")
            return
        self.core.request_goals(
            _route_goals(pts, float(self.par["route_speed"])), int(self.par["loops"])
        )

    def _on_push(self, msg: Any) -> None:
        v = msg.vector
        if (
            self.core.recorder is not None
            and convert.finite(v.x, v.y)
            and self.core.x_last is not None
        ):
            from gracenav.sim.state import position_state

            t = (
                seconds(msg.header)
                if (msg.header.stamp.sec or msg.header.stamp.nanosec)
                else self._last_tick
            )
            at = position_state(self.core.x_last, self.radius)[:2]
            self.core.recorder.push(t, run=0, run_time=t, at=at, impulse=(v.x, v.y))

    # -- outputs -----------------------------------------------------------------------
    def _publish_torque(self, t: float, torque: np.ndarray) -> None:
        msg = self._Wrench()
        msg.header.frame_id = "base_link"
        stamp(msg.header, t)
        vec = convert.vector_from_torque(torque)
        msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = (float(v) for v in vec)
        self.cmd_pub.publish(msg)

    def _on_timer(self) -> None:
        state = self.core.watchdog(wall())
        if state == "stop" and self._last_tick > -math.inf:
            self._publish_torque(self._last_tick, np.zeros(2))
        self._status_count += 1
        self._publish_status(force=self._status_count % 10 == 0)
        if not self._library_sent and self.core.library is not None:
            self._library_sent = True
            self.library_pub.publish(self._library_markers())

    def _publish_status(self, force: bool = False) -> None:
        status = self.core.status(wall())
        key = (status["state"], status["message"], status["policy"], status["staleness"])
        text = str(key)
        if force or text != self._status_text:
            self._status_text = text
            self.status_pub.publish(self._String(data=self.core.status_json()))

    def _publish_plan(self, t: float) -> None:
        from geometry_msgs.msg import PoseStamped

        rows = self.core.plan_rows()
        lib = self.core.library
        path = self._Path()
        path.header.frame_id = "map"
        stamp(path.header, t)
        if lib is not None:
            for row in rows:
                ref = np.asarray(lib.policy(row).reference_positions)
                for r in ref[:: max(1, ref.shape[0] // 16)]:
                    ps = PoseStamped()
                    ps.header = path.header
                    ps.pose.position.x, ps.pose.position.y = float(r[0]), float(r[1])
                    yaw = (
                        math.atan2(float(r[3]), float(r[2])) if np.hypot(r[2], r[3]) > 1e-9 else 0.0
                    )
                    ps.pose.orientation.z, ps.pose.orientation.w = (
                        math.sin(yaw / 2),
                        math.cos(yaw / 2),
                    )
                    path.poses.append(ps)
        self.plan_pub.publish(path)
        self.domains_pub.publish(self._domain_markers(t))
        self._publish_status(force=True)

    def _domain_markers(self, t: float) -> Any:
        from visualization_msgs.msg import Marker

        from gracenav.scenarios.mcap_log import ellipse_outline

        out = self._MarkerArray()
        clear = Marker()
        clear.action = Marker.DELETEALL
        out.markers.append(clear)
        row, lib = self.core.policy, self.core.library
        if row < 0 or lib is None:
            return out
        pol = lib.policy(row)
        shapes = [(pol.start_domain, (0.12, 0.47, 0.71)), (pol.goal_domain, (0.17, 0.63, 0.17))]
        shapes += [
            (pol.outer_domain(float(s)), (1.0, 0.5, 0.05)) for s in np.linspace(0, pol.duration, 6)
        ]
        for k, (dom, rgb) in enumerate(shapes):
            m = Marker()
            m.header.frame_id = "map"
            stamp(m.header, t)
            m.ns, m.id, m.type, m.action = "domains", k, Marker.LINE_STRIP, Marker.ADD
            m.pose.orientation.w = 1.0
            m.scale.x = 0.02 if k < 2 else 0.008
            m.color.r, m.color.g, m.color.b, m.color.a = (*rgb, 1.0)
            m.text = pol.name
            from geometry_msgs.msg import Point

            for q in ellipse_outline(dom.xy_projection(), dom.center):
                m.points.append(Point(x=float(q[0]), y=float(q[1]), z=0.01))
            out.markers.append(m)
        return out

    def _library_markers(self) -> Any:
        from geometry_msgs.msg import Point
        from visualization_msgs.msg import Marker

        lib = self.core.library
        m = Marker()
        m.header.frame_id = "map"
        m.ns, m.id, m.type, m.action = "library", 0, Marker.POINTS, Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = 0.03
        m.color.r, m.color.g, m.color.b, m.color.a = 0.4, 0.4, 0.4, 0.8
        xy = np.unique(np.asarray(lib.start_xy, dtype=float), axis=0)
        m.points = [Point(x=float(p[0]), y=float(p[1]), z=0.0) for p in xy]
        out = self._MarkerArray()
        out.markers.append(m)
        return out

    def close(self) -> None:
        st = self.core.status(wall())
        self._log(
            "info",
            f"control loop: {st['ticks']} ticks at {st['control_rate_hz']:.0f} Hz (wall clock); "
            f"reading to command {st['tick_ms_mean']:.3f} ms mean, {st['tick_ms_max']:.2f} ms max",
        )
        self.core.close()
        self.node.destroy_node()


def _route_goals(points: np.ndarray, speed: float) -> list[np.ndarray]:
    """Goals of a route: each point, moving at ``speed`` (m/s) toward the next (the
    first after the last); at rest when ``speed`` is 0."""
    out = []
    n = len(points)
    for k in range(n):
        d = points[(k + 1) % n] - points[k]
        norm = float(np.hypot(*d))
        v = speed * d / norm if (speed > 0 and norm > 0) else np.zeros(2)
        out.append(np.r_[points[k], v])
    return out


def run_navigator(overrides: dict[str, Any], ros_args: Sequence[str] = ()) -> int:
    """Run the navigator until SIGINT (or the task's end with ``exit_when_done``).
    Returns 0 after a clean shutdown, 1 when ``exit_when_done`` ended it on a task
    that did not reach its goal."""
    rclpy = start_rclpy(ros_args)
    nav = None
    status = 0
    try:
        nav = _Navigator(rclpy, overrides)
        with signals_ask_to_stop():
            spin_until(rclpy, nav.node, lambda: nav is not None and nav.done)
        if nav.done and nav.finished not in ("goal_reached", "loops_completed"):
            status = 1
    except KeyboardInterrupt:
        pass
    finally:
        if nav is not None:
            nav.close()
        if rclpy.ok():
            rclpy.shutdown()
    return status
