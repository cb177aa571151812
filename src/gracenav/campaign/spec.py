"""Campaign file format: a base scenario and the distributions of the trials' inputs."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gracenav._util.validate import Fields, check_number

__all__ = ["Campaign", "load_campaign", "parse_campaign"]

_TOP = (
    "name",
    "scenario",
    "trials",
    "seed",
    "planners",
    "push",
    "noise",
    "plant_params",
    "pairs",
    "cluster",
)
PLANNERS = ("gracenav", "gracenav_paper", "decoupled")
"""Planners a campaign may compare: ``gracenav`` (verified policies, with the
balancing-mode fallback, as ``gracenav run``), ``gracenav_paper`` (the same without the
fallback, the paper's behaviour: ``planner.resume_from_balancing: false``) and
``decoupled`` (the plan-then-track baseline, :mod:`gracenav.baseline`)."""
MAX_TRIALS = 100_000


@dataclass(frozen=True)
class Campaign:
    """A parsed campaign.

    Attributes
    ----------
    name : str
    scenario : dict
        The base scenario document (parsed YAML), with map paths made absolute.
    trials : int
        Number of trials per planner.
    seed : int
    planners : tuple of str
    push_impulse : tuple of float or None
        (low, high) of the uniform push impulse magnitude (N s); None: no push.
    push_time : tuple of float
        (low, high) of the uniform push time (s); the direction is uniform.
    noise_std : tuple of float
        Position noise standard deviations (m), one drawn uniformly per trial.
    plant_params : tuple of (str, float, float)
        Field, low and high factor, drawn uniformly per trial.
    pairs : tuple of float or None
        (clearance (m), minimum start-goal distance (m)) of random start/goal pairs
        drawn from the map's free space; None: the base scenario's start and goal.
    digest : str
        SHA-256 of everything that decides a trial's inputs and its scenario (the
        parsed file with the base scenario read in, without ``planners`` and
        ``cluster``): the resume check. Adding a planner to a finished campaign runs
        only the new planner's trials.
    cluster : str or None
        Address of a Dask scheduler to run on (``--cluster`` overrides it); None: a
        local process pool.
    """

    name: str
    scenario: dict[str, Any]
    trials: int
    seed: int
    planners: tuple[str, ...]
    push_impulse: tuple[float, float] | None
    push_time: tuple[float, float]
    noise_std: tuple[float, ...]
    plant_params: tuple[tuple[str, float, float], ...]
    digest: str
    pairs: tuple[float, float] | None = None
    cluster: str | None = None


def _range(f: Fields, key: str, *, minimum: float, maximum: float) -> tuple[float, float]:
    value = f.get(key)
    path = f.path(key)
    if not isinstance(value, list) or len(value) != 2:
        raise f.fail(f"'{path}' must be a list [low, high]")
    lo, hi = (
        check_number(v, f"{path}[{i}]", f.source, minimum=minimum, maximum=maximum)
        for i, v in enumerate(value)
    )
    if lo > hi:
        raise f.fail(f"'{path}' low {lo:g} exceeds high {hi:g}")
    return float(lo), float(hi)


def parse_campaign(data: Any, *, source: str = "campaign", base: Path | None = None) -> Campaign:
    """Check a campaign document and return a :class:`Campaign`.

    Raises
    ------
    ConfigError
        One line naming the key path.
    """
    from gracenav.scenarios import PLANT_FACTOR_FIELDS, PLANT_FACTOR_RANGE

    f = Fields(data, "", source)
    f.check_keys(_TOP)
    name = f.get("name", "campaign")
    if not isinstance(name, str) or not name:
        raise f.fail("'name' must be a non-empty string")
    scen = f.get("scenario")
    base = base if base is not None else Path.cwd()
    if isinstance(scen, str):
        path = (base / scen).resolve()
        if not path.is_file():
            raise f.fail(f"'scenario': file {path} not found")
        from gracenav._util.io import parse_yaml, read_text_file

        scen_doc = parse_yaml(read_text_file(path, "scenario file"), str(path))
        scen_base = path.parent
    elif isinstance(scen, dict):
        scen_doc = dict(scen)
        scen_base = base
    else:
        raise f.fail("'scenario' must be a path or a mapping")
    if not isinstance(scen_doc, dict):
        raise f.fail("'scenario' must hold a mapping")
    m = scen_doc.get("map")
    if isinstance(m, dict) and isinstance(m.get("ros_map"), str):
        scen_doc["map"] = {**m, "ros_map": str((scen_base / m["ros_map"]).resolve())}
    trials = f.integer("trials", minimum=1, maximum=MAX_TRIALS)
    seed = f.integer("seed", 0, minimum=0, maximum=2**32 - 1)
    planners = f.get("planners", ["gracenav"])
    if not isinstance(planners, list) or not planners or any(p not in PLANNERS for p in planners):
        raise f.fail(f"'planners' must be a non-empty list of {', '.join(PLANNERS)}")
    if len(set(planners)) != len(planners):
        raise f.fail("'planners' lists a planner twice")
    cluster = f.string("cluster") if "cluster" in f.data else None
    impulse: tuple[float, float] | None = None
    ptime = (0.0, 0.0)
    if "push" in f.data:
        p = f.sub("push")
        p.check_keys(("impulse", "time"))
        impulse = _range(p, "impulse", minimum=0.0, maximum=1000.0)
        ptime = _range(p, "time", minimum=0.0, maximum=1800.0)
    noise = f.get("noise", [0.0])
    if not isinstance(noise, list) or not noise:
        raise f.fail("'noise' must be a non-empty list of standard deviations (m)")
    noise_std = tuple(
        check_number(v, f"noise[{i}]", source, minimum=0.0, maximum=1.0, unit="m")
        for i, v in enumerate(noise)
    )
    factors = []
    if "plant_params" in f.data:
        pp = f.sub("plant_params")
        pp.check_keys(PLANT_FACTOR_FIELDS)
        for k in pp.data:
            lo, hi = _range(pp, k, minimum=PLANT_FACTOR_RANGE[0], maximum=PLANT_FACTOR_RANGE[1])
            factors.append((str(k), lo, hi))
    pairs = None
    if "pairs" in f.data:
        pf = f.sub("pairs")
        pf.check_keys(("clearance", "min_distance"))
        pairs = (
            float(pf.number("clearance", minimum=0.0, maximum=100.0, unit="m")),
            float(pf.number("min_distance", 0.0, minimum=0.0, maximum=1.0e4, unit="m")),
        )
    resolved = {k: v for k, v in f.data.items() if k not in ("planners", "cluster")}
    resolved["scenario"] = scen_doc
    digest = hashlib.sha256(json.dumps(resolved, sort_keys=True, default=str).encode()).hexdigest()
    return Campaign(
        cluster=cluster,
        pairs=pairs,
        name=name,
        scenario=scen_doc,
        trials=trials,
        seed=seed,
        planners=tuple(planners),
        push_impulse=impulse,
        push_time=ptime,
        noise_std=noise_std,
        plant_params=tuple(factors),
        digest=digest,
    )


def load_campaign(path: str | Path) -> Campaign:
    """Read and check a campaign YAML file."""
    from gracenav._util.io import parse_yaml, read_text_file

    path = Path(path)
    data = parse_yaml(read_text_file(path, "campaign file"), str(path))
    return parse_campaign(data, source=str(path), base=path.parent)
