"""Push recovery: a seeded Monte Carlo of single pushes on the 5 m room.

Each run is the point-to-point task (1, 1) -> (4, 4) at rest on
``examples/maps/room_5m_box.yaml`` (footprint 0.2 m, one lattice halving), with
one push on the body of uniform random direction, magnitude uniform in
[0, max impulse] N s, at a time uniform over the unpushed run. For each impulse
bin the table gives: runs that reached the goal; runs that left a domain and were
caught by a verified policy (the state was in its start domain S: a library policy
or a catch placed at the state, gracenav.execution.capture), and of those the runs caught by a
catch; runs that entered balancing mode (the unverified last resort); runs whose
footprint touched an obstacle or a wall (true positions against the map's
clearance).

``--mode paper`` is the paper's hybrid controller (no resumption from balancing
mode: the task stops there); ``--mode fallback`` resumes from it. The library keeps
the default stopping allowance (``--speed-clearance``, gracenav.library.build_library;
0 is the paper's instantiation); ``--design-push J`` keeps room, where the robot
moves faster than 0.8 m/s (FAN_FLOOR), for the catches of a push of J N s
(planner.design_push; default gracenav.library.DEFAULT_DESIGN_PUSH, 0: none).
``--plant mujoco`` runs the same robot in MuJoCo instead of the 3D model the policies
were verified on.
Target (paper mode): >= 99 % of >= 300 runs with pushes of 0-16 N s reach the
goal, every recovery into a verified start domain, no contact.

    OPENBLAS_NUM_THREADS=1 python bench/bench_pushes.py [--runs 300] [--mode paper]
        [--seed 0] [--speed-clearance 0.1] [--design-push 8] [--plant model3d]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import itertools
import multiprocessing as mp
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.execution import EventReason, ExecutionOptions, HybridController
from gracenav.library import DEFAULT_DESIGN_PUSH, DEFAULT_SPEED_CLEARANCE, build_library
from gracenav.palette import load_palette
from gracenav.planning.graph import build_graph
from gracenav.sim import Push, state_from_position
from gracenav.sim.plant import PLANT_KINDS, PlantKind
from gracenav.world import load_map

ROOT = Path(__file__).resolve().parent.parent
MAP = ROOT / "examples" / "maps" / "room_5m_box.yaml"
FOOTPRINT = 0.2
START = (1.0, 1.0, 0.0, 0.0)
GOAL = (4.0, 4.0, 0.0, 0.0)
BINS = (0.0, 4.0, 8.0, 12.0, 16.0)

_robot: HybridController | None = None
_resume = False
_plant: PlantKind = "model3d"


@dataclass(frozen=True)
class Outcome:
    """One pushed run."""

    impulse: float
    reached: bool
    status: str
    verified_recoveries: int
    captures: int
    balancing: bool
    contact: bool
    min_clearance: float


def _init(
    resume: bool,
    speed_clearance: float = DEFAULT_SPEED_CLEARANCE,
    plant: PlantKind = "model3d",
    design_push: float = DEFAULT_DESIGN_PUSH,
) -> None:
    global _robot, _resume, _plant
    pal = load_palette()
    lib = build_library(
        pal,
        load_map(MAP),
        footprint_radius=FOOTPRINT,
        max_halvings=1,
        speed_clearance=speed_clearance,
        design_push=design_push,
    )
    _robot = HybridController(lib, build_graph(lib))
    _resume = resume
    _plant = plant


def _run(args: tuple[float, float, float]) -> Outcome:
    magnitude, angle, push_time = args
    assert _robot is not None
    robot = _robot
    r = robot.palette.params.ball_radius
    push = Push(time=push_time, impulse=(magnitude * np.cos(angle), magnitude * np.sin(angle)))
    options = ExecutionOptions(
        max_time=60.0,
        resume_from_balancing=_resume,
        plant=_plant,
    )
    ep = robot.run(
        state_from_position(np.asarray(START), r), [GOAL], disturbances=[push], options=options
    )
    xy = ep.position_state[:, :2]
    clearance = robot.library.world_map.clearance(xy)
    inside = robot.library.world_map.is_free(xy)
    min_clear = float(np.min(np.where(inside, clearance, 0.0)))
    return Outcome(
        impulse=magnitude,
        reached=ep.reached_goal,
        status=ep.status.value,
        verified_recoveries=ep.verified_recoveries,
        captures=sum(1 for e in ep.events if e.reason is EventReason.CAPTURE),
        balancing=any(e.reason is EventReason.BALANCING for e in ep.events),
        contact=min_clear < FOOTPRINT,
        min_clearance=min_clear,
    )


def _draws(runs: int, max_impulse: float, seed: int, duration: float) -> list[Any]:
    rng = np.random.default_rng(seed)
    mags = rng.uniform(0.0, max_impulse, runs)
    angles = rng.uniform(0.0, 2.0 * np.pi, runs)
    times = rng.uniform(0.5, duration - 0.5, runs)
    return list(zip(mags.tolist(), angles.tolist(), times.tolist(), strict=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=300)
    ap.add_argument("--max-impulse", type=float, default=16.0, help="N s (default 16)")
    ap.add_argument("--mode", choices=("paper", "fallback"), default="paper")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument(
        "--speed-clearance",
        type=float,
        default=DEFAULT_SPEED_CLEARANCE,
        help=f"library stopping allowance (s, default {DEFAULT_SPEED_CLEARANCE:g}; 0: the "
        "paper's instantiation)",
    )
    ap.add_argument(
        "--design-push",
        type=float,
        default=DEFAULT_DESIGN_PUSH,
        help="push (N s) the library keeps room to catch above 0.8 m/s (default "
        f"{DEFAULT_DESIGN_PUSH:g}; 0: none)",
    )
    ap.add_argument(
        "--plant",
        choices=PLANT_KINDS,
        default="model3d",
        help="simulated robot (default model3d; mujoco: the same robot in MuJoCo, about "
        "10 s per run)",
    )
    args = ap.parse_args()
    _init(args.mode == "fallback", args.speed_clearance, args.plant, args.design_push)
    assert _robot is not None
    r = _robot.palette.params.ball_radius
    unpushed = _robot.run(
        state_from_position(np.asarray(START), r),
        [GOAL],
        options=ExecutionOptions(plant=args.plant),
    )
    draws = _draws(args.runs, args.max_impulse, args.seed, float(unpushed.time[-1]))
    t0 = time.perf_counter()
    if args.processes > 1:
        ctx = mp.get_context("fork")
        with ctx.Pool(
            args.processes,
            initializer=_init,
            initargs=(args.mode == "fallback", args.speed_clearance, args.plant, args.design_push),
        ) as pool:
            results = pool.map(_run, draws, chunksize=4)
    else:
        results = [_run(d) for d in draws]
    wall = time.perf_counter() - t0
    print(
        f"{args.runs} pushed runs (seed {args.seed}), plant {args.plant}, mode {args.mode}, "
        "speed clearance "
        f"{args.speed_clearance:g} s, design push {args.design_push:g} N s, "
        f"unpushed run {unpushed.time[-1]:.2f} s, "
        f"{len(_robot.library)} policies; {wall:.1f} s wall on {args.processes} processes"
    )
    header = (
        "impulse (N s)",
        "runs",
        "goal reached",
        "verified recovery",
        "of which capture",
        "balancing",
        "contact",
    )
    rows = [header]
    edges = list(BINS) + ([args.max_impulse] if args.max_impulse > BINS[-1] else [])
    for lo, hi in itertools.pairwise(edges):
        sel = [o for o in results if lo <= o.impulse < hi or (hi == edges[-1] and o.impulse == hi)]
        if not sel:
            continue
        rows.append(
            (
                f"{lo:g}-{hi:g}",
                str(len(sel)),
                f"{sum(o.reached for o in sel)} ({100 * np.mean([o.reached for o in sel]):.0f} %)",
                str(sum(o.verified_recoveries > 0 for o in sel)),
                str(sum(o.captures > 0 for o in sel)),
                str(sum(o.balancing for o in sel)),
                str(sum(o.contact for o in sel)),
            )
        )
    rows.append(
        (
            "all",
            str(len(results)),
            f"{sum(o.reached for o in results)} "
            f"({100 * np.mean([o.reached for o in results]):.1f} %)",
            str(sum(o.verified_recoveries > 0 for o in results)),
            str(sum(o.captures > 0 for o in results)),
            str(sum(o.balancing for o in results)),
            str(sum(o.contact for o in results)),
        )
    )
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    for row in rows:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)))
    statuses: dict[str, int] = {}
    for o in results:
        statuses[o.status] = statuses.get(o.status, 0) + 1
    print("end status:", ", ".join(f"{k} {v}" for k, v in sorted(statuses.items())))
    print(
        f"smallest footprint clearance: {min(o.min_clearance for o in results) - FOOTPRINT:+.3f} m"
    )
    for o in results:
        if o.contact:
            print(
                f"contact: {o.impulse:.1f} N s, {o.status}, clearance "
                f"{o.min_clearance - FOOTPRINT:+.3f} m, captures {o.captures}, "
                f"balancing {'yes' if o.balancing else 'no'}"
            )


if __name__ == "__main__":
    main()
