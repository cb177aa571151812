"""Campaigns: deterministic draws, resumption, Wilson intervals, the command line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml

from gracenav.campaign import (
    draw_trial,
    load_campaign,
    run_campaign,
    summarise,
    wilson_interval,
)
from gracenav.cli import main
from gracenav.errors import ConfigError, OutputError

ROOT = Path(__file__).resolve().parent.parent
BASE = ROOT / "examples" / "campaigns" / "room_5m_point_to_point.yaml"


def write_campaign(tmp_path: Path, **over: object) -> Path:
    doc: dict[str, object] = {
        "name": "tiny",
        "scenario": str(BASE),
        "trials": 3,
        "seed": 7,
        "draws": {
            "push": {"impulse": [2.0, 14.0], "time": [1.0, 6.0]},
            "position_noise_std": [0.0, 0.002],
            "plant_params": {"body_mass": [0.9, 1.1]},
        },
    }
    doc.update(over)
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_wilson_interval_matches_the_closed_form() -> None:
    # 8 of 10: the textbook value (0.4902, 0.9433).
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=5e-5) and hi == pytest.approx(0.9433, abs=5e-5)
    # All successes: upper bound 1, lower bound n / (n + z²).
    lo, hi = wilson_interval(20, 20)
    assert hi == 1.0 and lo == pytest.approx(20 / (20 + 1.959963984540054**2), rel=1e-12)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_draws_depend_only_on_seed_and_trial(tmp_path) -> None:
    spec = load_campaign(write_campaign(tmp_path))
    a = [draw_trial(spec, i) for i in range(3)]
    assert [draw_trial(spec, i) for i in (2, 0, 1)] == [a[2], a[0], a[1]]
    other = load_campaign(write_campaign(tmp_path, seed=8))
    assert draw_trial(other, 0) != a[0]
    for d in a:
        assert 2.0 <= d["push_impulse_ns"] <= 14.0 and 1.0 <= d["push_time_s"] <= 6.0
        assert 0.9 <= d["plant_params"]["body_mass"] <= 1.1
        assert 0.0 <= d["push_angle_rad"] < 2 * math.pi


def test_a_campaign_reproduces_and_resumes_exactly(tmp_path) -> None:
    spec = load_campaign(write_campaign(tmp_path))
    full = run_campaign(spec, tmp_path / "a", processes=1)
    assert [r["trial"] for r in full] == [0, 1, 2]
    # Interrupted after trial 0 (and half of a line of trial 1): the resumed campaign
    # runs trials 1 and 2 only, and the records equal the uninterrupted run's.
    lines = (tmp_path / "a" / "trials.jsonl").read_text().splitlines()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "trials.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    calls: list[tuple[int, int]] = []
    resumed = run_campaign(
        spec, tmp_path / "b", processes=1, progress=lambda d, t: calls.append((d, t))
    )
    assert calls[0] == (1, 3) and calls[-1] == (3, 3)
    assert resumed == full
    # The cut line was dropped, so the file reads back whole: a third run does nothing.
    again: list[tuple[int, int]] = []
    assert (
        run_campaign(spec, tmp_path / "b", processes=1, progress=lambda d, t: again.append((d, t)))
        == full
    )
    assert again == [(3, 3)]
    assert (tmp_path / "a" / "results.csv").read_text() == (
        tmp_path / "b" / "results.csv"
    ).read_text()
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary == summarise(spec, full)
    k = sum(r["reached_goal"] for r in full)
    assert summary["overall"]["goal_reached"] == k
    assert summary["overall"]["wilson95"] == pytest.approx(list(wilson_interval(k, 3)))
    assert sum(b["trials"] for b in summary["by_impulse"]) == 3


def test_another_campaign_in_the_same_directory_is_refused(tmp_path) -> None:
    spec = load_campaign(write_campaign(tmp_path, trials=1))
    run_campaign(spec, tmp_path / "a", processes=1)
    other = load_campaign(write_campaign(tmp_path, trials=1, seed=99))
    with pytest.raises(OutputError, match="holds trials of another campaign"):
        run_campaign(other, tmp_path / "a", processes=1)


@pytest.mark.parametrize(
    ("over", "message"),
    [
        ({"trials": 0}, "'trials' must be an integer in [1, 100000], got 0"),
        ({"draws": {"push": {"impulse": [5.0, 1.0], "time": [0, 1]}}}, "'draws.push.impulse'"),
        (
            {"draws": {"plant_params": {"gravity": [1, 1]}}},
            "unknown key(s) 'draws.plant_params.gravity'",
        ),
        ({"colour": 1}, "unknown key(s) 'colour'"),
        ({"scenario": "missing.yaml"}, "'scenario': file"),
    ],
)
def test_bad_campaigns_get_one_line_errors(tmp_path, over, message) -> None:
    with pytest.raises(ConfigError) as err:
        load_campaign(write_campaign(tmp_path, **over))
    assert message in str(err.value) and "\n" not in str(err.value)


def test_command_line(tmp_path, capsys) -> None:
    path = write_campaign(tmp_path, trials=2)
    assert main(["campaign", str(path), "--out", str(tmp_path / "o"), "--processes", "2"]) == 0
    out = capsys.readouterr().out
    assert "of 2 trials reached the goal" in out
    rows = (tmp_path / "o" / "results.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("trial,push_impulse_ns")
    # Two processes give the same records as one.
    one = run_campaign(load_campaign(path), tmp_path / "p", processes=1)
    lines = (tmp_path / "o" / "trials.jsonl").read_text().splitlines()[1:]
    assert sorted((json.loads(x) for x in lines), key=lambda r: r["trial"]) == one
    status = main(["campaign", str(path), "--out", str(tmp_path / "q"), "--processes", "0"])
    err = capsys.readouterr().err
    assert status == 2 and err.startswith("gracenav: error:") and err.count("\n") == 1


def test_params_apply_to_every_trial_and_a_resume_needs_the_same(tmp_path, capsys) -> None:
    path = write_campaign(tmp_path, trials=1)
    heavy = tmp_path / "p.yaml"
    heavy.write_text("body_mass: 60.0\n")
    out = tmp_path / "o"
    assert main(["campaign", str(path), "--out", str(out), "--params", str(heavy)]) == 0
    head = json.loads((out / "trials.jsonl").read_text().splitlines()[0])
    assert head["params"]["body_mass"] == 60.0
    capsys.readouterr()
    status = main(["campaign", str(path), "--out", str(out), "--processes", "1"])
    err = capsys.readouterr().err
    assert status == 2 and "other robot parameters" in err and err.count("\n") == 1
