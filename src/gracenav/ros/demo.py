"""``gracenav ros demo``: the simulated robot and the navigator as two processes talking
over DDS on this machine, one goal."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from gracenav.ros.env import local_dds_environment

__all__ = ["node_command", "run_demo"]


def node_command(*args: str) -> list[str]:
    """The command line of ``gracenav ARGS`` with this interpreter."""
    return [sys.executable, "-m", "gracenav.cli", *args]


def _stop(proc: subprocess.Popen[bytes], grace: float = 10.0) -> int:
    """SIGINT, then wait up to ``grace`` s (SIGKILL after that); the exit status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def run_demo(
    scenario: Path,
    goal: Sequence[float],
    start: Sequence[float],
    *,
    log: Path | None = None,
    timeout: float = 300.0,
) -> int:
    """Start ``gracenav ros sim`` (the robot at ``start``, the scenario's map on
    ``/map``) and ``gracenav ros navigate`` (map from ``/map``, ``goal``) and wait up to
    ``timeout`` s (wall) for the navigator to end the task; stop both with SIGINT.
    Their log lines go to standard error. Returns 0 if the goal was reached."""
    env = dict(os.environ)
    local_dds_environment(env)
    sim = subprocess.Popen(
        node_command(
            "ros", "sim", "--map", str(scenario), "--start", f"{start[0]:g}", f"{start[1]:g}"
        ),
        env=env,
    )
    nav_args = ["ros", "navigate", "--goal", f"{goal[0]:g}", f"{goal[1]:g}", "--exit-when-done"]
    if log is not None:
        nav_args += ["--log", str(log)]
    nav = subprocess.Popen(node_command(*nav_args), env=env)
    t0 = time.monotonic()
    try:
        status = nav.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        print(f"gracenav: the demo did not end within {timeout:g} s", file=sys.stderr)
        status = 1
    finally:
        nav_status = _stop(nav)
        sim_status = _stop(sim)
    print(
        f"demo: navigator exited {nav_status}, simulator exited {sim_status} after "
        f"{time.monotonic() - t0:.1f} s"
    )
    return 0 if status == 0 and sim_status == 0 else 1
