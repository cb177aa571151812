"""``gracenav ros navigate | sim | demo``: the ROS 2 nodes (needs ``gracenav[ros]``).

DDS discovery stays on this machine unless the environment says otherwise
(:func:`gracenav.ros.env.local_dds_environment`); everything after ``--ros-args`` goes
to ROS (``--params-file FILE``, ``-p name:=value``, ``-r from:=to``).
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path
from typing import Any

from gracenav.cli._common import add_palette_argument, number

__all__ = ["register"]

_ROS_ARGS_HELP = (
    "everything after it goes to ROS: --params-file FILE.yaml, -p name:=value, "
    "-r /topic:=/other (see docs/ros.md for the parameters)"
)


def _fig5() -> Path:
    return Path(
        str(resources.files("gracenav") / "data" / "scenarios" / "fig5_point_to_point.yaml")
    )


def register(sub: Any) -> None:
    """Add the ``ros`` command group."""
    p = sub.add_parser(
        "ros",
        help="run gracenav as ROS 2 nodes (navigator, simulated robot, demo)",
        description=(
            "ROS 2 nodes over DDS (discovery on this machine only unless "
            "ROS_AUTOMATIC_DISCOVERY_RANGE / ROS_LOCALHOST_ONLY say otherwise). Needs "
            "pip install 'gracenav[ros]'. Topics, frames and messages: docs/ros.md."
        ),
    )
    s = p.add_subparsers(dest="what", metavar="NODE", parser_class=type(p))
    s.required = True
    n = s.add_parser(
        "navigate",
        help="the hybrid controller as a node",
        description=(
            "Subscribes to /odom, /imu, /map (unless --map), /goal_pose and /gracenav/route; "
            "publishes /gracenav/cmd_torque at every state reading (the control rate), "
            "/gracenav/plan, /gracenav/domains, /gracenav/library and /gracenav/status."
        ),
    )
    n.add_argument("--map", type=Path, default=None, help="map or scenario file (else /map)")
    n.add_argument("--goal", type=float, nargs=2, metavar=("X", "Y"), default=None)
    add_palette_argument(n)
    n.add_argument("--log", type=Path, default=None, metavar="FILE.mcap", help="record the run")
    n.add_argument(
        "--exit-when-done",
        action="store_true",
        help="exit when the task ends (status 0 if it reached its goal, else 1)",
    )
    n.add_argument("--ros-args", nargs=argparse.REMAINDER, default=[], help=_ROS_ARGS_HELP)
    n.set_defaults(func=run_navigate)
    m = s.add_parser(
        "sim",
        help="the simulated ballbot (3D model) as a node",
        description=(
            "Publishes /clock, /imu and /odom every 1/1024 s of simulated time and waits for "
            "that tick's /gracenav/cmd_torque (lockstep); takes pushes on /gracenav/push; "
            "publishes /map when given --map."
        ),
    )
    m.add_argument("--map", type=Path, default=None, help="map or scenario file to publish")
    m.add_argument("--start", type=float, nargs=2, metavar=("X", "Y"), default=None)
    m.add_argument("--realtime", action="store_true", help="run in real time, not lockstep")
    m.add_argument(
        "--max-sim-time",
        type=number(minimum=0.0, unit="s"),
        default=None,
        help="stop after this much simulated time (s)",
    )
    m.add_argument("--ros-args", nargs=argparse.REMAINDER, default=[], help=_ROS_ARGS_HELP)
    m.set_defaults(func=run_sim)
    d = s.add_parser(
        "demo",
        help="both nodes on the paper's Fig. 5 map, one goal",
        description=(
            "Starts `gracenav ros sim` (robot at (0, 0), the Fig. 5 map on /map) and "
            "`gracenav ros navigate` (goal (2, 2)) as two processes talking over DDS on "
            "this machine, waits for the goal, stops both and prints the control rate."
        ),
    )
    d.add_argument("--log", type=Path, default=None, metavar="FILE.mcap", help="record the run")
    d.add_argument(
        "--timeout",
        type=number(positive=True, maximum=3600.0, unit="s"),
        default=300.0,
        help="give up after this wall time (s)",
    )
    d.set_defaults(func=run_demo)


def _check_ros() -> None:
    import importlib.util

    from gracenav.errors import ConfigError

    if importlib.util.find_spec("rclpy") is None:
        raise ConfigError("the ROS 2 nodes need rclpy: pip install 'gracenav[ros]'")


def _finish(status: int) -> int:
    """A node that shut down cleanly after SIGINT exits with ``status``."""
    from gracenav._util.io import note_signal

    note_signal(None)
    return status


def run_navigate(args: argparse.Namespace) -> int:
    """Run ``gracenav ros navigate``."""
    from gracenav.cli.run_cmd import check_log_path

    _check_ros()
    check_log_path(args.log)
    overrides: dict[str, Any] = {}
    if args.map is not None:
        overrides["map_file"] = str(args.map)
    if args.goal is not None:
        overrides["goal"] = [float(v) for v in args.goal]
    if args.palette is not None:
        from gracenav.palette import load_palette

        load_palette(args.palette)  # a bad file or name: one line, before ROS starts
        overrides["palette"] = str(args.palette)
    if args.log is not None:
        overrides["log_file"] = str(args.log)
    if args.exit_when_done:
        overrides["exit_when_done"] = True
    from gracenav.ros.navigate import run_navigator

    return _finish(run_navigator(overrides, args.ros_args))


def run_sim(args: argparse.Namespace) -> int:
    """Run ``gracenav ros sim``."""
    _check_ros()
    overrides: dict[str, Any] = {}
    if args.map is not None:
        overrides["map_file"] = str(args.map)
    if args.start is not None:
        overrides["start"] = [float(v) for v in args.start]
    if args.realtime:
        overrides["lockstep"] = False
    if args.max_sim_time is not None:
        overrides["max_sim_time"] = float(args.max_sim_time)
    from gracenav.ros.sim import run_sim as run

    return _finish(run(overrides, args.ros_args))


def run_demo(args: argparse.Namespace) -> int:
    """Run ``gracenav ros demo``."""
    from gracenav.cli.run_cmd import check_log_path

    _check_ros()
    check_log_path(args.log)
    from gracenav.ros.demo import run_demo as run

    return _finish(run(_fig5(), (2.0, 2.0), (0.0, 0.0), log=args.log, timeout=args.timeout))
