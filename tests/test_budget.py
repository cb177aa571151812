"""The memory budget: library sizes estimated before instantiating, and a scenario's
halvings chosen, or refused, by the estimated peak memory of its run."""

from __future__ import annotations

import copy
from typing import Any

import pytest
import yaml

from gracenav.cli import main
from gracenav.errors import ConfigError
from gracenav.library import (
    POLICY_BYTES,
    build_library,
    estimate_library_size,
    expected_library_size,
    lattice_points,
)
from gracenav.scenarios import (
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MEMORY_LIMIT_GIB,
    check_scenario,
    estimate_run_memory,
    library_key,
    load_scenario_map,
    parse_scenario,
    prepare_library,
    run_scenario,
    summary_dict,
)
from gracenav.world import load_map, office_map

GIB = 2**30

ROOM: dict[str, Any] = {
    "name": "room with a box",
    "map": {
        "bounds": [[0.0, 0.0], [4.0, 3.0]],
        "resolution": 0.05,
        "obstacles": [{"rectangle": {"min": [1.8, 1.2], "max": [2.2, 1.8]}}],
    },
    "task": {
        "kind": "point_to_point",
        "goal": [3.0, 1.5, 0.0, 0.0],
        "starts": [[1.0, 1.5, 0.0, 0.0]],
    },
    "simulation": {"max_time": 8},
}


def room(**planner: Any) -> dict[str, Any]:
    """ROOM with a ``planner`` section (none when empty)."""
    data = copy.deepcopy(ROOM)
    if planner:
        data["planner"] = planner
    return data


@pytest.fixture(scope="module")
def office14() -> Any:
    return office_map(14.0, 0.05, seed=1)


def test_expected_size_is_the_library_size_when_every_undecided_point_is_checked(
    palette: Any, office14: Any
) -> None:
    est = expected_library_size(palette, office14, 0.5, samples=10**6)
    lib = build_library(palette, office14, max_halvings=0, coverage_samples=50)
    assert est.sampled == est.undecided > 0 and est.std_error == 0.0
    assert est.expected == len(lib)
    assert (est.low, est.high) == estimate_library_size(palette, office14, 0.5)
    assert est.low < len(lib) < est.high
    assert est.points == lattice_points(office14, 0.5) == 29 * 29
    # A sample of the undecided points: an estimate with its standard error.
    few = expected_library_size(palette, office14, 0.5, samples=64, seed=3)
    assert few.sampled == 64 < few.undecided
    assert 0.0 < few.std_error and abs(few.expected - len(lib)) < 4 * few.std_error
    assert few.expected < few.upper() <= few.high
    with pytest.raises(ConfigError, match="samples"):
        expected_library_size(palette, office14, 0.5, samples=1)


def test_the_bound_decides_a_budget_as_the_sample_would(palette: Any, office14: Any) -> None:
    """With a limit, the policies' upper bound replaces the sampled check when it fits:
    the verdict (fits or not) at every limit is the sampled estimate's, and a limit the
    bound fits skips the sample."""
    from gracenav.world import forest_map

    for world in (office14, forest_map(density=0.012, seed=3)):
        for h in (0, 1):
            sampled = estimate_run_memory(world, palette, h)
            spacing = palette.d / 2**h
            high = expected_library_size(palette, world, spacing).high
            assert sampled.policies is not None and sampled.policies <= high
            roomy = estimate_run_memory(world, palette, h, limit=64 * GIB)
            assert roomy.policies == high and roomy.bytes >= sampled.bytes
            limits = [sampled.bytes * f for f in (0.9, 0.999, 1.0, 1.001, 1.1)]
            limits += [roomy.bytes * f for f in (0.999, 1.0, 1.001)]
            for limit in limits:
                got = estimate_run_memory(world, palette, h, limit=limit)
                assert (got.bytes <= limit) == (sampled.bytes <= limit), (h, limit)
            # A cap on the policies below the bound asks for the sample.
            capped = estimate_run_memory(world, palette, h, limit=64 * GIB, policy_cap=high - 1)
            assert capped.policies == sampled.policies
    with pytest.raises(ConfigError, match="samples"):
        expected_library_size(palette, office14, 0.5, samples=1, sample_above=1e9)


def test_build_library_refuses_a_pass_by_its_expected_size(palette: Any, office14: Any) -> None:
    """Between the bounds, build_library's memory check goes by the estimate (exact here:
    every undecided point is checked), not by the lower bound."""
    est = expected_library_size(palette, office14, 0.5)
    n = int(est.expected)
    assert est.std_error == 0.0 and est.low < n < est.high
    with pytest.raises(ConfigError, match=r"about .* policies, needing about .* memory_limit"):
        build_library(
            palette,
            office14,
            max_halvings=0,
            coverage_samples=50,
            memory_limit=(n - 1) * POLICY_BYTES,
        )
    lib = build_library(
        palette, office14, max_halvings=0, coverage_samples=50, memory_limit=n * POLICY_BYTES
    )
    assert len(lib) == n
    # A lattice whose estimate alone would not fit is refused by arithmetic.
    with pytest.raises(ConfigError, match="49 lattice points"):
        build_library(
            palette,
            load_map({"bounds": [[0, 0], [3, 3]]}),
            memory_limit=1000,
            coverage_target=0.99,
        )


def test_automatic_halvings_fit_the_budget(palette: Any) -> None:
    sc = parse_scenario(room(), source="room.yaml")
    assert sc.max_halvings is None and sc.memory_limit == DEFAULT_MEMORY_LIMIT_GIB * GIB
    world = load_scenario_map(sc)
    e0, e1 = (estimate_run_memory(world, palette, h) for h in (0, 1))
    assert e0.bytes < e1.bytes < 1 * GIB
    assert e0.policies is not None and e1.policies is not None and e0.policies < e1.policies
    assert check_scenario(sc, world, palette) == DEFAULT_MAX_HALVINGS == 1
    # A budget between the two: one halving fewer, and the library follows.
    mid = (e0.bytes + e1.bytes) / 2 / GIB
    small = parse_scenario(room(memory_limit_gib=mid), source="room.yaml")
    assert check_scenario(small, world, palette) == 0
    prepared = prepare_library(small, palette)
    assert prepared.max_halvings == 0 and prepared.library.spacing == palette.d
    result = run_scenario(small, palette=palette, prepared=prepared)
    assert summary_dict(result)["library_spacing_m"] == palette.d == 0.5
    # The halvings chosen depend on the budget: so does the prepared library's key.
    assert library_key(small, palette) != library_key(sc, palette)
    given = parse_scenario(room(max_halvings=1), source="room.yaml")
    bigger = parse_scenario(room(max_halvings=1, memory_limit_gib=8), source="room.yaml")
    assert library_key(given, palette) == library_key(bigger, palette)


def test_a_map_over_the_budget_is_refused_naming_the_key(palette: Any) -> None:
    world = load_scenario_map(parse_scenario(room(), source="room.yaml"))
    need = estimate_run_memory(world, palette, 0).bytes
    tiny = parse_scenario(room(memory_limit_gib=(need - 1000) / GIB), source="room.yaml")
    with pytest.raises(ConfigError) as exc:
        check_scenario(tiny, world, palette)
    msg = str(exc.value)
    assert msg.startswith("room.yaml: this 4 m × 3 m map needs about ")
    assert "even without halvings" in msg and "(planner.memory_limit_gib)" in msg
    assert f"raise planner.memory_limit_gib to {-(-10 * need // GIB) / 10:g} if" in msg
    # Below even the rest of a run (interpreter, map, outputs): no policies estimated.
    least = parse_scenario(room(memory_limit_gib=0.1), source="room.yaml")
    with pytest.raises(
        ConfigError, match=r"needs at least .* raise planner.memory_limit_gib to at least \d"
    ):
        check_scenario(least, world, palette)
    # The decoupled baseline builds no library: no budget.
    plain = parse_scenario(room(kind="decoupled", memory_limit_gib=0.01), source="d.yaml")
    assert check_scenario(plain, world, palette) == DEFAULT_MAX_HALVINGS


def test_explicit_halvings_over_the_budget_are_refused(palette: Any) -> None:
    world = load_scenario_map(parse_scenario(room(), source="room.yaml"))
    e0, e1 = (estimate_run_memory(world, palette, h).bytes for h in (0, 1))
    mid = (e0 + e1) / 2 / GIB
    sc = parse_scenario(room(max_halvings=1, memory_limit_gib=mid), source="room.yaml")
    with pytest.raises(ConfigError) as exc:
        check_scenario(sc, world, palette)
    msg = str(exc.value)
    assert msg.startswith("room.yaml: 'planner.max_halvings' 1 on this 4 m × 3 m map would need")
    assert "use planner.max_halvings <= 0" in msg and "raise planner.memory_limit_gib" in msg
    ok = parse_scenario(room(max_halvings=0, memory_limit_gib=mid), source="room.yaml")
    assert check_scenario(ok, world, palette) == 0


def test_a_lattice_too_fine_is_refused_without_estimating_its_policies(palette: Any) -> None:
    world = load_scenario_map(parse_scenario(room(), source="room.yaml"))
    est = estimate_run_memory(world, palette, 12, limit=2 * GIB)  # 4e8 points: not allocated
    assert est.policies is None and est.bytes > 2 * GIB
    assert est.describe().startswith("at least ") and "lattice of" in est.describe()


def test_run_refuses_over_budget_halvings_in_one_line(tmp_path, capsys, palette: Any) -> None:
    world = load_scenario_map(parse_scenario(room(), source="room.yaml"))
    e0, e1 = (estimate_run_memory(world, palette, h).bytes for h in (0, 1))
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(room(max_halvings=1, memory_limit_gib=(e0 + e1) / 2 / GIB)))
    out = tmp_path / "out"
    status = main(["run", str(path), "--out", str(out), "--no-animation"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"gracenav: error: {path}: 'planner.max_halvings' 1 on this 4 m × 3 m")
    assert "planner.memory_limit_gib" in err and not out.exists()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (0, "'planner.memory_limit_gib' must be a number in (0, 1024] GiB, got 0"),
        (-2, "must be a number in (0, 1024] GiB"),
        (5000, "must be a number in (0, 1024] GiB, got 5000"),
        ("2", "'planner.memory_limit_gib'"),
        (True, "'planner.memory_limit_gib'"),
    ],
)
def test_memory_limit_key_is_checked(value: Any, message: str) -> None:
    with pytest.raises(ConfigError, match=r"room\.yaml") as exc:
        parse_scenario(room(memory_limit_gib=value), source="room.yaml")
    assert message in str(exc.value)


def test_plot_library_takes_the_scenarios_budget() -> None:
    from gracenav.cli import build_parser

    args = build_parser().parse_args(["plot", "library", "m.yaml", "--out", "l.png"])
    assert args.memory_limit_gib == DEFAULT_MEMORY_LIMIT_GIB and args.max_halvings is None
