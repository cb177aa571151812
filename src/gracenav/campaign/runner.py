"""Run a campaign's trials on a local process pool or a Dask cluster, resumably."""

from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gracenav.campaign.draw import PairCheck, draw_trial, trial_scenario
from gracenav.campaign.spec import Campaign
from gracenav.errors import ConfigError, OutputError

if TYPE_CHECKING:
    from gracenav.baseline import DecoupledOptions
    from gracenav.palette import Palette

__all__ = ["CLUSTER_IDLE_S", "CLUSTER_TIMEOUT_S", "run_campaign", "run_trial", "trial_result"]

_LOG = "trials.jsonl"
_META = "campaign.json"
_LOCK = ".campaign.lock"
CLUSTER_TIMEOUT_S = 30.0
"""How long ``--cluster`` waits to connect to the Dask scheduler (s)."""
#: Time (s) between two reads of the state of the trials running on a cluster.
CLUSTER_POLL_S = 0.05
CLUSTER_IDLE_S = 300.0
"""How long ``--cluster`` waits with trials left while the scheduler has no worker, or
cannot be reached, before it stops (s); the finished trials stay in the resume log."""
#: Time (s) between two questions to the scheduler about its workers.
CLUSTER_CHECK_S = 5.0

_MEASURES = (
    "reached_goal",
    "outcome",
    "time_s",
    "path_length_m",
    "final_error_m",
    "max_lean_deg",
    "max_jerk_mps3",
    "p95_jerk_mps3",
    "max_torque_nm",
    "min_clearance_m",
    "verified_recoveries",
    "switches",
    "non_graceful_switches",
    "balancing_s",
    "replans",
)

# Per worker process: the palette and the libraries of the maps seen so far, so that
# the trials of one campaign (same map, footprint and library seed) build it once.
_PALETTE: list[Any] = []
_PREPARED: dict[str, Any] = {}
_PREPARED_MAX = 2


def _palette() -> Any:
    from gracenav.palette import load_palette

    if not _PALETTE:
        _PALETTE.append(load_palette())
    return _PALETTE[0]


def _prepared(scenario: Any, palette: Any) -> Any:
    """The scenario's library and graph on ``palette``, built once per worker process."""
    from gracenav.scenarios import library_key, prepare_library

    key = library_key(scenario, palette)
    hit = _PREPARED.get(key)
    if hit is None:
        if len(_PREPARED) >= _PREPARED_MAX:
            _PREPARED.clear()
        hit = prepare_library(scenario, palette)
        _PREPARED[key] = hit
    return hit


def _pair_check(campaign: Campaign, palette: Any) -> PairCheck:
    """Whether gracenav's library (on ``palette``) of the base scenario can start at rest
    at ``start`` and reach a rest goal at ``goal``: the same check for every planner, so
    that all planners get the same pairs."""
    from gracenav.errors import PlanningError
    from gracenav.scenarios import check_task, parse_scenario

    doc = trial_scenario(campaign, {"sim_seed": 0, "noise_std_m": 0.0})
    # Any pair is checked against one library: the whole map's, not a task's region.
    base = dataclasses.replace(
        parse_scenario(doc, source=f"{campaign.name} scenario"), region="map"
    )
    prepared = _prepared(base, palette)

    def accept(start: list[float], goal: list[float]) -> bool:
        sc = dataclasses.replace(base, starts=((*start, 0.0, 0.0),), goals=((*goal, 0.0, 0.0),))
        try:
            check_task(sc, prepared, palette)
        except PlanningError:
            return False
        return True

    return accept


def run_trial(campaign: Campaign, index: int, planner: str, params: Any = None) -> dict[str, Any]:
    """Run trial ``index`` with ``planner`` and return its result row; ``params`` is the
    simulated robot (:class:`gracenav.BallbotParams`, default the palette's), which the
    trial's plant factors scale."""
    return trial_result(campaign, index, planner, params)[0]


def trial_result(
    campaign: Campaign,
    index: int,
    planner: str,
    params: Any = None,
    *,
    decoupled_options: DecoupledOptions | None = None,
    palette: Palette | None = None,
) -> tuple[dict[str, Any], Any]:
    """Run trial ``index`` with ``planner``: its result row (:func:`run_trial`) and the
    :class:`gracenav.scenarios.ScenarioResult` (None when no plan was found), for
    measurements that need the run itself (its episode, its library).
    ``decoupled_options`` (:class:`gracenav.baseline.DecoupledOptions`, default its
    defaults) configures the decoupled baseline; ``palette`` is the palette the trial
    runs on and its pair is drawn with (default: :func:`gracenav.palette.load_palette`'s,
    read once per process)."""
    from gracenav.errors import PlanningError
    from gracenav.execution import EventReason
    from gracenav.scenarios import parse_scenario, run_scenario
    from gracenav.scenarios.decoupled import run_decoupled

    palette = palette if palette is not None else _palette()
    accept = _pair_check(campaign, palette) if campaign.pairs is not None else None
    inputs = draw_trial(campaign, index, accept)
    doc = trial_scenario(campaign, inputs, planner)
    scenario = parse_scenario(doc, source=f"{campaign.name} trial {index}")
    row: dict[str, Any] = {"planner": planner, **inputs}
    try:
        if scenario.planner == "decoupled":
            result = run_decoupled(
                scenario, palette=palette, params=params, options=decoupled_options
            )
        else:
            result = run_scenario(
                scenario, palette=palette, params=params, prepared=_prepared(scenario, palette)
            )
    except PlanningError:
        # No verified way (or no geometric path) from this start to this goal.
        row.update(reached_goal=False, outcome="no_plan")
        return row, None
    run = result.runs[0].to_dict()
    for key in _MEASURES:
        row[key] = run[key]
    ep = result.episodes[0]
    row["fallbacks"] = sum(1 for e in ep.events if e.reason == EventReason.BALANCING)
    return row, result


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


@contextmanager
def _locked(out: Path) -> Iterator[None]:
    """Hold ``out/.campaign.lock``: a second campaign into the same directory is refused."""
    path = out / _LOCK
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputError(
                f"--out {out} is in use by another gracenav campaign (lock {path}); wait "
                "for it to finish or choose another directory"
            ) from None
        yield
    finally:
        os.close(fd)


def _check_dir(out: Path) -> None:
    """``out`` must be absent or a campaign directory: nothing but what
    :func:`run_campaign` and ``gracenav campaign`` write."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a directory; give a directory")
    if not out.exists():
        return
    ours = {_META, _META.replace(".json", ".tmp"), _LOG, _LOCK, "results"}
    others = sorted(
        e.name for e in out.iterdir() if e.name not in ours and not e.name.startswith(".results.")
    )
    if others:
        shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
        raise OutputError(
            f"--out {out} holds files a campaign did not write ({shown}); give a new "
            "directory or the directory of this campaign"
        )


def _check_meta(campaign: Campaign, out: Path, robot: Any) -> None:
    meta = out / _META
    if meta.exists():
        try:
            stored = json.loads(meta.read_text())
        except json.JSONDecodeError:
            stored = {}
        if stored.get("digest") != campaign.digest:
            raise OutputError(
                f"--out {out}: holds results of a different campaign (its inputs or base "
                "scenario differ); use another directory"
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


def run_campaign(
    campaign: Campaign,
    out: str | Path,
    *,
    processes: int | None = None,
    params: Any = None,
    progress: Callable[[int, int], None] | None = None,
    cluster: str | None = None,
) -> list[dict[str, Any]]:
    """Run every (planner, trial) not yet in ``out/trials.jsonl`` and return all rows.

    Parameters
    ----------
    campaign : Campaign
    out : path-like
        Campaign directory: ``campaign.json`` and the resume log ``trials.jsonl``.
    processes : int, optional
        Local worker processes (default: the number of cores; 1 runs in this process).
    params : BallbotParams, optional
        The simulated robot of every trial (``--params``); a resumed campaign must use
        the same.
    progress : callable(done, total), optional
    cluster : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default the
        campaign's ``cluster`` entry, else the local pool. Needs the ``cluster`` extra.
        A trial whose worker dies is run again on another worker (Dask's
        ``allowed-failures``); its row counts that in ``worker_losses``.

    Each finished trial is appended to ``out/trials.jsonl`` as one JSON line (flushed
    and synced) by this process, whatever runs it, so an interrupted campaign resumes
    where it stopped. A trial's row depends only on the campaign and its index, not
    on where it ran.

    Raises
    ------
    OutputError
        ``out`` holds results of a different campaign or robot parameters, or another
        campaign is running into it.
    ConfigError
        The cluster cannot be reached, or its engine is not installed.
    """
    out = Path(out)
    _check_dir(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot create it: {exc.strerror}") from None
    robot = None if params is None else params.to_dict()
    cluster = cluster if cluster is not None else campaign.cluster
    with _locked(out):
        _check_meta(campaign, out, robot)
        log = out / _LOG
        done = _read_log(log)
        jobs = [
            (p, i) for p in campaign.planners for i in range(campaign.trials) if (p, i) not in done
        ]
        total = len(campaign.planners) * campaign.trials
        count = total - len(jobs)
        with open(log, "a") as fh:
            if fh.tell() > 0 and not log.read_bytes().endswith(b"\n"):
                fh.write("\n")  # end a line cut by a kill, so the next one stands alone

            def record(row: dict[str, Any]) -> None:
                nonlocal count
                row.setdefault("worker_losses", 0)
                fh.write(json.dumps(row) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
                done[(row["planner"], row["trial"])] = row
                count += 1
                if progress is not None:
                    progress(count, total)

            if cluster is not None:
                _run_on_cluster(cluster, campaign, jobs, params, record)
            else:
                processes = processes or (os.cpu_count() or 1)
                if processes <= 1:
                    for p, i in jobs:
                        record(run_trial(campaign, i, p, params))
                elif jobs:
                    with ProcessPoolExecutor(max_workers=processes) as pool:
                        futures = [pool.submit(run_trial, campaign, i, p, params) for p, i in jobs]
                        for fut in as_completed(futures):
                            record(fut.result())
    return [done[(p, i)] for p in campaign.planners for i in range(campaign.trials)]


def _run_on_cluster(
    address: str,
    campaign: Campaign,
    jobs: list[tuple[str, int]],
    params: Any,
    record: Callable[[dict[str, Any]], None],
) -> None:
    """Submit every job to the Dask scheduler at ``address`` and record rows as they
    finish. Dask runs a task again when its worker dies (up to its
    ``distributed.scheduler.allowed-failures``, default 3); the scheduler's count of
    such losses goes into the row as ``worker_losses``."""
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError(
            "--cluster needs Dask distributed: pip install 'gracenav[cluster]'"
        ) from None
    try:
        client = Client(address, timeout=CLUSTER_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(
            f"--cluster {address}: cannot connect to a Dask scheduler within "
            f"{CLUSTER_TIMEOUT_S:g} s ({exc}); start one (dask scheduler) or check the address"
        ) from None
    with client:
        keys = {}
        futures = []
        for p, i in jobs:
            key = f"gracenav-trial-{campaign.digest[:16]}-{p}-{i}"
            fut = client.submit(run_trial, campaign, i, p, params, key=key, pure=False)
            keys[fut.key] = (p, i)
            futures.append(fut)
        # Each future's own state is read, CLUSTER_POLL_S apart: distributed.as_completed
        # and distributed.wait wait on the default client's event loop, which is another
        # client's when the process has two (a campaign run beside a client of the same
        # cluster); as_completed then missed a future lost with its worker and waited
        # forever, and wait failed on an event bound to the other loop.
        # A trial may run for minutes, so waiting is bounded by the workers, not by the
        # trials: the loop stops once no worker has been connected (or the scheduler not
        # reachable) for CLUSTER_IDLE_S.
        pending = futures
        worker_seen = checked = time.monotonic()
        while pending:
            finished = [f for f in pending if f.done()]
            if not finished:
                now = time.monotonic()
                if now - checked >= CLUSTER_CHECK_S:
                    checked = now
                    if _has_workers(client):
                        worker_seen = now
                    elif now - worker_seen >= CLUSTER_IDLE_S:
                        raise ConfigError(
                            f"--cluster {address}: no Dask worker for {CLUSTER_IDLE_S:g} s with "
                            f"{len(pending)} trials left (finished ones are kept); start workers "
                            f"(dask worker {address}) and run the command again to resume"
                        )
                time.sleep(CLUSTER_POLL_S)
                continue
            pending = [f for f in pending if f not in finished]
            for fut in finished:
                if fut.cancelled():
                    p, i = keys[fut.key]
                    raise ConfigError(
                        f"--cluster {address}: the scheduler dropped trial {i} of {p} (it "
                        "restarted or the connection was lost); finished trials are kept: "
                        "run the command again to resume"
                    )
                row = fut.result()
                losses = client.run_on_scheduler(_task_losses, key=fut.key)
                row["worker_losses"] = int(losses)
                fut.release()
                record(row)


def _has_workers(client: Any) -> bool:
    """Whether the scheduler of ``client`` has a worker now (False when it cannot be
    asked)."""
    if client.status != "running":
        return False
    try:
        return bool(client.scheduler_info(n_workers=1).get("workers"))
    except (OSError, TimeoutError):
        return False


def _task_losses(dask_scheduler: Any, key: str) -> int:
    """On the scheduler: how many workers died while running task ``key``."""
    ts = dask_scheduler.tasks.get(key)
    return int(ts.suspicious) if ts is not None else 0
