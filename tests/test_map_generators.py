"""Seeded map generators: forests, warehouses and offices with narrow doors, and the
traversability check that keeps generated tasks possible."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav.baseline import grid_path
from gracenav.errors import PlanningError
from gracenav.world import (
    footprint_connected,
    forest_map,
    load_map,
    office_map,
    save_ros_map,
    warehouse_map,
)

FOOT = 0.2


def test_generators_are_seeded() -> None:
    for make in (forest_map, lambda seed: warehouse_map(20.0, 20.0, seed=seed)):
        a, b, c = make(seed=3), make(seed=3), make(seed=4)
        np.testing.assert_array_equal(a.occupied, b.occupied)
        assert not np.array_equal(a.occupied, c.occupied)


@pytest.mark.parametrize("seed", range(12))
def test_forest_traversability_agrees_with_an_independent_a_star(seed: int) -> None:
    """footprint_connected (connected regions of the footprint-inflated grid) says yes
    exactly when the baseline's A* on the inflated grid finds a path."""
    world = forest_map(seed=seed, density=0.08)
    start, goal = (1.0, 2.25), (15.0, 2.25)
    try:
        grid_path(world, start, goal, FOOT)
        found = True
    except PlanningError:
        found = False
    assert footprint_connected(world, start, goal, FOOT) == found


def test_forest_posts_and_clear_ends() -> None:
    world = forest_map(width=4.5, length=16.0, post=0.15, density=0.06, seed=1)
    xy = world.cell_centers()
    ends = (xy[..., 0] < 2.45) | (xy[..., 0] > 13.55)
    field = (xy[..., 1] > 0.05) & (xy[..., 1] < 4.45)
    assert not np.any(world.occupied & ends & field)  # start and goal areas are clear
    inner = world.occupied & ~ends & field
    assert 0.03 < inner.sum() / (~ends & field).sum() < 0.09  # about the density
    # Walls close the field on both sides.
    assert np.all(world.occupied[0, :]) and np.all(world.occupied[-1, :])


def test_warehouse_shelves_have_unknown_insides_and_aisles_in_range() -> None:
    world = warehouse_map(30.0, 50.0, resolution=0.03, seed=2)
    (_, y0), (x1, y1) = world.bounds
    assert (x1, round(y1, 6)) == (30.0, 50.01)  # 50 m rounded up to whole 3 cm cells
    assert world.unknown is not None and world.unknown.any()
    assert np.all(world.occupied[world.unknown])  # unknown counts as an obstacle
    # An unknown cell is never free to the planner either.
    unk = world.cell_centers()[world.unknown][:50]
    assert not np.any(world.is_free(unk))
    # Along the row y = 12 m (shelves, no cross aisle): free runs between shelves are
    # the aisles, 1.0-2.5 m wide (cells at shelf edges round by one cell).
    row = world.occupied[round((12.0 - y0) / world.resolution)]
    change = np.flatnonzero(np.diff(row.astype(int)))  # last cell before each change
    starts, ends = change[row[change + 1] == 0] + 1, change[row[change + 1] == 1] + 1
    runs = (ends - starts[: ends.size]) * world.resolution  # free runs, cells to m
    inner = runs[1:]  # not the strip along the west wall
    assert inner.size >= 10
    assert np.all(inner >= 1.0 - 2 * world.resolution) and np.all(inner <= 2.5 + 1e-9)
    assert footprint_connected(world, (2.0, 1.5), (28.0, 49.1), FOOT)


def test_office_doors_can_be_narrow() -> None:
    wide = office_map(20.0, resolution=0.05, seed=0)
    narrow = office_map(20.0, resolution=0.05, seed=0, door=0.8)
    assert narrow.occupied.sum() > wide.occupied.sum()  # 0.2 m more wall per door
    # Every room is reachable through its 0.8 m door by a 0.2 m footprint.
    assert footprint_connected(narrow, (1.2, 1.2), (18.0, 18.0), FOOT)


def test_generated_maps_round_trip_as_ros_maps(tmp_path) -> None:  # type: ignore[no-untyped-def]
    world = warehouse_map(12.0, 14.0, resolution=0.05, seed=5)
    save_ros_map(world, tmp_path / "w.yaml", image_format="png")
    back = load_map(tmp_path / "w.yaml")
    np.testing.assert_array_equal(back.occupied, world.occupied)
    np.testing.assert_array_equal(back.unknown, world.unknown)


def test_example_generated_maps_are_current(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """examples/maps/{forest,warehouse,office}_ros.* are what the generator writes."""
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "examples" / "maps" / "make_generated_maps.py"
    runpy.run_path(str(script), run_name="gen")["main"](["x", str(tmp_path)])
    for stem in ("forest_ros", "warehouse_ros", "office_ros"):
        shipped = load_map(script.parent / f"{stem}.yaml")
        fresh = load_map(tmp_path / f"{stem}.yaml")
        np.testing.assert_array_equal(shipped.occupied, fresh.occupied)
        np.testing.assert_array_equal(shipped.unknown, fresh.unknown)
