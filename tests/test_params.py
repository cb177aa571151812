"""BallbotParams: defaults, validation and files."""

from __future__ import annotations

import dataclasses
import json

import pytest

from gracenav import BallbotParams, ConfigError


def test_defaults_are_the_cmu_ballbot() -> None:
    p = BallbotParams()
    assert p.ball_radius == 0.1058
    assert p.body_mass == 51.66
    assert p.body_inertia_x == 12.59
    assert p.coulomb_friction == 3.82
    # Derived constants of IJRR 2014 eqs. 1-5 (DESIGN.md 2.2).
    assert p.alpha() == pytest.approx(0.6230, abs=5e-5)
    assert p.beta() == pytest.approx(3.7713, abs=5e-5)
    assert p.gamma(p.body_inertia_x) == pytest.approx(37.185, abs=5e-4)


def test_friction_torque_to_cruise_half_a_metre_per_second() -> None:
    p = BallbotParams()
    tau = p.viscous_friction * 0.5 / p.ball_radius + p.coulomb_friction
    assert tau == pytest.approx(21.21, abs=0.01)
    assert p.torque_limit > tau


def test_without_friction() -> None:
    p = BallbotParams().without_friction()
    assert p.coulomb_friction == 0.0 and p.viscous_friction == 0.0


@pytest.mark.parametrize("name", ["ball_mass", "ball_radius", "body_inertia_y", "torque_limit"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_non_physical_values_name_the_field(name: str, value: float) -> None:
    with pytest.raises(ConfigError, match=name):
        BallbotParams(**{name: value})


def test_negative_friction_rejected_but_zero_allowed() -> None:
    BallbotParams(coulomb_friction=0.0)
    with pytest.raises(ConfigError, match="coulomb_friction"):
        BallbotParams(coulomb_friction=-0.1)


def test_non_numeric_and_non_finite_rejected() -> None:
    with pytest.raises(ConfigError) as info:
        BallbotParams(body_mass="heavy")  # type: ignore[arg-type]
    assert str(info.value) == "BallbotParams: 'body_mass' must be a finite number (kg), got 'heavy'"
    with pytest.raises(ConfigError) as info:
        BallbotParams(body_mass=float("nan"))
    assert str(info.value) == "BallbotParams: 'body_mass' must be a finite number (kg), got nan"
    with pytest.raises(ConfigError) as info:
        BallbotParams(coulomb_friction=-0.5)
    assert (
        str(info.value) == "BallbotParams: 'coulomb_friction' must be a number >= 0 N m, got -0.5"
    )


def test_numpy_numbers_are_accepted_and_stored_as_floats() -> None:
    import numpy as np

    p = BallbotParams(body_mass=np.float32(60.0), gravity=np.int64(10))  # type: ignore[arg-type]
    assert type(p.body_mass) is float and p.body_mass == 60.0 and p.gravity == 10.0
    with pytest.raises(ConfigError) as info:
        BallbotParams(body_mass=np.float64(-1.0))
    assert str(info.value) == "BallbotParams: 'body_mass' must be a positive number (kg), got -1.0"


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_round_trip(tmp_path, suffix: str) -> None:
    p = dataclasses.replace(BallbotParams(), torque_limit=80.0)
    path = tmp_path / f"robot{suffix}"
    p.save(path)
    assert BallbotParams.load(path) == p


def test_unknown_and_missing_keys(tmp_path) -> None:
    data = BallbotParams().to_dict()
    data["wheel_count"] = 3
    path = tmp_path / "p.json"
    path.write_text(json.dumps(data))
    with pytest.raises(
        ConfigError, match=r"p\.json: unknown key\(s\) 'wheel_count'; allowed: ball_"
    ):
        BallbotParams.load(path)
    data.pop("wheel_count")
    data.pop("body_mass")
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"missing parameter\(s\) body_mass"):
        BallbotParams.load(path)


def test_bad_value_in_file_names_file_and_field(tmp_path) -> None:
    data = BallbotParams().to_dict()
    data["ball_radius"] = -0.1
    path = tmp_path / "p.yaml"
    import yaml

    path.write_text(yaml.safe_dump(data))
    with pytest.raises(
        ConfigError, match=r"p\.yaml: 'ball_radius' must be a positive number \(m\), got -0\.1$"
    ):
        BallbotParams.load(path)


def test_unreadable_and_malformed_files(tmp_path) -> None:
    with pytest.raises(ConfigError, match="cannot read parameter file"):
        BallbotParams.load(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("ball_radius: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid"):
        BallbotParams.load(bad)
    lst = tmp_path / "list.yaml"
    lst.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="expected a mapping of parameter keys"):
        BallbotParams.load(lst)
