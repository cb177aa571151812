"""The command line: outputs, help, and one-line errors with a non-zero exit."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav.cli import main
from gracenav.palette import load_palette


def test_simulate_balance_writes_csv_and_png(tmp_path, capsys) -> None:
    assert main(["simulate", "balance", "--lean-deg", "5", "--out", str(tmp_path)]) == 0
    data = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    assert header == "t,x,y,xdot,ydot,lean_x,lean_y,tau_x,tau_y"
    assert data[0, 5] == pytest.approx(np.deg2rad(5.0))
    assert np.hypot(data[-1, 1], data[-1, 2]) < 0.02
    assert (tmp_path / "balance.png").stat().st_size > 10_000
    assert "max lean 5.00°" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "balance", "--lean-deg", "abc", "--out", "x"],
        ["simulate", "balance", "--lean-deg", "45", "--out", "x"],
        ["simulate", "balance"],
        ["simulate", "walk", "--out", "x"],
        ["plot", "domain", "no_such_policy", "--out", "x.png"],
        ["palette", "show", "--file", "/nonexistent.npz"],
        # Not a shipped palette's name, nor a file: refused before ROS starts.
        ["palette", "show", "--file", "fast"],
        ["ros", "navigate", "--palette", "fast"],
        # Limits refused before anything is planned: not ascending from 0.5 m/s, a
        # reference speed cap below the top speed.
        ["palette", "build", "--cruise-speeds", "0.4", "--out", "x.npz"],
        ["palette", "build", "--cruise-speed", "0.6", "--cruise-speeds", "0.5", "--out", "x.npz"],
        ["palette", "build", "--cruise-speed", "0", "--out", "x.npz"],
        ["palette", "build", "--cruise-speed", "nan", "--out", "x.npz"],
        ["palette", "build", "--cruise-speed", "1.7", "--out", "x.npz"],
        # Trims that would outlast the longest maneuver (4.5 s), refused before any is
        # sampled: 1e-6 m/s made trims of 7e5 s.
        ["palette", "build", "--cruise-speed", "1e-6", "--out", "x.npz"],
        ["palette", "build", "--d", "1e9", "--out", "x.npz"],
        ["palette", "build", "--cruise-speeds", "1.0", "--max-speed", "0.9", "--out", "x.npz"],
        ["palette", "build", "--reference", "cubic", "--out", "x.npz"],
        # Cruise speeds at or above the robot's top speed (1.615 m/s), refused before
        # the catches' speeds are listed (1e9 m/s used to list them without end).
        ["palette", "build", "--cruise-speeds", "1.7", "--out", "x.npz"],
        ["palette", "build", "--cruise-speeds", "1e9", "--out", "x.npz"],
        ["palette", "build", "--cruise-speeds", "inf", "--out", "x.npz"],
        ["palette", "build", "--shift-max-ball-jerk", "0", "--out", "x.npz"],
        ["palette", "build", "--shift-max-ball-jerk", "abc", "--out", "x.npz"],
        ["frobnicate"],
    ],
)
def test_bad_arguments_give_one_line_and_nonzero_exit(argv, capsys) -> None:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse exits by itself
        status = int(exc.code or 0)
    assert status == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err and "Traceback" not in err


def test_help_explains(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "summary.json" in out and "scenario" in out


@pytest.mark.slow
def test_plot_commands(tmp_path) -> None:
    # The nonics plan in about 2 s where the default palette's references take 25 s.
    out = str(tmp_path / "p.png")
    assert main(["plot", "primitives", "--reference", "nonic", "--out", out]) == 0
    assert main(["plot", "domain", "rest_to_cruise_x_2_0", "--out", str(tmp_path / "d.png")]) == 0
    assert (tmp_path / "p.png").stat().st_size > 10_000
    assert (tmp_path / "d.png").stat().st_size > 10_000


def test_palette_show(capsys) -> None:
    assert main(["palette", "show"]) == 0
    out = capsys.readouterr().out
    assert "rest_to_cruise_x_2_0" in out and "capture[S=6G]" in out
    assert "(40 primitives and their larger-domain variants)" in out
    assert "limits: lean 4.5° planned, 8° verified; torque 60 N m; cruise 0.5 m/s" in out
    assert "design push (planner.design_push, default 8 N s)" in out
    assert "this palette's reach 0.7" in out and "so it changes no library" in out
    assert "controller: friction fed forward at the measured ball rate" in out
    pal = load_palette()
    checked = [p for p in pal.policies if p.still_report is not None]
    passed = sum(p.starts_from_still_band for p in checked)
    assert 0 < passed < len(checked)
    assert f"still band: {passed} of the {len(checked)} policies that start at rest" in out


@pytest.mark.parametrize(
    ("argv", "changed"),
    [
        ([], {}),
        (["--reference", "nonic"], {"reference": "nonic"}),
        (["--max-ball-jerk", "6", "--shift-max-ball-jerk", "none"], {"max_ball_jerk": 6.0}),
        (["--friction-midpoint"], {}),
        (["--cruise-speed", "0.4"], {"cruise_speeds": (0.4,)}),
        (
            ["--cruise-speed", "0.4", "--cruise-speeds", "0.8"],
            {"cruise_speeds": (0.4, 0.8), "max_speed": 1.1 * 0.8},
        ),
    ],
)
def test_palette_build_takes_the_limits_not_given_from_the_default_palette(
    argv, changed, monkeypatch, tmp_path
) -> None:
    """`gracenav palette build` without limit options asks for exactly what
    `PaletteLimits()` states (the shipped default palette's key); each option changes
    only its own limit, and ``--friction-midpoint`` only the controller's friction
    feed-forward. The build itself is replaced: it stops the command."""
    import dataclasses

    import gracenav.palette as palette_module
    from gracenav.errors import ConfigError
    from gracenav.palette import PaletteLimits

    asked = []

    def record(**kwargs):  # type: ignore[no-untyped-def]
        asked.append(kwargs)
        raise ConfigError("stopped before the build")

    monkeypatch.setattr(palette_module, "build_palette_for", record)
    assert main(["palette", "build", *argv, "--out", str(tmp_path / "p.npz")]) == 2
    want = dataclasses.replace(PaletteLimits(), **changed)
    if "--shift-max-ball-jerk" in argv:
        want = dataclasses.replace(want, shift_max_ball_jerk=None)
    (kwargs,) = asked
    assert kwargs["primitive_options"] == want.primitive_options()
    assert kwargs["options"] == want.verification_options()
    assert kwargs["gains"].friction_midpoint == ("--friction-midpoint" in argv)
    assert kwargs["gains"].friction_compensation
