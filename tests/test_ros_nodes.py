"""The two ROS 2 nodes in separate processes over real DDS on this machine: the robot
reaches the goal, recovers from a push sent on the topic, bad messages are dropped with
a log line (the navigator reading its noise from the odometry's covariances), silence
makes the navigator hold and then stop, and SIGINT ends both cleanly. Every wait is
bounded."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

with warnings.catch_warnings():  # rosidl's parser imports lark, which imports sre_parse
    warnings.simplefilter("ignore", DeprecationWarning)
    rclpy = pytest.importorskip("rclpy")
    pytest.importorskip("mcap")
    from geometry_msgs.msg import PoseStamped, Vector3Stamped
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Imu
    from std_msgs.msg import String

from gracenav.ros.demo import node_command
from gracenav.ros.env import local_dds_environment

FIG5 = (
    Path(__file__).resolve().parent.parent / "src/gracenav/data/scenarios/fig5_point_to_point.yaml"
)
GOAL = (2.0, 2.0)
PUSH = (0.0, 9.0)
pytestmark = pytest.mark.filterwarnings(
    # rosidl's parser imports lark, which imports the deprecated sre_parse
    "ignore:module 'sre_.*' is deprecated:DeprecationWarning"
)
#: A DDS domain of its own, so the test meets no other nodes on this machine.
DOMAIN = str(51 + os.getpid() % 50)


@pytest.fixture
def ros_env(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    monkeypatch.setenv("ROS_DOMAIN_ID", DOMAIN)
    # The test's DDS traffic stays on this machine whatever the environment says.
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_LOCALHOST_ONLY", "1")
    env = dict(os.environ)
    local_dds_environment(env)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    for key, value in env.items():
        if key.startswith(("ROS_", "RMW_")):
            monkeypatch.setenv(key, value)
    return env


#: The whole test ends within this wall time (s), whatever each wait allows.
DEADLINE_S = 85.0
_deadline = [math.inf]


def _wait(what: str, cond: Callable[[], bool], spin: Callable[[], None], limit: float) -> None:
    end = min(time.monotonic() + limit, _deadline[0])
    while time.monotonic() < end:
        spin()
        if cond():
            return
    raise AssertionError(f"timed out after {limit:g} s waiting for {what}")


def _stop(proc: subprocess.Popen[bytes], limit: float = 10.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            raise AssertionError(
                f"{proc.args!r} did not end within {limit:g} s of SIGINT"
            ) from None
    return int(proc.returncode)


@pytest.mark.slow
def test_nodes_reach_the_goal_recover_from_a_push_and_stop_cleanly(
    tmp_path: Path, ros_env: dict[str, str]
) -> None:
    from gracenav.scenarios.mcap_log import LOG_CHANNELS

    t_start = time.monotonic()
    _deadline[0] = t_start + DEADLINE_S
    log = tmp_path / "navigator.mcap"
    sim_err = (tmp_path / "sim.log").open("wb")
    nav_err = (tmp_path / "nav.log").open("wb")

    stopped = False

    def spin() -> None:
        executor.spin_once(timeout_sec=0.02)
        assert stopped or sim.poll() is None, (
            f"the simulator ended: {(tmp_path / 'sim.log').read_text()}"
        )
        assert nav.poll() is None, f"the navigator ended: {(tmp_path / 'nav.log').read_text()}"

    def state() -> dict[str, Any]:
        return status[-1] if status else {}

    def nav_log() -> str:
        nav_err.flush()
        return (tmp_path / "nav.log").read_text()

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("gracenav_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    sim = subprocess.Popen(
        node_command("ros", "sim", "--map", str(FIG5), "--start", "0", "0"),
        env=ros_env,
        stdout=sim_err,
        stderr=subprocess.STDOUT,
    )
    nav = subprocess.Popen(
        node_command(
            "ros",
            "navigate",
            "--log",
            str(log),
            "--ros-args",
            "-p",
            "state_timeout:=0.2",
            "-p",
            "noise_from_covariance:=true",  # the simulator's zero covariances: no filter
        ),
        env=ros_env,
        stdout=nav_err,
        stderr=subprocess.STDOUT,
    )
    try:
        status: list[dict[str, Any]] = []
        odom: list[tuple[float, float, float, float, float]] = []

        def on_odom(m: Any) -> None:
            if m.header.frame_id == "odom" and math.isfinite(m.pose.pose.position.x):
                t = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
                p, v = m.pose.pose.position, m.twist.twist.linear
                odom.append((t, p.x, p.y, v.x, v.y))

        node.create_subscription(
            String, "/gracenav/status", lambda m: status.append(json.loads(m.data)), 50
        )
        node.create_subscription(Odometry, "/odom", on_odom, 100)
        goal_pub = node.create_publisher(PoseStamped, "/goal_pose", 10)
        push_pub = node.create_publisher(Vector3Stamped, "/gracenav/push", 10)
        odom_pub = node.create_publisher(Odometry, "/odom", 10)
        imu_pub = node.create_publisher(Imu, "/imu", 10)

        _wait("the library", lambda: state().get("state") == "ready", spin, 60)
        # Bad readings from a third node: wrong frame, NaN; a goal in the wrong frame.
        bad = Odometry()
        bad.header.frame_id = "wrong_frame"
        odom_pub.publish(bad)
        nan = Odometry()
        nan.header.frame_id = "odom"
        nan.pose.pose.position.x = float("nan")
        odom_pub.publish(nan)
        negative = Odometry()
        negative.header.frame_id = "odom"
        negative.pose.covariance[7] = -1.0
        odom_pub.publish(negative)
        imu = Imu()
        imu.header.frame_id = "base_link"
        imu.orientation.w = float("nan")
        imu_pub.publish(imu)
        wrong_goal = PoseStamped()
        wrong_goal.header.frame_id = "base_link"
        goal_pub.publish(wrong_goal)
        goal = PoseStamped()
        goal.header.frame_id = "map"
        goal.pose.position.x, goal.pose.position.y = GOAL
        goal.pose.orientation.w = 1.0
        goal_pub.publish(goal)
        _wait("the task to start", lambda: state().get("state") == "running", spin, 30)
        _wait("2 s of motion", lambda: bool(odom) and odom[-1][0] >= 2.0, spin, 30)
        push = Vector3Stamped()
        push.header.frame_id = "map"
        push.vector.x, push.vector.y = PUSH
        push_pub.publish(push)
        t_push = odom[-1][0]
        _wait("the end of the task", lambda: state().get("state") == "done", spin, 60)
        assert state()["message"] == "goal_reached"
        _wait("the last reading", lambda: bool(odom) and odom[-1][0] > t_push + 1.0, spin, 5)
        end = np.array(odom[-1])
        assert math.hypot(end[1] - GOAL[0], end[2] - GOAL[1]) <= 0.05
        # The push changed the ball's y velocity by more than the plan did over the
        # same time: the robot was knocked off its reference and recovered.
        o = np.array(odom)
        before = o[(o[:, 0] > t_push - 0.05) & (o[:, 0] <= t_push)]
        after = o[(o[:, 0] > t_push) & (o[:, 0] <= t_push + 0.6)]
        assert before.size and after.size
        jump = np.max(np.abs(after[:, 4] - before[-1, 4]))
        assert jump > 0.05, f"the push did not reach the robot (|Δẏ| = {jump:.3f} m/s)"
        rate = float(state()["control_rate_hz"])
        assert rate > 100.0
        text = nav_log()
        assert "/odom: frame_id 'wrong_frame' is not 'odom' or 'map'; dropped" in text
        assert "/odom: position or velocity is not finite; dropped" in text
        assert "/odom: a position or velocity variance is negative or not finite; dropped" in text
        assert "/imu: orientation or angular velocity is not finite; dropped" in text
        assert "/goal_pose: frame_id 'base_link' is not 'map'; dropped" in text
        assert "push of (0, 9) N s" in (tmp_path / "sim.log").read_text()
        # Silence: the simulator stops; the navigator holds, then stops.
        stopped = True
        code = _stop(sim)
        assert code == 0, f"the simulator exited with {code}: {(tmp_path / 'sim.log').read_text()}"
        _wait("the navigator to stop", lambda: state().get("state") == "stopped", spin, 10)
        text = nav_log()
        assert "holding the last command" in text and "stopping, zero torque" in text
        code = _stop(nav)
        assert code == 0, f"the navigator exited with {code}: {nav_log()}"
    finally:
        for proc in (sim, nav):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.shutdown(context=context)
        sim_err.close()
        nav_err.close()
    sim_text = (tmp_path / "sim.log").read_text()
    nav_text = (tmp_path / "nav.log").read_text()
    assert "Traceback" not in sim_text and "Traceback" not in nav_text, nav_text + sim_text
    assert "control loop:" in nav_text and "ticks per second" in sim_text
    # The navigator's recording: every channel (the push arrow on /gracenav/path).
    from mcap.reader import make_reader

    topics: dict[str, int] = {}
    with log.open("rb") as fh:
        for _, channel, _ in make_reader(fh).iter_messages():
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
    assert set(topics) == set(LOG_CHANNELS)
    assert topics["/gracenav/pushes"] == 1 and topics["/gracenav/state"] > 1000
    assert time.monotonic() - t_start < DEADLINE_S + 10.0
