"""Run a campaign's trials on a local process pool, resumably."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from gracenav.campaign.draw import draw_trial, trial_scenario
from gracenav.campaign.spec import Campaign
from gracenav.errors import OutputError

__all__ = ["run_campaign", "run_trial"]

_LOG = "trials.jsonl"
_META = "campaign.json"


def run_trial(campaign: Campaign, index: int, planner: str, params: Any = None) -> dict[str, Any]:
    """Run trial ``index`` with ``planner`` and return its result row; ``params`` is the
    simulated robot (:class:`gracenav.BallbotParams`, default the palette's), which the
    trial's plant factors scale."""
    from gracenav.scenarios import parse_scenario, run_scenario

    inputs = draw_trial(campaign, index)
    doc = trial_scenario(campaign, inputs)
    from gracenav.errors import PlanningError

    scenario = parse_scenario(doc, source=f"{campaign.name} trial {index}")
    row: dict[str, Any] = {"planner": planner, **inputs}
    try:
        result = run_scenario(scenario, params=params)
    except PlanningError:
        # The library has no verified way from this start to this goal: a failed trial.
        row.update(reached_goal=False, outcome="no_plan")
        return row
    run = result.runs[0].to_dict()
    for key in (
        "reached_goal",
        "outcome",
        "time_s",
        "path_length_m",
        "final_error_m",
        "max_lean_deg",
        "max_jerk_mps3",
        "max_torque_nm",
        "min_clearance_m",
        "verified_recoveries",
        "switches",
        "non_graceful_switches",
        "balancing_s",
    ):
        row[key] = run[key]
    return row


def _read_log(path: Path) -> dict[tuple[str, int], dict[str, Any]]:
    done: dict[tuple[str, int], dict[str, Any]] = {}
    if not path.exists():
        return done
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by a kill: that trial runs again
        done[(row["planner"], row["trial"])] = row
    return done


def run_campaign(
    campaign: Campaign,
    out: str | Path,
    *,
    processes: int | None = None,
    params: Any = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every (planner, trial) not yet in ``out/trials.jsonl`` and return all rows.

    ``params``: the simulated robot of every trial (``--params``); a resumed campaign
    must use the same.

    Each finished trial is appended to ``out/trials.jsonl`` as one JSON line (flushed
    and synced), so an interrupted campaign resumes where it stopped.

    Raises
    ------
    OutputError
        ``out`` holds results of a different campaign file or robot parameters.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = out / _META
    robot = None if params is None else params.to_dict()
    if meta.exists():
        stored = json.loads(meta.read_text())
        if stored.get("digest") != campaign.digest:
            raise OutputError(
                f"--out {out}: holds results of a different campaign file (hash differs); "
                "use another directory"
            )
        if stored.get("params") != robot:
            raise OutputError(
                f"--out {out}: its trials were run with other robot parameters (--params); "
                "use the same file or another directory"
            )
    else:
        tmp = meta.with_suffix(".tmp")
        tmp.write_text(
            json.dumps({"name": campaign.name, "digest": campaign.digest, "params": robot}) + "\n"
        )
        os.replace(tmp, meta)
    log = out / _LOG
    done = _read_log(log)
    jobs = [(p, i) for p in campaign.planners for i in range(campaign.trials) if (p, i) not in done]
    total = len(campaign.planners) * campaign.trials
    count = total - len(jobs)
    processes = processes or (os.cpu_count() or 1)
    with open(log, "a") as fh:
        if fh.tell() > 0 and not log.read_bytes().endswith(b"\n"):
            fh.write("\n")  # end a line cut by a kill, so the next one stands alone

        def record(row: dict[str, Any]) -> None:
            nonlocal count
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
            done[(row["planner"], row["trial"])] = row
            count += 1
            if progress is not None:
                progress(count, total)

        if processes <= 1:
            for p, i in jobs:
                record(run_trial(campaign, i, p, params))
        elif jobs:
            with ProcessPoolExecutor(max_workers=processes) as pool:
                futures = [pool.submit(run_trial, campaign, i, p, params) for p, i in jobs]
                for fut in as_completed(futures):
                    record(fut.result())
    return [done[(p, i)] for p in campaign.planners for i in range(campaign.trials)]
