"""How long a planning thread keeps the others waiting: the largest gap of a 1 ms loop.

The ROS node plans on a worker thread while its control callback balances the robot
(``docs/ros.md``); online starts make that plan design and verify a maneuver on the 3D
model. Python threads share the interpreter, so a compiled kernel that held it would
stall the control loop for its whole call. This runs one trial of
``examples/campaigns/random_pairs.yaml`` (library, trees, the online start's design,
the run) on a worker thread once to warm up, then again while the main thread sleeps
1 ms at a time, and prints the largest gap between its wake-ups, its 99.9th percentile
and the trial's wall time. The worker limits its verifications to one thread, as the
ROS node's planning thread does (``--batch-threads 0``: split over every core).

    OPENBLAS_NUM_THREADS=1 python bench/bench_stall.py [--trial 5] [--batch-threads 1]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import dataclasses
import threading
import time
from pathlib import Path

import numpy as np

from gracenav.campaign import load_campaign
from gracenav.campaign.runner import trial_result
from gracenav.sim import limit_batch_threads

PAIRS = Path(__file__).resolve().parent.parent / "examples" / "campaigns" / "random_pairs.yaml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trial", type=int, default=5, help="random pairs trial (default 5)")
    ap.add_argument(
        "--batch-threads",
        type=int,
        default=1,
        help="threads the worker's verifications may split over (default 1, as the ROS "
        "node's planning thread; 0: one per core)",
    )
    args = ap.parse_args()
    campaign = load_campaign(PAIRS)
    doc = dict(campaign.scenario)
    doc["planner"] = {**(doc.get("planner") or {}), "online_starts": True}
    campaign = dataclasses.replace(campaign, scenario=doc)
    trial_result(campaign, args.trial, "gracenav")  # compiled kernels, palette, caches

    import gracenav.execution.launch as launch

    launch._MADE.clear()  # the start designed again, as in a new task
    took: list[float] = []

    def work() -> None:
        limit_batch_threads(args.batch_threads or None)
        t0 = time.perf_counter()
        trial_result(campaign, args.trial, "gracenav")
        took.append(time.perf_counter() - t0)

    thread = threading.Thread(target=work)
    gaps: list[float] = []
    last = time.perf_counter()
    thread.start()
    while thread.is_alive():
        time.sleep(0.001)
        now = time.perf_counter()
        gaps.append(now - last)
        last = now
    thread.join()
    g = np.array(gaps) * 1000.0
    print(
        f"random pairs trial {args.trial} on a worker thread, {took[0]:.2f} s wall: a 1 ms loop "
        f"waited at most {g.max():.1f} ms (99.9th percentile {np.percentile(g, 99.9):.1f} ms, "
        f"{g.size} wake-ups)"
    )


if __name__ == "__main__":
    main()
