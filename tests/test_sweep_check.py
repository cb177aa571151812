"""The compiled check of swept outer domains against a map: its verdicts are those of
checking every sample's clearance one by one, whatever the order of the pairs (the
bounding discs and the failing-group hints only make it faster)."""

from __future__ import annotations

import numpy as np
import pytest

from gracenav.library import push_fans as push_fans_module
from gracenav.library.instantiation import _lattice, _palette_tables
from gracenav.library.sweep_check import check_sweeps
from gracenav.world import forest_map

FOOT = 0.2


def _brute(world, points, pair_type, pair_point, tables) -> np.ndarray:
    """Each pair's verdict by every sample of its type, with WorldMap.clearance."""
    sfirst, scount = tables["type_super_first"], tables["type_super_count"]
    g_first = tables["super_group_first"]
    out = np.ones(pair_type.size, dtype=bool)
    for a, (t, q) in enumerate(zip(pair_type, pair_point, strict=True)):
        last_super = sfirst[t] + scount[t] - 1
        g0 = g_first[sfirst[t]]
        g1 = g_first[last_super] + tables["super_size"][last_super]
        k0 = tables["group_sample_first"][g0]
        k1 = tables["group_sample_first"][g1 - 1] + tables["group_size"][g1 - 1]
        xy = points[q] + tables["sample_offset"][k0:k1]
        out[a] = bool(np.all(world.clearance(xy) >= FOOT + tables["sample_reach"][k0:k1]))
    return out


@pytest.mark.parametrize("push", [0.0, 7.5])
def test_compiled_check_is_the_sample_by_sample_check(palette, monkeypatch, push) -> None:
    """On a cluttered field, 3000 random pairs of policy type and lattice point: the
    verdicts equal the sample-by-sample check, and do not change when the pairs come
    in another order. With a design push (its fan from 0.3 m/s, so that the shipped
    palette has one) a type has hundreds of groups, the case the hints are for."""
    monkeypatch.setattr(push_fans_module, "FAN_FLOOR", 0.3)
    world = forest_map(density=0.012, seed=5)
    types, tables = _palette_tables(palette, float(world.resolution), 0.1, push)
    _, _, _, points = _lattice(world, 0.25)
    rng = np.random.default_rng(0)
    n_types = tables["type_super_first"].size
    assert n_types == types.start_radii.shape[0]
    if push > 0.0:
        assert np.max(tables["type_super_count"]) > 8  # > 64 groups: a fan
    pair_type = rng.integers(0, n_types, 3000)
    pair_point = rng.integers(0, points.shape[0], 3000)
    got = check_sweeps(world, points, pair_type, pair_point, tables, FOOT)
    want = _brute(world, points, pair_type, pair_point, tables)
    assert want.sum() >= 100 and (~want).sum() >= 100  # both verdicts, many of each
    np.testing.assert_array_equal(got, want)
    order = np.argsort(pair_point * n_types + pair_type)  # neighbours in a row
    again = check_sweeps(world, points, pair_type[order], pair_point[order], tables, FOOT)
    np.testing.assert_array_equal(again, want[order])


@pytest.mark.parametrize("seed", range(3))
def test_the_clearance_floor_never_exceeds_the_clearance_and_is_near_it(seed: int) -> None:
    """:func:`_clearance_floor` bounds the clearance from below in every cell it covers
    (inside, on obstacles, on the edge and outside the map), so a disc it calls clear
    is clear; and it is tight enough to decide most discs: within one and a half cells
    of the clearance wherever the point is inside the map."""
    from gracenav.library.sweep_check import _disc_clear, map_grid

    world = forest_map(4.0, 8.0, density=0.03, seed=seed)
    rng = np.random.default_rng(seed)
    (x0, y0), (x1, y1) = world.bounds
    pts = rng.uniform([x0 - 0.3, y0 - 0.3], [x1 + 0.3, y1 + 0.3], size=(20000, 2))
    grid, floor = map_grid(world)
    assert map_grid(world)[1] is floor  # computed once per map
    want = world.clearance(pts)
    ky = (np.floor((pts[:, 1] - grid[3]) / grid[4] - 0.5) + 1).astype(int)
    kx = (np.floor((pts[:, 0] - grid[2]) / grid[4] - 0.5) + 1).astype(int)
    inside = (ky >= 0) & (ky < floor.shape[0]) & (kx >= 0) & (kx < floor.shape[1])
    bound = floor[ky[inside], kx[inside]]
    assert np.all(bound <= want[inside])
    assert np.all(want[inside] - bound <= 1.5 * world.resolution)
    assert np.any(want == 0.0) and np.mean(bound > 0.1) > 0.3
    # The disc test with the floor gives the clearance's verdict at every point.
    need = rng.uniform(0.0, 0.6, size=pts.shape[0])
    got = np.array([_disc_clear(x, y, n, floor, grid) for (x, y), n in zip(pts, need, strict=True)])
    np.testing.assert_array_equal(got, want >= need)
