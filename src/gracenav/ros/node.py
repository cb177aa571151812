"""What both nodes share: rclpy started on the local DDS environment, quality of
service, map messages, time stamps and the spin loop that ends cleanly on SIGINT."""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from gracenav._util.io import note_signal, pending_signal
from gracenav.errors import ConfigError, MapError
from gracenav.ros.env import local_dds_environment

__all__ = [
    "grid_message",
    "signals_ask_to_stop",
    "spin_until",
    "start_rclpy",
    "stop_requested",
    "world_map_from_grid",
]


def start_rclpy(ros_args: Sequence[str] = ()) -> Any:
    """Set the local DDS environment, import rclpy and initialise it with ``ros_args``
    (what follows ``--ros-args`` on the command line); rclpy installs no signal handler
    (gracenav's turns SIGINT into KeyboardInterrupt). Returns the rclpy module.

    Raises
    ------
    ConfigError
        rclpy or its middleware is not installed.
    """
    local_dds_environment()
    try:
        import rclpy
        from rclpy.signals import SignalHandlerOptions
    except ImportError as exc:  # the extra is missing, or the middleware library
        raise ConfigError(
            f"the ROS 2 nodes need rclpy and Fast DDS: pip install 'gracenav[ros]' ({exc})"
        ) from None
    args = ["gracenav", "--ros-args", *ros_args] if ros_args else None
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    return rclpy


def stop_requested() -> bool:
    """Whether SIGINT or SIGTERM asked the node to stop (:func:`signals_ask_to_stop`)."""
    return pending_signal() is not None


@contextmanager
def signals_ask_to_stop() -> Iterator[None]:
    """While inside, the first SIGINT or SIGTERM only records itself
    (:func:`stop_requested`); the spin loops check it between two waits and return,
    so no KeyboardInterrupt lands inside rclpy's executor or a callback half done (the
    node's handles and the work it tracks stay consistent for the shutdown). A second
    signal raises KeyboardInterrupt at once, for a loop that does not come back. Outside
    the main thread (no signal handlers there) it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def ask(signum: int, frame: Any) -> None:
        if pending_signal() is not None:
            raise KeyboardInterrupt
        note_signal(signum)

    previous = {sig: signal.signal(sig, ask) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def spin_until(rclpy: Any, node: Any, done: Callable[[], bool], period: float = 0.05) -> None:
    """Spin ``node`` until ``done()`` or :func:`stop_requested` (a KeyboardInterrupt
    propagates)."""
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not done() and not stop_requested():
            executor.spin_once(timeout_sec=period)
    finally:
        executor.remove_node(node)
        executor.shutdown(timeout_sec=0.5)


def transient_local_qos() -> Any:
    """Reliable, transient local, depth 1: a latched topic (``/map``, the library)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=1,
        history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def stamp(msg_header: Any, t: float) -> None:
    """Set a header's stamp to ``t`` (s)."""
    ns = round(t * 1e9)
    msg_header.stamp.sec = ns // 1_000_000_000
    msg_header.stamp.nanosec = ns % 1_000_000_000


def seconds(msg_header: Any) -> float:
    """A header's stamp in seconds."""
    return float(msg_header.stamp.sec) + 1e-9 * float(msg_header.stamp.nanosec)


def grid_message(world_map: Any, t: float = 0.0) -> Any:
    """A ``nav_msgs/OccupancyGrid`` (frame ``map``) of a :class:`WorldMap`: 100 where
    occupied, −1 where unknown, 0 free; row 0 is the lowest y (as map_server)."""
    from nav_msgs.msg import OccupancyGrid

    occ = np.asarray(world_map.occupied, dtype=bool)
    data = np.where(occ, 100, 0).astype(np.int8)
    if world_map.unknown is not None:
        data[np.asarray(world_map.unknown, dtype=bool)] = -1
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    stamp(msg.header, t)
    msg.info.resolution = float(world_map.resolution)
    msg.info.height, msg.info.width = (int(n) for n in occ.shape)
    msg.info.origin.position.x = float(world_map.origin[0])
    msg.info.origin.position.y = float(world_map.origin[1])
    msg.info.origin.orientation.w = 1.0
    msg.data = data.ravel().tolist()
    return msg


def world_map_from_grid(msg: Any) -> Any:
    """The :class:`WorldMap` of a ``nav_msgs/OccupancyGrid``: occupied where the value is
    ≥ 50 or unknown (−1), as map_server's trinary threshold.

    Raises
    ------
    MapError
        A frame other than ``map``, a rotated origin, or sizes that do not match.
    """
    from gracenav.world.occupancy import WorldMap

    if msg.header.frame_id not in ("map", "/map"):
        raise MapError(f"/map: frame_id is {msg.header.frame_id!r}, expected 'map'")
    q = msg.info.origin.orientation
    if abs(q.z) > 1e-9 or abs(q.x) > 1e-9 or abs(q.y) > 1e-9:
        raise MapError("/map: a rotated origin is not supported (yaw must be 0)")
    h, w = int(msg.info.height), int(msg.info.width)
    data = np.asarray(msg.data, dtype=np.int16)
    if data.size != h * w or h < 1 or w < 1:
        raise MapError(f"/map: {data.size} cells for a {w} x {h} grid")
    grid = data.reshape(h, w)
    unknown = grid < 0
    return WorldMap(
        origin=np.array([msg.info.origin.position.x, msg.info.origin.position.y]),
        resolution=float(msg.info.resolution),
        occupied=(grid >= 50) | unknown,
        unknown=unknown if np.any(unknown) else None,
        name="map",
        source="/map",
    )


def wall() -> float:
    """Monotonic wall time (s)."""
    return time.monotonic()
