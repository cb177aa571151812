"""Campaigns: schema, per-trial draws, Wilson intervals, reproducibility and resume."""

from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path

import pytest

from gracenav.campaign import load_campaign, parse_campaign, run_campaign, wilson_interval
from gracenav.campaign.draw import draw_trial
from gracenav.errors import ConfigError, OutputError

TINY = """\
name: tiny
seed: 3
trials: 2
scenario:
  name: tiny
  map:
    bounds: [[0.0, 0.0], [3.0, 3.0]]
  robot: {footprint_radius: 0.2}
  planner: {cost: time, max_halvings: 0}
  task:
    kind: point_to_point
    goal: [2.0, 2.0, 0.0, 0.0]
    starts: [[1.0, 1.0, 0.0, 0.0]]
  simulation: {max_time: 20}
push: {impulse: [0.0, 6.0], time: [0.5, 2.0]}
noise: [0.0, 0.002]
plant_params: {body_mass: [0.8, 1.2], ball_radius: [0.98, 1.02]}
"""


def _tiny(tmp_path: Path, text: str = TINY) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(text)
    return path


def test_wilson_closed_form() -> None:
    # 8 of 10 at z = 1.96: centre (0.8 + 0.192) / 1.384, half-width from the closed form.
    z = 1.959963984540054
    n, p = 10, 0.8
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(c - h, rel=0, abs=1e-12)
    assert hi == pytest.approx(c + h, rel=0, abs=1e-12)
    assert lo == pytest.approx(0.4902, abs=1e-4)
    assert hi == pytest.approx(0.9433, abs=1e-4)
    assert wilson_interval(0, 5)[0] == 0.0
    assert wilson_interval(5, 5)[1] == 1.0


def test_draws_depend_only_on_seed_and_index(tmp_path: Path) -> None:
    c = load_campaign(_tiny(tmp_path))
    a = draw_trial(c, 1)
    assert draw_trial(c, 1) == a
    assert draw_trial(c, 0) != a
    assert 0.0 <= a["impulse_ns"] <= 6.0
    assert 0.5 <= a["push_time_s"] <= 2.0
    assert 0.8 <= a["factor_body_mass"] <= 1.2
    assert a["noise_std_m"] in (0.0, 0.002)


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"trials": 0}, "'trials'"),
        ({"colour": 1}, "unknown key(s) 'colour'"),
        ({"push": {"impulse": [5, 1], "time": [0, 1]}}, "'push.impulse' low 5 exceeds high 1"),
        ({"plant_params": {"gravity": [1, 1]}}, "'plant_params.gravity'"),
        ({"planners": ["rrt"]}, "'planners'"),
    ],
)
def test_schema_errors(patch: dict, message: str) -> None:
    import yaml

    data = yaml.safe_load(TINY) | patch
    with pytest.raises(ConfigError) as err:
        parse_campaign(data, source="c.yaml")
    text = str(err.value)
    assert text.startswith("c.yaml: ")
    assert message in text
    assert "\n" not in text


def test_resume_equals_uninterrupted_and_refuses_other_file(tmp_path: Path) -> None:
    c = load_campaign(_tiny(tmp_path))
    full = run_campaign(c, tmp_path / "a", processes=1)
    assert [r["trial"] for r in full] == [0, 1]
    # An interrupted run: only the first line and half of the second survive.
    lines = (tmp_path / "a" / "trials.jsonl").read_text().splitlines()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "campaign.json").write_text((tmp_path / "a" / "campaign.json").read_text())
    (tmp_path / "b" / "trials.jsonl").write_text(lines[0] + "\n" + lines[1][:20])
    seen = []
    resumed = run_campaign(c, tmp_path / "b", processes=1, progress=lambda d, n: seen.append(d))
    assert seen == [2]  # only the missing trial ran
    assert json.dumps(resumed, sort_keys=True) == json.dumps(full, sort_keys=True)
    again = run_campaign(c, tmp_path / "b", processes=1, progress=lambda d, n: seen.append(d))
    assert seen == [2]  # nothing left to run: the appended line reads back
    assert json.dumps(again, sort_keys=True) == json.dumps(full, sort_keys=True)
    other = load_campaign(_tiny(tmp_path, TINY.replace("seed: 3", "seed: 4")))
    with pytest.raises(OutputError, match="different campaign"):
        run_campaign(other, tmp_path / "a", processes=1)


def test_two_processes_equal_one_and_outputs(tmp_path: Path) -> None:
    pa = pytest.importorskip("pyarrow.parquet")
    from gracenav.campaign.results import write_results

    c = load_campaign(_tiny(tmp_path))
    one = run_campaign(c, tmp_path / "one", processes=1)
    two = run_campaign(c, tmp_path / "two", processes=2)
    assert json.dumps(two, sort_keys=True) == json.dumps(one, sort_keys=True)
    write_results(two, tmp_path / "two")
    table = pa.read_table(tmp_path / "two" / "results.parquet").to_pylist()
    assert [r["max_lean_deg"] for r in table] == [r["max_lean_deg"] for r in one]
    summary = json.loads((tmp_path / "two" / "summary.json").read_text())
    g = summary["planners"]["gracenav"]
    k = sum(r["reached_goal"] for r in one)
    assert g["successes"] == k
    assert g["ci95"] == pytest.approx(list(wilson_interval(k, 2)), abs=1e-12)
    table_md = (tmp_path / "two" / "table.md").read_text()
    assert table_md.startswith("| planner |")
    assert "| push impulse (N s) | gracenav |" in table_md
    bins = g["impulse_bins"]
    cell = f"{bins[0]['successes']}/{bins[0]['n']} ["
    assert cell in table_md.split("| push impulse")[1] or bins[0]["n"] == 0
    for name in ("success_vs_impulse.png", "time_to_goal.png", "lean.png"):
        assert (tmp_path / "two" / name).read_bytes()[:4] == b"\x89PNG"


def test_random_pairs_have_clearance_and_distance(tmp_path: Path) -> None:
    import yaml

    from gracenav.world import load_map

    data = yaml.safe_load(TINY) | {"pairs": {"clearance": 0.4, "min_distance": 1.0}}
    c = parse_campaign(data, source="c.yaml")
    world = load_map(c.scenario["map"])
    for i in range(20):
        d = draw_trial(c, i)
        a, b = (d["start_x"], d["start_y"]), (d["goal_x"], d["goal_y"])
        assert math.dist(a, b) >= 1.0
        assert world.clearance([a, b]).min() >= 0.4 - 1e-9
    bad = yaml.safe_load(TINY) | {"pairs": {"clearance": 0.4, "min_distance": 50.0}}
    with pytest.raises(ConfigError, match=re.escape("'pairs.min_distance' 50 m apart in 1000")):
        draw_trial(parse_campaign(bad, source="c.yaml"), 0)


def test_cli_refuses_missing_scenario_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from gracenav.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text("trials: 2\nscenario: nope.yaml\n")
    code = main(["campaign", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code != 0
    assert err.endswith(f"{path}: 'scenario': file {tmp_path / 'nope.yaml'} not found")
    assert "\n" not in err
    assert not (tmp_path / "out").exists()


def test_params_reach_every_trial_and_a_resume_needs_the_same(tmp_path, capsys) -> None:
    """--params is the simulated robot of every trial; resuming with other parameters is
    refused on one line."""
    from gracenav.cli import main

    camp = _tiny(tmp_path)
    heavy = tmp_path / "p.yaml"
    heavy.write_text("body_mass: 60.0\n")
    out = tmp_path / "o"
    status = main(["campaign", str(camp), "--out", str(out), "--params", str(heavy)])
    assert status == 0
    assert json.loads((out / "campaign.json").read_text())["params"]["body_mass"] == 60.0
    capsys.readouterr()
    status = main(["campaign", str(camp), "--out", str(out), "--processes", "1"])
    err = capsys.readouterr().err
    assert status == 2 and "other robot parameters" in err and err.count("\n") == 1
    status = main(["campaign", str(camp), "--out", str(tmp_path / "q"), "--processes", "0"])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("gracenav: error: --processes") and err.count("\n") == 1


def test_adding_a_planner_runs_only_its_trials(tmp_path: Path) -> None:
    """The resume check ignores 'planners': a planner added to a finished campaign runs
    its own trials only, on the same drawn inputs."""
    c = load_campaign(_tiny(tmp_path))
    first = run_campaign(c, tmp_path / "a", processes=1)
    more = load_campaign(
        _tiny(
            tmp_path,
            TINY.replace("trials: 2\n", "trials: 2\nplanners: [gracenav, gracenav_paper]\n"),
        )
    )
    assert more.digest == c.digest
    seen: list[int] = []
    rows = run_campaign(more, tmp_path / "a", processes=1, progress=lambda d, n: seen.append(d))
    assert seen == [3, 4]  # two new trials of four
    assert rows[:2] == first
    paper = rows[2:]
    assert [r["planner"] for r in paper] == ["gracenav_paper"] * 2
    for a, b in zip(first, paper, strict=True):  # same drawn inputs
        assert a["impulse_ns"] == b["impulse_ns"] and a["sim_seed"] == b["sim_seed"]
        # Without the fallback, a trial that enters balancing mode stays there.
        assert b["fallbacks"] == 0 or b["outcome"] != "goal_reached"


def test_pairs_are_possible_tasks_and_counted(tmp_path: Path) -> None:
    """Random pairs are drawn again until the library can start at one and reach the
    other; the count of draws is recorded and the trials then run without 'no_plan'."""
    import yaml

    data = yaml.safe_load(TINY)
    data.pop("push")
    data["pairs"] = {"clearance": 0.3, "min_distance": 1.0}
    path = tmp_path / "pairs.yaml"
    path.write_text(yaml.safe_dump(data))
    c = load_campaign(path)
    rows = run_campaign(c, tmp_path / "p", processes=1)
    assert all(r["outcome"] != "no_plan" for r in rows)
    assert all(1 <= r["pair_draws"] <= 1000 for r in rows)
    assert all(
        math.dist((r["start_x"], r["start_y"]), (r["goal_x"], r["goal_y"])) >= 1.0 for r in rows
    )


def test_out_holding_other_files_or_in_use_is_refused(tmp_path: Path) -> None:
    from gracenav.campaign.runner import _locked

    c = load_campaign(_tiny(tmp_path))
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="holds files a campaign did not write"):
        run_campaign(c, tmp_path / "x", processes=1)
    (tmp_path / "y").mkdir()
    with _locked(tmp_path / "y"), pytest.raises(OutputError, match="in use by another"):
        run_campaign(c, tmp_path / "y", processes=1)


def test_cli_publishes_results_as_a_unit(tmp_path: Path) -> None:
    from gracenav.cli import main

    out = tmp_path / "o"
    assert main(["campaign", str(_tiny(tmp_path)), "--out", str(out), "--processes", "1"]) == 0
    names = sorted(p.name for p in (out / "results").iterdir())
    assert "results.csv" in names and "summary.json" in names and "table.md" in names
    assert not list(out.glob(".results.*"))  # no staging left
    # A second run (nothing left to run) replaces the results as a whole.
    stale = out / "results" / "results.csv"
    before = stale.stat().st_ino
    assert main(["campaign", str(_tiny(tmp_path)), "--out", str(out), "--processes", "1"]) == 0
    assert (out / "results" / "results.csv").stat().st_ino != before


@pytest.mark.slow
def test_unreachable_cluster_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("distributed")
    import gracenav.campaign.runner as runner
    from gracenav.cli import main

    monkeypatch.setattr(runner, "CLUSTER_TIMEOUT_S", 2.0)
    code = main(
        [
            "campaign",
            str(_tiny(tmp_path)),
            "--out",
            str(tmp_path / "o"),
            "--cluster",
            "tcp://127.0.0.1:1",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "--cluster tcp://127.0.0.1:1: cannot connect to a Dask scheduler" in err
    assert "\n" not in err


def test_a_cluster_without_workers_stops_waiting(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A scheduler that never gets a worker does not keep the campaign waiting: after
    CLUSTER_IDLE_S without one it stops with a one-line reason, the resume log in place."""
    distributed = pytest.importorskip("distributed")
    import gracenav.campaign.runner as runner

    monkeypatch.setattr(runner, "CLUSTER_IDLE_S", 1.0)
    monkeypatch.setattr(runner, "CLUSTER_CHECK_S", 0.1)
    c = load_campaign(_tiny(tmp_path, TINY))
    # In one process (inproc://), its HTTP server on loopback.
    with distributed.LocalCluster(
        n_workers=0, processes=False, dashboard_address="127.0.0.1:0"
    ) as cluster:
        t0 = time.monotonic()
        with pytest.raises(ConfigError, match=r"no Dask worker for 1 s with 2 trials left") as err:
            run_campaign(c, tmp_path / "out", cluster=cluster.scheduler_address)
        assert time.monotonic() - t0 < 60.0  # a hang guard, not a timing target
    assert "\n" not in str(err.value)
    assert (tmp_path / "out" / "trials.jsonl").read_text() == ""


@pytest.mark.slow
def test_dask_cluster_equals_local_and_survives_a_dead_worker(tmp_path: Path) -> None:
    """A real local Dask cluster of two worker processes runs the campaign; one worker
    is killed while it runs a trial. No trial is lost, the lost run is counted, and every
    row equals the local run's."""
    distributed = pytest.importorskip("distributed")
    import os
    import signal

    text = TINY.replace("trials: 2", "trials: 6")
    c = load_campaign(_tiny(tmp_path, text))
    local = run_campaign(c, tmp_path / "local", processes=1)
    with (
        # Scheduler, workers and the scheduler's HTTP server on loopback only
        # (dashboard_address=None would still serve its health routes on 0.0.0.0:8787).
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        pids = client.run(os.getpid)
        killed: list[str] = []

        def kill_a_busy_worker(done: int, total: int) -> None:
            if killed:
                return
            for addr, keys in client.processing().items():
                if keys:
                    os.kill(pids[addr], signal.SIGKILL)
                    killed.append(addr)
                    return

        remote = run_campaign(
            c, tmp_path / "remote", cluster=cluster.scheduler_address, progress=kill_a_busy_worker
        )
    assert killed, "no worker was busy when the first trial finished"
    assert sum(r["worker_losses"] for r in remote) >= 1
    strip = [{k: v for k, v in r.items() if k != "worker_losses"} for r in remote]
    assert json.dumps(strip, sort_keys=True) == json.dumps(
        [{k: v for k, v in r.items() if k != "worker_losses"} for r in local], sort_keys=True
    )
