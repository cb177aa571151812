"""The DDS environment of gracenav's nodes: discovery stays on this machine unless the
user says otherwise."""

from __future__ import annotations

import os
from collections.abc import MutableMapping

__all__ = ["LOCAL_DDS", "local_dds_environment"]

#: Set by :func:`local_dds_environment` where the user has not set them: ROS 2 Kilted's
#: discovery range (localhost only), its predecessor's switch for older ROS 2 releases,
#: and the middleware the wheels ship.
LOCAL_DDS: dict[str, str] = {
    "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    "ROS_LOCALHOST_ONLY": "1",
    "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
}


def local_dds_environment(env: MutableMapping[str, str] | None = None) -> dict[str, str]:
    """Keep DDS traffic on this machine: set each variable of :data:`LOCAL_DDS` the
    environment does not set yet (a value the user set is kept). Call before rclpy is
    imported; returns the values in force."""
    target = os.environ if env is None else env
    for key, value in LOCAL_DDS.items():
        if not target.get(key):
            target[key] = value
    return {key: target[key] for key in LOCAL_DDS}
