"""gracenav in a ROS 2 system: the hybrid controller and the simulated ballbot as nodes.

Nothing here imports rclpy at import time: :mod:`gracenav.ros.convert` and
:mod:`gracenav.ros.core` are plain numpy (the message conventions and the navigator's
logic), and the nodes (:mod:`gracenav.ros.navigate`, :mod:`gracenav.ros.sim`) import
rclpy when they start, after :func:`gracenav.ros.env.local_dds_environment` has kept
DDS discovery on this machine. Install with ``pip install 'gracenav[ros]'`` (rclpy and
the message packages as Python wheels; no ROS installation is needed). See docs/ros.md
for the topics, frames and messages.
"""

from gracenav.ros.env import local_dds_environment

__all__ = ["local_dds_environment"]
