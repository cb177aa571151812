"""Fingerprints of hybrid-controller and baseline episodes, to check that a change of
the code's structure leaves every episode as it was.

Runs the shipped scenarios (each with the hybrid controller, the first two also with
the decoupled baseline), pushed runs on the 5 m room (seeded draws as
``bench/bench_pushes.py``), runs that end in balancing mode and resume from it, a
run with a plant whose parameters differ from the controller's, and a run with
position noise. Each episode is reduced to its status, its length, its events, the
goals it reached and SHA-256 digests of its states, inputs, policies and references;
its final state is kept in full.

    GRACENAV_PALETTE=nonic python tools/episode_fingerprints.py --out FILE

The reference, ``tests/data/episode_fingerprints.json``, was made on the nonic palette
(the default then); ``tests/test_episode_fingerprints.py`` runs the same cases on it
and compares.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "src" / "gracenav" / "data" / "scenarios"
ROOM = ROOT / "examples" / "maps" / "room_5m_box.yaml"


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]


def fingerprint(ep: Any) -> dict[str, Any]:
    """What must stay equal of an episode (``ep``: gracenav.execution.Episode)."""
    dt = 1.0 / 1024.0
    return {
        "status": ep.status.value,
        "samples": int(ep.time.shape[0]),
        "time_off_grid": float(np.max(np.abs(ep.time - np.round(ep.time / dt) * dt))),
        "events": [[e.tick, e.from_policy, e.to_policy, e.reason.value] for e in ep.events],
        "goals_reached": [[round(t / dt), k] for t, k in ep.goals_reached],
        "captures": len(ep.captures),
        "replans": [[round(r.time / dt), r.reason] for r in ep.replans],
        "states": _digest(ep.states),
        "inputs": _digest(ep.inputs),
        "policy": _digest(ep.policy),
        "reference": _digest(ep.reference),
        "final_state": [float(v).hex() for v in ep.states[-1]],
        # States, inputs and references once a second and at the end, for comparisons
        # with a tolerance (the digests above change with the last bit of any float).
        "trace": np.concatenate([ep.states, ep.inputs, ep.reference], axis=1)[
            np.r_[np.arange(0, ep.time.size, 1024), ep.time.size - 1]
        ].tolist(),
    }


def cases(quick: bool = False) -> Iterator[tuple[str, Callable[[], list[Any]]]]:
    """(name, run) for every case; ``run()`` returns its episodes."""
    from gracenav.execution import ExecutionOptions, HybridController
    from gracenav.library import build_library
    from gracenav.palette import load_palette
    from gracenav.scenarios import load_scenario, run_scenario
    from gracenav.world import load_map

    try:
        from gracenav.planning.graph import build_graph
        from gracenav.sim import Model3DPlant, Push, SimulationOptions, state_from_position
    except ImportError:  # the code before the per-tick controller, which made the reference
        from gracenav.graph import build_graph  # type: ignore[import-not-found,no-redef]
        from gracenav.simulate import (  # type: ignore[import-not-found,no-redef]
            Push,
            SimulationOptions,
            state_from_position,
        )

        Model3DPlant = None

    names = ["fig5_point_to_point", "fig7_drag"]
    if not quick:
        names += ["fig8_surveillance", "corridor_person", "doorway_cart"]
    for name in names:
        sc = load_scenario(SCENARIOS / f"{name}.yaml")
        yield name, lambda sc=sc: list(run_scenario(sc).episodes)
        if name in ("fig5_point_to_point", "fig7_drag"):
            dec = dataclasses.replace(sc, planner="decoupled")
            yield f"{name}/decoupled", lambda dec=dec: list(run_scenario(dec).episodes)

    palette = load_palette()
    lib = build_library(palette, load_map(ROOM), footprint_radius=0.2, max_halvings=1)
    graph = build_graph(lib)
    r = palette.params.ball_radius
    x0 = state_from_position(np.array([1.0, 1.0, 0.0, 0.0]), r)
    goal = [np.array([4.0, 4.0, 0.0, 0.0])]
    rng = np.random.default_rng(0)
    n = 4 if quick else 12
    pushes = [
        Push(float(t), (float(m * np.cos(a)), float(m * np.sin(a))))
        for m, a, t in zip(
            rng.uniform(0.0, 16.0, n),
            rng.uniform(0.0, 2.0 * np.pi, n),
            rng.uniform(0.5, 11.5, n),
            strict=True,
        )
    ]

    def pushed(push: Push, options: ExecutionOptions) -> list[Any]:
        hc = HybridController(lib, graph)
        return [hc.run(x0, goal, disturbances=[push], options=options)]

    for i, push in enumerate(pushes):
        yield f"push/{i}", lambda push=push: pushed(push, ExecutionOptions(max_time=60.0))
    # Large pushes: caught, or with captures off balancing mode, then resumed (or not).
    big = [Push(3.0, (22.0, 5.0)), Push(6.0, (-4.0, 24.0))]
    for i, push in enumerate(big):
        for capture, resume in ((True, True), (False, False), (False, True)):
            opts = ExecutionOptions(max_time=40.0, capture=capture, resume_from_balancing=resume)
            yield f"big_push/{i}/{capture}/{resume}", lambda p=push, o=opts: pushed(p, o)
    # A plant heavier than the controller believes, and one with a larger ball.
    for field, factor in (("body_mass", 1.15), ("ball_radius", 1.05)):
        plant = dataclasses.replace(
            palette.params, **{field: getattr(palette.params, field) * factor}
        )

        def mismatch(plant: Any = plant) -> list[Any]:
            if Model3DPlant is None:  # before: the controller took the plant's parameters
                old = HybridController(lib, graph, params=plant)
                return [old.run(x0, goal, disturbances=[pushes[0]])]
            hc = HybridController(lib, graph)
            return [hc.run(x0, goal, disturbances=[pushes[0]], plant=Model3DPlant(plant))]

        yield f"mismatch/{field}", mismatch
    noisy = ExecutionOptions(simulation=SimulationOptions(position_noise_std=0.005, seed=3))
    yield "noise", lambda: pushed(pushes[1], noisy)


def compute(quick: bool = False) -> dict[str, list[dict[str, Any]]]:
    """Fingerprints of every case."""
    return {name: [fingerprint(ep) for ep in run()] for name, run in cases(quick)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument(
        "--quick", action="store_true", help="fewer cases (other pushes than the reference file)"
    )
    args = ap.parse_args()
    out = compute(args.quick)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"{sum(len(v) for v in out.values())} episodes in {len(out)} cases -> {args.out}")


if __name__ == "__main__":
    main()
