"""The task's region of a big map: windows of a map, the region around the footprint's
shortest paths, libraries built there (the same policies as the whole map's away from
the region's edge) and the fallback to the whole map."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest
from scipy import ndimage

from gracenav.errors import ConfigError, MapError, PlanningError
from gracenav.library import build_library
from gracenav.library.instantiation import _palette_tables
from gracenav.palette import Palette
from gracenav.scenarios import library_key, parse_scenario, prepare_library, run_scenario
from gracenav.scenarios.outputs import summary_dict
from gracenav.scenarios.region import (
    AUTO_REGION_AREA,
    resolve_region,
    task_region,
    task_waypoints,
)
from gracenav.scenarios.run import _checked, _execution_options
from gracenav.world import WorldMap, footprint_connected, office_map
from gracenav.world.grid_search import astar_cells

FOOT = 0.2


@pytest.fixture(scope="module")
def office() -> WorldMap:
    """A 40 m office at 5 cm (1600 m²: a task region under ``auto``)."""
    return office_map(40.0, resolution=0.05, seed=4)


def _task(world: WorldMap, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A seeded start and goal 6-12 m apart, on the 0.5 m lattice, 0.5 m beyond the
    footprint from obstacles, connected for the footprint."""
    rng = np.random.default_rng(seed)
    (x0, y0), (x1, y1) = world.bounds
    for _ in range(10_000):
        p = np.round(rng.uniform((x0 + 1, y0 + 1), (x1 - 1, y1 - 1)) / 0.5) * 0.5
        a, d = rng.uniform(0, 2 * np.pi), rng.uniform(6.0, 12.0)
        q = np.round((p + d * np.array([np.cos(a), np.sin(a)])) / 0.5) * 0.5
        pts = np.array([p, q])
        if np.any(pts < (x0, y0)) or np.any(pts > (x1, y1)):
            continue
        if np.all(world.clearance(pts) >= FOOT + 0.5) and footprint_connected(world, p, q, FOOT):
            return p, q
    raise AssertionError("no task drawn")


# -- windows of a map ---------------------------------------------------------------------
def test_window_clearance_never_exceeds_the_maps(office: WorldMap) -> None:
    rows, cols = slice(100, 420), slice(250, 700)
    win = office.window(rows, cols)
    assert win.grid_shape == (320, 450)
    np.testing.assert_allclose(win.origin, office.origin + 0.05 * np.array([250, 100]), atol=1e-12)
    np.testing.assert_array_equal(win.occupied, office.occupied[rows, cols])
    rng = np.random.default_rng(0)
    (x0, y0), (x1, y1) = win.bounds
    p = rng.uniform((x0, y0), (x1, y1), size=(4000, 2))
    cw, cm = win.clearance(p), office.clearance(p)
    assert np.all(cw <= cm + 1e-12)
    # Where the window's edge is farther than the nearest obstacle, the window sees it
    # (within a cell: among equally near cells the two transforms may pick others).
    edge = np.minimum(
        np.minimum(p[:, 0] - x0, x1 - p[:, 0]), np.minimum(p[:, 1] - y0, y1 - p[:, 1])
    )
    far = edge > cm + 3 * office.resolution
    assert np.count_nonzero(far) > 1000
    np.testing.assert_allclose(cw[far], cm[far], atol=office.resolution)


def test_window_keep_mask_and_errors(office: WorldMap) -> None:
    keep = np.zeros((10, 20), dtype=bool)
    keep[2:8, 5:15] = True
    win = office.window(slice(300, 310), slice(300, 320), keep=keep)
    assert np.all(win.occupied[~keep])
    np.testing.assert_array_equal(win.occupied[keep], office.occupied[300:310, 300:320][keep])
    with pytest.raises(MapError, match="non-empty row and column ranges"):
        office.window(slice(5, 5), slice(0, 10))
    with pytest.raises(MapError, match="step 1"):
        office.window(slice(0, 10, 2), slice(0, 10))
    with pytest.raises(MapError, match="keep mask"):
        office.window(slice(0, 10), slice(0, 10), keep=np.ones((3, 3), dtype=bool))


# -- the task's region ----------------------------------------------------------------------
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_region_holds_the_path_within_its_margin(
    office: WorldMap, palette: Palette, seed: int
) -> None:
    start, goal = _task(office, seed)
    margin = 3.0
    region = task_region(
        office, np.array([start, goal]), footprint_radius=FOOT, margin=margin, d=palette.d
    )
    assert region is not None
    # The lower corner lies on the whole map's lattice: a whole number of d, of cells.
    offset = (region.origin - office.origin) / palette.d
    np.testing.assert_allclose(offset, np.round(offset), atol=1e-9)
    # The region holds a shortest footprint path of the whole map: A* finds one as
    # long in it.
    lengths = []
    for world in (office, region):
        free = np.ascontiguousarray(world.clearance_grid >= FOOT)
        iy, ix, _ = world._cells(np.array([start, goal]))
        nx = world.grid_shape[1]
        cells = astar_cells(free, int(iy[0] * nx + ix[0]), int(iy[1] * nx + ix[1]))
        assert cells.size > 0
        centres = world.cell_centers().reshape(-1, 2)[cells]
        lengths.append(float(np.sum(np.hypot(*np.diff(centres, axis=0).T))))
    np.testing.assert_allclose(lengths[1], lengths[0], rtol=1e-9)
    # No more free cells than a band of the margin on either side of such a path.
    band = 2 * margin * lengths[0] + np.pi * margin**2
    assert np.count_nonzero(~region.occupied) * office.resolution**2 <= band


def test_region_is_none_for_an_unreachable_goal(palette: Palette) -> None:
    # A walled-in goal: no footprint path, the whole map's checks say why.
    world = WorldMap.from_shapes(
        [[0.0, 0.0], [40.0, 30.0]],
        _walls(
            [
                (20.0, 20.0, 24.0, 20.2),
                (20.0, 24.0, 24.0, 24.2),
                (20.0, 20.0, 20.2, 24.2),
                (23.8, 20.0, 24.0, 24.2),
            ]
        ),
        resolution=0.1,
    )
    out = task_region(
        world, np.array([[5.0, 5.0], [22.0, 22.0]]), footprint_radius=FOOT, margin=5.0, d=palette.d
    )
    assert out is None


def _walls(rects: list[tuple[float, float, float, float]]) -> list[Any]:
    from gracenav.world import Rectangle

    return [Rectangle((a, b), (c, d)) for a, b, c, d in rects]


def test_region_library_matches_the_whole_maps_away_from_its_edge(
    office: WorldMap, palette: Palette
) -> None:
    start, goal = _task(office, 5)
    region = task_region(
        office, np.array([start, goal]), footprint_radius=FOOT, margin=4.0, d=palette.d
    )
    assert region is not None
    whole = build_library(palette, office, footprint_radius=FOOT, max_halvings=0, memory_limit=None)
    part = build_library(palette, region, footprint_radius=FOOT, max_halvings=0, memory_limit=None)
    assert 0 < len(part) < len(whole)
    # Every policy of the region stands where the whole map has a lattice point.
    lat = (part.start_xy - office.origin) / part.spacing
    np.testing.assert_allclose(lat, np.round(lat), atol=1e-9)
    # Away from what the region added (its edge, the cells beyond the margin) by more
    # than any swept D' reaches, the two libraries keep the same policies.
    tables = _palette_tables(palette, office.resolution, whole.speed_clearance)[1]
    reach = FOOT + float(np.max(tables["type_total_reach"])) + 2 * office.resolution
    r0 = round((region.origin[1] - office.origin[1]) / office.resolution)
    c0 = round((region.origin[0] - office.origin[0]) / office.resolution)
    ny, nx = region.grid_shape
    added = np.ones((ny + 2, nx + 2), dtype=bool)
    added[1:-1, 1:-1] = region.occupied & ~office.occupied[r0 : r0 + ny, c0 : c0 + nx]
    dist = ndimage.distance_transform_edt(~added) * office.resolution

    def rows(lib: Any) -> set[tuple[float, float, int, int]]:
        iy, ix, inside = region._cells(lib.start_xy)
        ok = inside & (dist[iy + 1, ix + 1] > reach)
        return {
            (round(x, 6), round(y, 6), int(p), int(k))
            for (x, y), p, k, o in zip(
                lib.start_xy, lib.palette_index, lib.orientation, ok, strict=True
            )
            if o
        }

    inner = rows(part)
    assert len(inner) > 1000
    assert inner == rows(whole)


# -- scenarios ------------------------------------------------------------------------------
GAP: dict[str, Any] = {
    "name": "a hall with a slot beside the start and a wide way far off",
    "map": {
        "bounds": [[0.0, 0.0], [34.0, 30.0]],
        "resolution": 0.1,
        # A wall at y = 15: a slot of 0.6 m free cells at x = 5 (the footprint passes,
        # no policy's swept D' does) and a 4 m opening at x = 20-24.
        "obstacles": [
            {"rectangle": {"min": [0.0, 14.8], "max": [4.74, 15.2]}},
            {"rectangle": {"min": [5.26, 14.8], "max": [20.0, 15.2]}},
            {"rectangle": {"min": [24.0, 14.8], "max": [34.0, 15.2]}},
        ],
    },
    "robot": {"footprint_radius": 0.25},
    "planner": {"max_halvings": 0},
    "task": {
        "kind": "point_to_point",
        "goal": [5.0, 20.0, 0.0, 0.0],
        "starts": [[5.0, 10.0, 0, 0]],
    },
    "simulation": {"max_time": 20},
}


def _scenario(data: dict[str, Any], **planner: Any) -> Any:
    doc = copy.deepcopy(data)
    doc["planner"].update(planner)
    return parse_scenario(doc, source="test")


def test_resolve_region_by_area() -> None:
    big = _scenario(GAP)
    small = copy.deepcopy(GAP)
    small["map"]["bounds"] = [[0.0, 0.0], [34.0, 24.0]]
    small["map"]["obstacles"] = []
    small["task"]["goal"] = [5.0, 20.0, 0.0, 0.0]
    world_big = WorldMap.from_shapes([[0.0, 0.0], [34.0, 30.0]], resolution=0.5)
    world_small = WorldMap.from_shapes([[0.0, 0.0], [34.0, 24.0]], resolution=0.5)
    assert 34.0 * 24.0 < AUTO_REGION_AREA < 34.0 * 30.0
    assert resolve_region(big, world_big) == "task"
    assert resolve_region(_scenario(small), world_small) == "map"
    assert resolve_region(_scenario(GAP, region="map"), world_big) == "map"
    assert resolve_region(_scenario(small, region="task"), world_small) == "task"


def test_region_keys_are_checked() -> None:
    with pytest.raises(ConfigError, match=r"'planner\.region'"):
        _scenario(GAP, region="room")
    margin = r"'planner\.region_margin' 1 m must be at least .* \(1\.25 m\)"
    with pytest.raises(ConfigError, match=margin):
        _scenario(GAP, region_margin=1.0)
    sc = _scenario(GAP, region="task", region_margin=3.5)
    assert (sc.region, sc.region_margin) == ("task", 3.5)


def test_library_key_holds_the_task_only_for_a_region(palette: Palette) -> None:
    a, b = copy.deepcopy(GAP), copy.deepcopy(GAP)
    b["task"]["goal"] = [8.0, 20.0, 0.0, 0.0]
    assert library_key(_scenario(a), palette) != library_key(_scenario(b), palette)
    # The whole map's library on the map's lattice serves every task; on the lattice
    # through the goal (the default for point-to-point tasks), each goal its own.
    assert library_key(_scenario(a, region="map", lattice_anchor="map"), palette) == (
        library_key(_scenario(b, region="map", lattice_anchor="map"), palette)
    )
    assert library_key(_scenario(a, region="map"), palette) != library_key(
        _scenario(b, region="map"), palette
    )


def test_task_waypoints_of_a_surveillance_loop() -> None:
    doc = copy.deepcopy(GAP)
    doc["task"] = {
        "kind": "surveillance",
        "start": [5.0, 10.0, 0.0, 0.0],
        "goals": [[10.0, 10.0, 0.5, 0.0], [10.0, 12.0, -0.5, 0.0]],
        "loops": 2,
    }
    pts = task_waypoints(_scenario(doc))
    np.testing.assert_array_equal(pts, [[5, 10], [10, 10], [10, 12], [10, 10]])


def test_a_task_impossible_in_its_region_falls_back_to_the_whole_map(palette: Palette) -> None:
    sc = _scenario(GAP)
    prepared = prepare_library(sc, palette)
    assert prepared.region == "task"
    assert prepared.library.world_map is not prepared.world_map
    with pytest.raises(PlanningError):
        _checked(_scenario(GAP, region="task"), prepared, palette, _execution_options(sc))
    whole = _checked(sc, prepared, palette, _execution_options(sc))
    assert whole.region == "map"
    assert whole.library.world_map is whole.world_map


def test_a_run_on_its_region_reaches_the_goal(palette: Palette) -> None:
    doc = copy.deepcopy(GAP)
    doc["task"] = {
        "kind": "point_to_point",
        "goal": [12.0, 22.0, 0.0, 0.0],
        "starts": [[7.0, 20.0, 0.0, 0.0]],
    }
    result = run_scenario(_scenario(doc), palette=palette)
    (run,) = result.runs
    assert run.reached_goal and not run.contact
    assert run.final_error_m is not None and run.final_error_m < 0.01
    region = summary_dict(result)["library_region"]
    assert region["kind"] == "task"
    (x0, y0), (x1, y1) = region["bounds_m"]
    assert (x1 - x0) * (y1 - y0) < 0.5 * 34.0 * 30.0
    assert x0 <= 7.0 - 5.0 + 0.5 and x1 >= 12.0 + 5.0 - 0.05


def test_a_big_region_takes_fewer_halvings_when_they_are_chosen(
    palette: Palette, monkeypatch: pytest.MonkeyPatch
) -> None:
    import gracenav.scenarios.region as region_module

    doc = copy.deepcopy(GAP)
    del doc["planner"]["max_halvings"]
    doc["task"] = {
        "kind": "point_to_point",
        "goal": [12.0, 22.0, 0.0, 0.0],
        "starts": [[7.0, 20.0, 0.0, 0.0]],
    }
    assert prepare_library(_scenario(doc), palette).max_halvings == 1
    monkeypatch.setattr(region_module, "REGION_POLICIES", 1000)
    capped = prepare_library(_scenario(doc), palette)
    assert (capped.region, capped.max_halvings) == ("task", 0)
    assert capped.library.spacing == pytest.approx(palette.d, abs=1e-12)
    # Halvings the scenario gives are kept.
    assert prepare_library(_scenario(doc, max_halvings=1), palette).max_halvings == 1
