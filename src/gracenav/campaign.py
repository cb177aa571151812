"""Campaigns: seeded Monte Carlo studies over a scenario, resumable, on local processes.

A campaign file (YAML) names a base scenario and what to draw for each trial::

    name: pushes on the 5 m room
    scenario: ../scenarios/room_push_base.yaml   # relative to this file
    trials: 300
    seed: 0
    draws:
      push: {impulse: [0.0, 16.0], time: [0.5, 10.0]}   # N s (uniform), s (uniform);
                                                        # direction uniform in [0, 2π)
      position_noise_std: [0.0, 0.01]                   # m (uniform)
      plant_params: {body_mass: [0.8, 1.2], ball_radius: [0.98, 1.02]}  # factors
      start: 0                                          # index into the base's starts

Trial i draws its inputs from its own generator, seeded by (seed, i) through
:class:`numpy.random.SeedSequence`, so a trial does not depend on how many trials or
processes ran before it, and re-running a campaign reproduces every trial exactly. Each
finished trial is appended to ``DIR/trials.jsonl`` (one JSON line, flushed and synced);
running the same campaign into the same ``DIR`` again skips the trials already there,
so an interrupted campaign resumes where it stopped. ``DIR/results.csv`` (one row per
trial) and ``DIR/summary.json`` (success rates with Wilson 95 % intervals, overall and
per impulse bin) are rewritten atomically at the end.

Every trial is the base scenario with its drawn inputs, validated and run by
:func:`gracenav.scenarios.run_scenario` exactly as ``gracenav run`` would.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gracenav._io import atomic_write_text, load_document
from gracenav._validate import Fields
from gracenav.errors import OutputError

__all__ = [
    "CAMPAIGN_FORMAT",
    "CampaignSpec",
    "draw_trial",
    "load_campaign",
    "run_campaign",
    "wilson_interval",
]

#: Version of the trial records; a DIR written by another version is refused.
CAMPAIGN_FORMAT = 1
#: Most trials of one campaign.
MAX_TRIALS = 100_000
#: Width of the impulse bins of summary.json (N s).
IMPULSE_BIN_NS = 4.0
#: The standard normal quantile of a two-sided 95 % interval.
_Z95 = 1.959963984540054

_COLUMNS = (
    "trial",
    "push_impulse_ns",
    "push_angle_rad",
    "push_time_s",
    "position_noise_std_m",
    "plant_params",
    "reached_goal",
    "outcome",
    "stop_reason",
    "time_s",
    "path_length_m",
    "final_error_m",
    "max_lean_deg",
    "max_jerk_mps3",
    "max_torque_nm",
    "min_clearance_m",
    "switches",
    "non_graceful_switches",
    "verified_recoveries",
    "balancing_s",
)


@dataclass(frozen=True)
class CampaignSpec:
    """A parsed campaign (see the module notes).

    Attributes
    ----------
    name : str
    source : str
        The campaign file, for messages.
    scenario : dict
        The base scenario document (as parsed from YAML).
    scenario_dir : Path
        Folder the base scenario's relative paths are resolved from.
    trials : int
    seed : int
    push : tuple of (float, float) or None
        Impulse range (N s) and time range (s) of one push per trial.
    noise : tuple of float or None
        Range of the position noise standard deviation (m).
    plant_params : dict of str to (float, float)
        Ranges of the plant parameter factors.
    start : int
        Index of the base scenario's start used by every trial.
    key : str
        Hash of the campaign and base scenario documents: what a DIR's trials were
        computed from.
    """

    name: str
    source: str
    scenario: dict[str, Any] = field(repr=False)
    scenario_dir: Path
    trials: int
    seed: int
    push: tuple[tuple[float, float], tuple[float, float]] | None
    noise: tuple[float, float] | None
    plant_params: dict[str, tuple[float, float]]
    start: int
    key: str


def _range(
    f: Fields, key: str, *, minimum: float, maximum: float, unit: str
) -> tuple[float, float]:
    """A [low, high] range within [minimum, maximum] (``unit`` for the message)."""
    lo, hi = f.vector(key, 2, what=f"[low, high] ({unit})")
    if not (minimum <= lo <= hi <= maximum):
        raise f.fail(
            f"'{f.path(key)}' must be [low, high] with {minimum:g} <= low <= high <= "
            f"{maximum:g} ({unit}), got [{lo:g}, {hi:g}]"
        )
    return float(lo), float(hi)


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign file (and its base scenario).

    Raises
    ------
    ConfigError
        For a malformed campaign or base scenario; the message names the key.
    """
    from gracenav.scenarios import (
        MAX_IMPULSE_NS,
        MAX_NOISE_STD_M,
        PLANT_FACTOR_FIELDS,
        PLANT_FACTOR_RANGE,
        parse_scenario,
    )

    path = Path(path)
    src = str(path)
    doc = load_document(path, "campaign file")
    f = Fields(doc, "", src)
    f.check_keys({"name", "scenario", "trials", "seed", "draws"})
    name = f.string("name", path.stem)
    scen_path = f.file("scenario", path.parent)
    scen_doc = load_document(scen_path, "scenario file")
    parse_scenario(scen_doc, source=str(scen_path), base=scen_path.parent)  # valid as is
    trials = f.integer("trials", minimum=1, maximum=MAX_TRIALS)
    seed = f.integer("seed", 0, minimum=0, maximum=2**63 - 1)
    d = f.sub("draws", {})
    d.check_keys({"push", "position_noise_std", "plant_params", "start"})
    push = None
    if "push" in d.data:
        p = d.sub("push")
        p.check_keys({"impulse", "time"})
        push = (
            _range(p, "impulse", minimum=0.0, maximum=MAX_IMPULSE_NS, unit="N s"),
            _range(p, "time", minimum=0.0, maximum=1e6, unit="s"),
        )
    noise = None
    if "position_noise_std" in d.data:
        noise = _range(d, "position_noise_std", minimum=0.0, maximum=MAX_NOISE_STD_M, unit="m")
    plant: dict[str, tuple[float, float]] = {}
    if "plant_params" in d.data:
        pp = d.sub("plant_params")
        pp.check_keys(set(PLANT_FACTOR_FIELDS))
        lo, hi = PLANT_FACTOR_RANGE
        for k in sorted(pp.data):
            plant[str(k)] = _range(pp, str(k), minimum=lo, maximum=hi, unit="factor")
    starts = (scen_doc.get("task") or {}).get("starts") or [None]
    start = d.integer("start", 0, minimum=0, maximum=max(len(starts) - 1, 0))
    blob = json.dumps(
        {"format": CAMPAIGN_FORMAT, "campaign": doc, "scenario": scen_doc},
        sort_keys=True,
        default=str,
    )
    return CampaignSpec(
        name=name,
        source=src,
        scenario=scen_doc,
        scenario_dir=scen_path.parent,
        trials=trials,
        seed=seed,
        push=push,
        noise=noise,
        plant_params=plant,
        start=start,
        key=hashlib.sha256(blob.encode()).hexdigest(),
    )


def draw_trial(spec: CampaignSpec, trial: int) -> dict[str, Any]:
    """The inputs of trial ``trial`` (0-based): drawn from its own generator, seeded by
    (campaign seed, trial), in a fixed order."""
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(trial,)))
    out: dict[str, Any] = {"trial": trial, "sim_seed": int(rng.integers(0, 2**31 - 1))}
    if spec.push is not None:
        (i0, i1), (t0, t1) = spec.push
        out["push_impulse_ns"] = float(rng.uniform(i0, i1))
        out["push_angle_rad"] = float(rng.uniform(0.0, 2.0 * math.pi))
        out["push_time_s"] = float(rng.uniform(t0, t1))
    if spec.noise is not None:
        out["position_noise_std_m"] = float(rng.uniform(*spec.noise))
    if spec.plant_params:
        out["plant_params"] = {k: float(rng.uniform(*r)) for k, r in spec.plant_params.items()}
    return out


def _trial_document(spec: CampaignSpec, inputs: dict[str, Any]) -> dict[str, Any]:
    doc = json.loads(json.dumps(spec.scenario))  # a deep copy of plain data
    task = doc.setdefault("task", {})
    if isinstance(task.get("starts"), list):
        task["starts"] = [task["starts"][spec.start]]
    sim = doc.setdefault("simulation", {})
    sim["seed"] = inputs["sim_seed"]
    if "position_noise_std_m" in inputs:
        sim["position_noise_std"] = inputs["position_noise_std_m"]
    if "plant_params" in inputs:
        sim["plant_params"] = dict(inputs["plant_params"])
    if "push_impulse_ns" in inputs:
        m, a = inputs["push_impulse_ns"], inputs["push_angle_rad"]
        push = {
            "kind": "push",
            "time": inputs["push_time_s"],
            "impulse": [m * math.cos(a), m * math.sin(a)],
        }
        doc["disturbances"] = [*(doc.get("disturbances") or []), push]
    return doc


def run_trial(spec: CampaignSpec, trial: int, params: Any = None) -> dict[str, Any]:
    """Run trial ``trial`` and return its record (inputs and outcome); ``params``: the
    simulated robot's parameters (:class:`BallbotParams`, default the palette's), which
    the trial's plant factors scale."""
    from gracenav.scenarios import parse_scenario, run_scenario

    inputs = draw_trial(spec, trial)
    sc = parse_scenario(
        _trial_document(spec, inputs),
        source=f"{spec.source} trial {trial}",
        base=spec.scenario_dir,
    )
    run = run_scenario(sc, params=params).runs[0].to_dict()
    keep = (
        "reached_goal",
        "outcome",
        "stop_reason",
        "time_s",
        "path_length_m",
        "final_error_m",
        "max_lean_deg",
        "max_jerk_mps3",
        "max_torque_nm",
        "min_clearance_m",
        "switches",
        "non_graceful_switches",
        "verified_recoveries",
        "balancing_s",
    )
    return {**inputs, **{k: run[k] for k in keep}}


def wilson_interval(successes: int, trials: int, z: float = _Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (95 % by default); (0, 1) for
    no trials."""
    if trials <= 0:
        return 0.0, 1.0
    p = successes / trials
    denom = 1.0 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denom
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def _rate(records: list[dict[str, Any]]) -> dict[str, Any]:
    k = sum(1 for r in records if r["reached_goal"])
    lo, hi = wilson_interval(k, len(records))
    return {
        "trials": len(records),
        "goal_reached": k,
        "rate": k / len(records) if records else None,
        "wilson95": [lo, hi],
    }


def summarise(spec: CampaignSpec, records: list[dict[str, Any]]) -> dict[str, Any]:
    """The content of summary.json."""
    out: dict[str, Any] = {
        "campaign": spec.name,
        "source": spec.source,
        "key": spec.key,
        "format": CAMPAIGN_FORMAT,
        "seed": spec.seed,
        "overall": _rate(records),
        "outcomes": {},
    }
    for r in records:
        out["outcomes"][r["outcome"]] = out["outcomes"].get(r["outcome"], 0) + 1
    if spec.push is not None:
        top = spec.push[0][1]
        n_bins = max(1, math.ceil(top / IMPULSE_BIN_NS - 1e-12))
        which = [min(int(r["push_impulse_ns"] // IMPULSE_BIN_NS), n_bins - 1) for r in records]
        out["by_impulse"] = [
            {
                "impulse_ns": [b * IMPULSE_BIN_NS, min((b + 1) * IMPULSE_BIN_NS, max(top, 0.0))],
                **_rate([r for r, w in zip(records, which, strict=True) if w == b]),
            }
            for b in range(n_bins)
        ]
    done = [r["time_s"] for r in records if r["reached_goal"]]
    out["median_time_to_goal_s"] = float(np.median(done)) if done else None
    return out


def _csv(records: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_COLUMNS)
    for r in records:
        row = []
        for c in _COLUMNS:
            v = r.get(c)
            if c == "plant_params":
                v = "" if v is None else json.dumps(v, sort_keys=True)
            row.append("" if v is None else v)
        w.writerow(row)
    return buf.getvalue()


def _read_done(path: Path, spec: CampaignSpec, params: Any) -> dict[int, dict[str, Any]]:
    """Trials already in ``DIR/trials.jsonl`` (a torn last line is ignored)."""
    done: dict[int, dict[str, Any]] = {}
    if not path.exists():
        return done
    lines = path.read_text(encoding="utf-8").splitlines()
    for n, line in enumerate(lines):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            if n == len(lines) - 1:
                break  # interrupted while writing: that trial runs again
            raise OutputError(
                f"{path}: line {n + 1} is not a trial record; remove the file"
            ) from None
        if n == 0:
            if rec.get("key") != spec.key or rec.get("format") != CAMPAIGN_FORMAT:
                raise OutputError(
                    f"{path.parent}: holds trials of another campaign (or another version "
                    "of this one); use another --out or remove it"
                )
            if rec.get("params") != _params_dict(params):
                raise OutputError(
                    f"{path.parent}: its trials were run with other robot parameters "
                    "(--params); use the same file, another --out, or remove it"
                )
            continue
        done[int(rec["trial"])] = rec
    return done


def _params_dict(params: Any) -> dict[str, Any] | None:
    return None if params is None else dict(params.to_dict())


def _append(fh: Any, record: dict[str, Any]) -> None:
    fh.write(json.dumps(record, sort_keys=True, allow_nan=False) + "\n")
    fh.flush()
    os.fsync(fh.fileno())


def _init_worker() -> None:
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def _run_one(args: tuple[CampaignSpec, int, Any]) -> dict[str, Any]:
    return run_trial(*args)


def run_campaign(
    spec: CampaignSpec,
    out: str | Path,
    *,
    processes: int | None = None,
    params: Any = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, Any]]:
    """Run (or resume) a campaign into ``out``; returns every trial's record in order.

    Parameters
    ----------
    spec : CampaignSpec
    out : path-like
        The campaign's directory: ``trials.jsonl``, ``results.csv``, ``summary.json``.
    processes : int, optional
        Worker processes (default: the machine's cores); 1 runs in this process.
    params : BallbotParams, optional
        The simulated robot (default: the palette's); resuming needs the same.
    progress : callable(done, total), optional
        Called after each trial.

    Raises
    ------
    OutputError
        If ``out`` holds another campaign's trials or cannot be written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: exists and is not a directory; choose another --out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot create it: {exc.strerror}") from None
    lock = out / ".lock"
    try:
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        raise OutputError(
            f"--out {out}: another campaign is running into it (remove {lock} if none is)"
        ) from None
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot write into it: {exc.strerror}") from None
    try:
        os.close(fd)
        trials_path = out / "trials.jsonl"
        done = _read_done(trials_path, spec, params)
        if trials_path.exists():
            # Drop a line cut by an interruption, so that the next record starts a line.
            text = trials_path.read_bytes()
            keep = text.rfind(b"\n") + 1
            if keep < len(text):
                os.truncate(trials_path, keep)
        todo = [i for i in range(spec.trials) if i not in done]
        with trials_path.open("a", encoding="utf-8") as fh:
            if not trials_path.stat().st_size:
                head = {"key": spec.key, "format": CAMPAIGN_FORMAT, "campaign": spec.name}
                _append(fh, {**head, "params": _params_dict(params)})
            n_done = spec.trials - len(todo)
            if progress is not None:
                progress(n_done, spec.trials)
            procs = processes if processes is not None else (os.cpu_count() or 1)
            if procs <= 1 or len(todo) <= 1:
                results = (run_trial(spec, i, params) for i in todo)
                for rec in results:
                    done[rec["trial"]] = rec
                    _append(fh, rec)
                    n_done += 1
                    if progress is not None:
                        progress(n_done, spec.trials)
            else:
                import multiprocessing as mp
                from concurrent.futures import ProcessPoolExecutor

                ctx = mp.get_context("spawn")
                with ProcessPoolExecutor(procs, mp_context=ctx, initializer=_init_worker) as pool:
                    for rec in pool.map(_run_one, [(spec, i, params) for i in todo]):
                        done[rec["trial"]] = rec
                        _append(fh, rec)
                        n_done += 1
                        if progress is not None:
                            progress(n_done, spec.trials)
        records = [done[i] for i in range(spec.trials)]
        atomic_write_text(out / "results.csv", _csv(records))
        atomic_write_text(
            out / "summary.json",
            json.dumps(summarise(spec, records), indent=2, allow_nan=False) + "\n",
        )
        return records
    finally:
        lock.unlink(missing_ok=True)
