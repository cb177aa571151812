"""Automatic instantiation: lattice, obstacle checks, orientations, coverage, halving."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import DT, palette, policy, primitive

from gracenav import ConfigError, MapError
from gracenav.library import (
    POLICY_BYTES,
    InstantiationIteration,
    PolicyLibrary,
    build_library,
    estimate_library_size,
    max_trim_speed,
    quarter_turn,
    sample_position_states,
)
from gracenav.palette import Palette
from gracenav.policies import (
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
)
from gracenav.policies.domains import EllipsoidalDomain
from gracenav.world import WorldMap, load_map

# -- inline fixtures: primitives with septic position references ------------------------


def rest(duration: float = 1.0) -> SampledPrimitive:
    return primitive("rest", (0.0, 0.0), duration=duration, kind=PrimitiveKind.REST)


def cruise_x(v: float = 0.5) -> SampledPrimitive:
    return primitive("cruise_x", (0.5, 0.0), (v, 0.0), (v, 0.0), 0.5 / v, PrimitiveKind.CRUISE)


def free_map(x0: float, y0: float, x1: float, y1: float, obstacles: list | None = None) -> WorldMap:
    return load_map(
        {"bounds": [[x0, y0], [x1, y1]], "obstacles": obstacles or [], "resolution": 0.05}
    )


def rows(lib: PolicyLibrary) -> set[tuple[int, int, float, float]]:
    """(palette index, k, x, y) of every library policy, positions rounded to 1e-9 m."""
    return {
        (int(p), int(k), round(float(x), 9), round(float(y), 9))
        for p, k, (x, y) in zip(lib.palette_index, lib.orientation, lib.start_xy, strict=True)
    }


# -- lattice -----------------------------------------------------------------------------


def test_instantiation_points_lie_on_the_origin_aligned_lattice() -> None:
    wmap = free_map(-1.25, 0.75, 2.75, 4.75)
    # D' radius 0.1 m (S = G = 0.1 m, outer factor 1) + footprint 0.1 m: every lattice
    # point at least 0.2 m from the map edge is valid, i.e. all but the border ring.
    pal = palette(policy(rest(), (0.1, 0.1), (0.1, 0.1), (1.0, 1.0)))
    lib = build_library(pal, wmap, footprint_radius=0.1, max_halvings=0, coverage_samples=200)
    assert lib.spacing == pytest.approx(0.5, rel=0, abs=1e-15)
    np.testing.assert_allclose(lib.origin, [-1.25, 0.75], rtol=0, atol=0)
    assert lib.lattice_shape == (9, 9)
    offsets = (lib.start_xy - lib.origin) / 0.5
    np.testing.assert_allclose(offsets, np.rint(offsets), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.rint(offsets).astype(int), lib.start_cell)
    xs = -1.25 + 0.5 * np.arange(1, 8)
    ys = 0.75 + 0.5 * np.arange(1, 8)
    expected = {(0, k, round(x, 9), round(y, 9)) for k in range(4) for x in xs for y in ys}
    assert rows(lib) == expected
    # A goal on the lattice is an instantiation point.
    assert (0, 0, 0.75, 2.75) in rows(lib)
    # Type-major, then row-major point order.
    order = np.lexsort((lib.start_cell[:, 0], lib.start_cell[:, 1], lib.type_index))
    np.testing.assert_array_equal(order, np.arange(len(lib)))


# -- obstacle and edge rejection ------------------------------------------------------------


def test_obstacle_and_edge_rejection_hand_computed() -> None:
    # 2.5 m x 1 m map, an obstacle covering the cells around (2.0, 0.5). A straight 0.5 m
    # move along +x with D' radius 0.1 m and footprint 0.1 m needs 0.2 m of clearance
    # along its path. Lattice points: x in {0, 0.5, ..., 2.5}, y in {0, 0.5, 1}; only
    # y = 0.5 is far enough from the edge, and paths along ±y always reach it.
    wmap = free_map(0.0, 0.0, 2.5, 1.0, [{"rectangle": {"min": [1.96, 0.46], "max": [2.04, 0.54]}}])
    assert not wmap.is_free([[2.0, 0.5]])[()]
    move = primitive("move_x", (0.5, 0.0), duration=2.0)
    pal = palette(policy(move, (0.1, 0.1), (0.1, 0.1), (1.0, 1.0)))
    lib = build_library(pal, wmap, footprint_radius=0.1, max_halvings=0, coverage_samples=200)
    expected = {
        (0, 0, 0.5, 0.5),  # (0.5, 0.5) -> (1.0, 0.5)
        (0, 0, 1.0, 0.5),  # (1.0, 0.5) -> (1.5, 0.5): 0.41 m from the obstacle
        (0, 2, 1.0, 0.5),  # (1.0, 0.5) -> (0.5, 0.5)
        (0, 2, 1.5, 0.5),  # (1.5, 0.5) -> (1.0, 0.5)
    }
    # Rejected: (1.5 -> 2.0) and (2.0 -> 2.5) hit the obstacle, (0.5 -> 0) reaches the edge,
    # (2.0 -> 1.5) starts in the obstacle, every ±y move reaches the edge.
    assert rows(lib) == expected
    np.testing.assert_allclose(lib.end_state[lib.orientation == 0, 0], [1.0, 1.5], atol=1e-12)


def test_stopping_allowance_is_all_ahead_and_half_beside_hand_computed() -> None:
    # A 4 m x 1 m corridor; a straight cruise of 0.5 m at 0.5 m/s with D' radius 0.1 m,
    # footprint 0.1 m, lattice points at y = 0.5 (0.5 m from both long walls). The
    # paper's check needs 0.2 m around the path. An allowance of 0.8 s asks
    # 0.8 s x 0.5 m/s = 0.4 m more straight ahead; the disc checked for it (led by
    # 0.2 m and grown by 0.2 m, radius 0.4 m) asks half of that beside, which still
    # fits (the cruise stays on y = 0.5, 0.5 m from the walls), but the end walls now
    # need 0.5 + 0.2 + 0.4 = 1.1 m ahead of the start instead of 0.7 m. The full
    # allowance in every direction (0.6 m beside) would keep none.
    wmap = free_map(0.0, 0.0, 4.0, 1.0)
    pal = palette(policy(cruise_x(0.5), (0.1, 0.1), (0.1, 0.1), (1.0, 1.0)))

    def kept(allowance: float) -> set[tuple[int, int, float, float]]:
        lib = build_library(
            pal,
            wmap,
            footprint_radius=0.1,
            max_halvings=0,
            coverage_samples=200,
            speed_clearance=allowance,
        )
        return rows(lib)

    def line(k: int, xs: np.ndarray) -> set[tuple[int, int, float, float]]:
        return {(0, k, round(float(x), 9), 0.5) for x in xs}

    # Moving +x (k = 0) from x0: x0 >= 0.2 behind, x0 + 0.7 <= 4 (paper) or
    # x0 + 1.1 <= 4 ahead; moving -x (k = 2) mirrored. Moves along y hit a wall.
    assert kept(0.0) == line(0, np.arange(0.5, 3.01, 0.5)) | line(2, np.arange(1.0, 3.51, 0.5))
    assert kept(0.8) == line(0, np.arange(0.5, 2.51, 0.5)) | line(2, np.arange(1.5, 3.51, 0.5))


def _exact_valid(
    lib_map: WorldMap,
    pol: MotionPolicy,
    q: np.ndarray,
    k: int,
    fp: float,
    speed_clearance: float = 0.0,
) -> float:
    """Smallest clearance margin over every control tick of the swept D' with the
    stopping allowance: the disc of radius ``fp`` + ρ'(t) + κ|v|/2 centred κ v/2 ahead
    of the reference (κ = ``speed_clearance``) must be clear (m)."""
    prim = pol.primitive
    t = np.arange(prim.num_ticks + 1) * prim.dt
    lead = prim.position[:, :2] + 0.5 * speed_clearance * prim.position[:, 2:4]
    centres = q + lead @ quarter_turn(k).T
    radius = pol.radii(t)[0] * pol.outer_factors[0]
    speed = np.hypot(prim.position[:, 2], prim.position[:, 3])
    return float(np.min(lib_map.clearance(centres) - fp - radius - 0.5 * speed_clearance * speed))


@pytest.mark.parametrize("speed_clearance", [0.0, 0.3])
def test_sweep_check_is_conservative_and_tight(speed_clearance: float) -> None:
    """Every kept instantiation keeps clear, at every control tick, the footprint plus
    D'(t) grown by the stopping allowance (the disc led by half of ``speed_clearance``
    times the velocity and grown by half of it times the speed), and every
    instantiation clear by more than the sampling allowance is kept."""
    rng = np.random.default_rng(3)
    obstacles = [
        {"circle": {"center": [float(x), float(y)], "radius": float(r)}}
        for x, y, r in zip(
            rng.uniform(0.5, 3.5, 6),
            rng.uniform(0.5, 3.5, 6),
            rng.uniform(0.1, 0.3, 6),
            strict=True,
        )
    ]
    wmap = free_map(0.0, 0.0, 4.0, 4.0, obstacles)
    turn = primitive("turn", (1.0, 0.5), (0.5, 0.0), (0.0, 0.5), 3.0)
    pols = (policy(turn, (0.2, 0.2), (0.1, 0.1), (1.5, 2.0)), policy(rest(), (0.15, 0.2)))
    pal = palette(*pols)
    fp = 0.2
    lib = build_library(
        pal,
        wmap,
        footprint_radius=fp,
        max_halvings=1,
        coverage_samples=200,
        speed_clearance=speed_clearance,
    )
    assert lib.speed_clearance == speed_clearance
    kept = rows(lib)
    # Allowance: half the sweep step (map resolution) plus one tick of motion at 0.6 m/s,
    # plus the shrink of D' between two checked samples (< 1 cm here).
    allowance = 0.5 * (wmap.resolution + 0.6 * DT) + 0.01
    n_checked = n_refused_for_speed = 0
    for p, pol in enumerate(pols):
        for k in range(4):
            for ix in range(lib.lattice_shape[1]):
                for iy in range(lib.lattice_shape[0]):
                    q = lib.origin + lib.spacing * np.array([ix, iy])
                    margin = _exact_valid(wmap, pol, q, k, fp, speed_clearance)
                    key = (p, k, round(float(q[0]), 9), round(float(q[1]), 9))
                    if margin < 0.0:
                        assert key not in kept, f"kept an instantiation that collides: {key}"
                        # Clear of the verified D' alone: refused for the allowance.
                        n_refused_for_speed += _exact_valid(wmap, pol, q, k, fp) >= allowance
                    if margin >= allowance + 1e-9:
                        assert key in kept, f"rejected a clear instantiation: {key}"
                    n_checked += 1
    assert lib.spacing == pytest.approx(0.25, abs=1e-15)
    assert n_checked == 2 * 4 * 17 * 17
    assert 0 < len(lib) < n_checked
    assert (n_refused_for_speed > 0) == (speed_clearance > 0)


# -- orientations ------------------------------------------------------------------------


def test_orientations_rotate_displacements_velocities_and_domains() -> None:
    turn = primitive("turn", (1.0, 0.5), (0.5, 0.0), (0.0, 0.5), 3.0)
    pal = palette(policy(turn, (0.2, 0.3), (0.1, 0.1), (1.5, 2.0), correlation=-0.5))
    lib = build_library(pal, free_map(0.0, 0.0, 6.0, 6.0), max_halvings=0, coverage_samples=200)
    expected = {
        0: ((1.0, 0.5), (0.5, 0.0), (0.0, 0.5)),
        1: ((-0.5, 1.0), (0.0, 0.5), (-0.5, 0.0)),
        2: ((-1.0, -0.5), (-0.5, 0.0), (0.0, -0.5)),
        3: ((0.5, -1.0), (0.0, -0.5), (0.5, 0.0)),
    }
    for k, (disp, v0, v1) in expected.items():
        sel = np.flatnonzero(lib.orientation == k)
        assert sel.size > 0
        np.testing.assert_allclose(
            lib.end_state[sel, :2] - lib.start_state[sel, :2],
            np.broadcast_to(disp, (sel.size, 2)),
            rtol=0,
            atol=1e-9,
        )
        np.testing.assert_allclose(
            lib.start_state[sel, 2:], np.broadcast_to(v0, (sel.size, 2)), atol=1e-12
        )
        np.testing.assert_allclose(
            lib.end_state[sel, 2:], np.broadcast_to(v1, (sel.size, 2)), atol=1e-12
        )
        view = lib.policy(int(sel[0]))
        assert view.orientation == k
        assert view.angle == pytest.approx(k * np.pi / 2, rel=1e-15)
        ref = view.reference_positions
        np.testing.assert_allclose(ref[0, :2], lib.start_xy[sel[0]], atol=1e-12)
        np.testing.assert_allclose(ref[-1, :4], lib.end_state[sel[0]], atol=1e-9)
        # Acceleration rotates too: compare with the palette's at mid-manoeuvre.
        mid = turn.num_ticks // 2
        np.testing.assert_allclose(
            ref[mid, 4:6], quarter_turn(k) @ turn.position[mid, 4:6], atol=1e-12
        )
        # Domains: centred on the world-frame reference, rotation-invariant shape.
        t = 1.3
        d_world = view.domain(t)
        np.testing.assert_allclose(d_world.center, view.position_state(t), atol=1e-12)
        np.testing.assert_allclose(d_world.shape_matrix, pol_shape(pal, t), rtol=1e-12, atol=0)
        # XY projection of D'(t): a disc of radius outer factor × position extent.
        q = view.outer_domain(t).xy_projection()
        r = pal.policies[0].outer_factors[0] * float(pal.policies[0].radii(t)[0])
        np.testing.assert_allclose(q, np.eye(2) / r**2, rtol=1e-9)
    assert view.name.startswith("turn@270°(")
    assert view.duration == pytest.approx(3.0, abs=1e-12)
    assert view.kind is PrimitiveKind.MANEUVER and not view.is_trim


def pol_shape(pal: Palette, t: float) -> np.ndarray:
    return pal.policies[0].domain(t).shape_matrix


def test_policy_view_and_trim_indices() -> None:
    pal = palette(
        policy(rest()), policy(cruise_x()), policy(primitive("m", (0.5, 0.5), duration=2.0))
    )
    lib = build_library(pal, free_map(0.0, 0.0, 3.0, 3.0), max_halvings=0, coverage_samples=200)
    trims = lib.trim_indices()
    assert set(lib.palette_index[trims].tolist()) == {0, 1}
    assert np.all(lib.palette_index[np.setdiff1d(np.arange(len(lib)), trims)] == 2)
    np.testing.assert_array_equal(
        lib.trim_indices(PrimitiveKind.REST), np.flatnonzero(lib.palette_index == 0)
    )
    with pytest.raises(ConfigError, match="MANEUVER"):
        lib.trim_indices(PrimitiveKind.MANEUVER)
    np.testing.assert_allclose(lib.durations[lib.palette_index == 1], 1.0, atol=1e-12)
    np.testing.assert_allclose(lib.path_lengths[lib.palette_index == 1], 0.5, rtol=1e-9)
    np.testing.assert_allclose(lib.path_lengths[lib.palette_index == 0], 0.0, atol=0)
    i = len(lib) - 1
    assert lib.policy(-1).index == i and lib.policy(i).palette_index == 2
    with pytest.raises(IndexError, match="out of range"):
        lib.policy(len(lib))
    assert "PolicyLibrary(" in repr(lib)


# -- start domain queries and coverage ------------------------------------------------------


def test_start_domain_contains_matches_dense_check() -> None:
    pal = palette(
        policy(rest(), (0.3, 0.25), correlation=-0.8),
        policy(cruise_x(), (0.25, 0.3), correlation=-0.8),
        policy(
            primitive("go", (1.0, 0.0), (0.0, 0.0), (0.5, 0.0), 2.5), (0.2, 0.2), correlation=-0.8
        ),
    )
    wmap = free_map(0.0, 0.0, 3.0, 3.0, [{"circle": {"center": [1.5, 1.5], "radius": 0.3}}])
    lib = build_library(pal, wmap, footprint_radius=0.1, max_halvings=1, coverage_samples=300)
    assert lib.spacing == pytest.approx(0.25, abs=1e-15)
    rng = np.random.default_rng(7)
    pts = np.column_stack([rng.uniform(0, 3, (3000, 2)), rng.uniform(-0.6, 0.6, (3000, 2))])
    got = lib.start_domain_contains(pts)
    assert got.shape == (3000, len(lib)) and got.dtype == bool
    dense = np.column_stack([lib.policy(i).start_domain.contains(pts) for i in range(len(lib))])
    np.testing.assert_array_equal(got.toarray(), dense)
    np.testing.assert_array_equal(lib.start_domain_covers(pts), dense.any(axis=1))
    assert 0 < dense.sum() < dense.size
    with pytest.raises(ConfigError, match=r"\(M, 4\)"):
        lib.start_domain_contains(np.zeros((3, 2)))


def test_coverage_matches_the_analytic_area_fraction() -> None:
    # Rest trim only, so v_max = 0 and coverage is an area fraction. S has radius 0.25 m
    # (= d / 2) and D' = S; with footprint 0.05 m a start point needs 0.3 m of clearance:
    # the 7 x 7 interior points of a 4 m square. Their discs are disjoint, covering
    # 49 π 0.25² m² of the 3.9 m x 3.9 m square of positions with clearance >= 0.05 m.
    pal = palette(policy(rest(), (0.25, 0.25), (0.25, 0.25), (1.0, 1.0)))
    n = 20_000
    lib = build_library(
        pal, free_map(0.0, 0.0, 4.0, 4.0), footprint_radius=0.05, max_halvings=0, coverage_samples=n
    )
    assert len(lib) == 4 * 49
    exact = 49 * np.pi * 0.25**2 / 3.9**2
    sigma = np.sqrt(exact * (1 - exact) / n)
    assert lib.coverage == pytest.approx(exact, abs=4 * sigma)
    assert lib.iterations == (
        InstantiationIteration(0.5, 4 * 49, lib.coverage, lib.iterations[0].seconds),
    )


def test_coverage_against_brute_force_with_velocities() -> None:
    pal = palette(
        policy(rest(), (0.2, 0.3)),
        policy(cruise_x(), (0.2, 0.3)),
        policy(primitive("go", (1.0, 0.0), (0.0, 0.0), (0.5, 0.0), 2.5), (0.15, 0.2)),
    )
    wmap = free_map(0.0, 0.0, 4.0, 4.0, [{"rectangle": {"min": [1.7, 1.7], "max": [2.3, 2.3]}}])
    lib = build_library(
        pal, wmap, footprint_radius=0.15, max_halvings=0, coverage_samples=4000, seed=11
    )
    assert len(lib) > 100
    # The same samples as build_library: seed 11, clearance >= footprint, and velocities in
    # [-0.5, 0.5]² (the largest trim speed).
    assert max_trim_speed(pal) == pytest.approx(0.5, abs=1e-12)
    pts = sample_position_states(wmap, 4000, footprint_radius=0.15, v_max=0.5, seed=11)
    assert pts.shape == (4000, 4)
    assert np.all(wmap.clearance(pts[:, :2]) >= 0.15)
    assert np.all(np.abs(pts[:, 2:]) <= 0.5)
    dense = np.zeros(4000, dtype=bool)
    for i in range(len(lib)):
        dense |= lib.policy(i).start_domain.contains(pts)
    assert lib.coverage == pytest.approx(dense.mean(), abs=1e-12)
    assert 0.0 < lib.coverage < 1.0


def test_halving_refines_until_the_target_or_the_limit() -> None:
    pal = palette(policy(rest(), (0.15, 0.15)), policy(cruise_x(), (0.15, 0.15)))
    wmap = free_map(0.0, 0.0, 3.0, 3.0)
    # Just below 1: with a target of 1, which no spacing reaches here (samples by the
    # walls lie in no start domain), only the last spacing is built (below).
    lib = build_library(pal, wmap, max_halvings=2, coverage_samples=2000, coverage_target=0.999)
    spacings = [it.spacing for it in lib.iterations]
    assert spacings == [0.5, 0.25, 0.125]
    sizes = [it.size for it in lib.iterations]
    covs = [it.coverage for it in lib.iterations]
    assert sizes[0] < sizes[1] < sizes[2] == len(lib)
    assert covs[0] < covs[1] <= covs[2] == lib.coverage < 1.0
    assert lib.spacing == pytest.approx(0.125, abs=1e-15)
    assert all(it.seconds > 0 for it in lib.iterations)
    # A coarser lattice is a subset of the finer one.
    coarse = build_library(pal, wmap, max_halvings=0, coverage_samples=2000)
    assert rows(coarse) <= rows(lib)
    # Stop as soon as the target is met.
    target = 0.5 * (covs[0] + covs[1])
    mid = build_library(pal, wmap, max_halvings=3, coverage_target=target, coverage_samples=2000)
    assert [it.spacing for it in mid.iterations] == [0.5, 0.25]
    assert mid.coverage == pytest.approx(covs[1], abs=1e-12)
    once = build_library(pal, wmap, max_halvings=3, coverage_target=0.0, coverage_samples=2000)
    assert len(once.iterations) == 1
    # A target of 1 out of reach: the last spacing alone, the same library.
    last = build_library(pal, wmap, max_halvings=2, coverage_samples=2000)
    assert [it.spacing for it in last.iterations] == [0.125]
    assert rows(last) == rows(lib) and last.coverage == lib.coverage


# -- bad inputs ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"footprint_radius": -0.1}, "footprint_radius"),
        ({"footprint_radius": float("nan")}, "footprint_radius"),
        ({"coverage_target": 1.5}, "coverage_target"),
        ({"max_halvings": -1}, "max_halvings"),
        ({"max_halvings": 1.5}, "max_halvings"),
        ({"coverage_samples": 0}, "coverage_samples"),
        ({"sweep_step": 0.0}, "sweep_step"),
        ({"speed_clearance": -0.1}, "speed_clearance"),
        ({"speed_clearance": 5.0}, "speed_clearance"),
        ({"speed_clearance": True}, "speed_clearance"),
    ],
)
def test_bad_arguments_name_the_argument(kwargs: dict, match: str) -> None:
    pal = palette(policy(rest()))
    with pytest.raises(ConfigError, match=match):
        build_library(pal, free_map(0.0, 0.0, 2.0, 2.0), **kwargs)


def test_bad_palette_and_map() -> None:
    wmap = free_map(0.0, 0.0, 2.0, 2.0)
    with pytest.raises(ConfigError, match="no policies"):
        build_library(palette(), wmap)
    with pytest.raises(ConfigError, match="WorldMap"):
        build_library(palette(policy(rest())), "map.yaml")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="Palette"):
        build_library(object(), wmap)  # type: ignore[arg-type]
    shifted = primitive("shifted", (0.5, 0.0), duration=2.0)
    pos = shifted.position.copy()
    pos[:, 0] += 0.1
    moved = SampledPrimitive(**{**shifted.__dict__, "position": pos})
    with pytest.raises(ConfigError, match="not at the origin"):
        build_library(palette(policy(moved)), wmap)
    full = load_map(
        {"bounds": [[0, 0], [1, 1]], "obstacles": [{"rectangle": {"min": [0, 0], "max": [1, 1]}}]}
    )
    with pytest.raises(MapError, match="footprint_radius"):
        build_library(palette(policy(rest())), full)


def test_library_arrays_are_read_only() -> None:
    lib = build_library(
        palette(policy(rest())), free_map(0.0, 0.0, 2.0, 2.0), max_halvings=0, coverage_samples=100
    )
    with pytest.raises(ValueError, match="read-only"):
        lib.start_xy[0, 0] = 1.0
    assert isinstance(lib.policy(0).start_domain, EllipsoidalDomain)


def test_plot_library(tmp_path) -> None:
    from gracenav.plotting.library import plot_library

    pal = palette(policy(rest()), policy(cruise_x()))
    wmap = free_map(0.0, 0.0, 3.0, 3.0, [{"circle": {"center": [1.5, 1.5], "radius": 0.4}}])
    lib = build_library(pal, wmap, max_halvings=0, coverage_samples=500)
    out = plot_library(lib, tmp_path / "lib.png")
    assert out.stat().st_size > 10_000
    out2 = plot_library(lib, tmp_path / "cov.png", coverage=True, seed=1)
    assert out2.stat().st_size > 10_000


@pytest.mark.slow
def test_plot_library_coverage_with_captures(tmp_path, monkeypatch, request) -> None:
    """With a palette that has catches, --coverage adds a fourth panel: the states
    covered by a start domain or a capture (here on a 12 x 12 grid instead of 30 x 30).
    On a 4 m room with a central box it covers far more than the start domains alone
    (measured 0.863 against 0.354 of the same states) and less in the cells along the
    walls than in those 0.67-1.33 m from the south wall (measured 0.43 and 1.0),
    where a push leaves room to stop."""
    from PIL import Image

    from gracenav.execution.capture import Capture
    from gracenav.plotting import library as plotting

    monkeypatch.setattr(plotting, "_CAPTURE_CELLS", 12)
    wmap = free_map(0.0, 0.0, 4.0, 4.0, [{"rectangle": {"min": [1.7, 1.7], "max": [2.3, 2.3]}}])
    shipped = request.getfixturevalue("palette")  # conftest's; `palette` here is synthetic
    lib = build_library(shipped, wmap, footprint_radius=0.2, max_halvings=1)
    frac, extent, share = plotting._capture_grid(lib, np.random.default_rng(0), progress=False)
    assert frac.shape == (12, 12) and extent == pytest.approx((0.0, 4.0, 0.0, 4.0))
    ok = np.isfinite(frac)
    assert np.all((frac[ok] >= 0.0) & (frac[ok] <= 1.0))
    assert not ok[6, 6]  # the box's cell: no free sample
    ring = np.zeros_like(ok)
    ring[[0, -1], :] = True
    ring[:, [0, -1]] = True
    middle = np.zeros_like(ok)
    middle[2:4, 2:10] = True
    assert np.nanmean(frac[ring & ok]) < 0.6 < 0.95 < np.nanmean(frac[middle & ok])
    with monkeypatch.context() as mp:  # the same states, no capture
        mp.setattr(Capture, "covers", lambda self, states: np.zeros(len(states), dtype=bool))
        _, _, alone = plotting._capture_grid(lib, np.random.default_rng(0), progress=False)
    assert share > 0.8 and alone < 0.4, (share, alone)
    one = plotting.plot_library(lib, tmp_path / "one.png")
    four = plotting.plot_library(lib, tmp_path / "four.png", coverage=True)
    with Image.open(one) as a, Image.open(four) as b:
        assert b.size[0] == pytest.approx(4 * a.size[0], rel=0.02)


def test_the_largest_start_domain_that_fits_is_placed(request) -> None:
    """Scaled domains: per primitive, orientation and point only the largest verified
    start domain whose swept D' fits is instantiated (checked against libraries built
    from each size alone)."""
    import dataclasses
    from pathlib import Path

    pal = request.getfixturevalue("palette")  # conftest's; `palette` here is synthetic
    world = load_map(Path(__file__).parent.parent / "examples" / "maps" / "room_5m_box.yaml")
    lib = build_library(pal, world, max_halvings=0)
    n_points = lib.lattice_shape[0] * lib.lattice_shape[1]
    key = lib.types.scale_group[lib.type_index] * n_points + lib.point_index
    assert np.unique(key).size == len(lib)
    family = sorted((p for p in pal if p.primitive.name == "capture"), key=lambda p: p.scale)
    assert len(family) >= 2
    valid = {}
    for pol in family:
        alone = build_library(dataclasses.replace(pal, policies=(pol,)), world, max_halvings=0)
        valid[pol.name] = set(
            zip(alone.orientation.tolist(), alone.point_index.tolist(), strict=True)
        )
    names = [pal.policies[p].name for p in lib.palette_index]
    placed = {pol.name: 0 for pol in family}
    for i, name in enumerate(names):
        if name not in valid:
            continue
        placed[name] += 1
        where = (int(lib.orientation[i]), int(lib.point_index[i]))
        assert where in valid[name]
        larger = [p.name for p in family if p.scale > pal[name].scale]
        assert all(where not in valid[other] for other in larger)
    # and every point where some size fits has its largest one
    everywhere = set().union(*valid.values())
    assert sum(placed.values()) == len(everywhere)
    assert placed[family[0].name] > 0 and placed[family[-1].name] > 0


def test_library_size_is_bounded_and_an_over_budget_pass_refused() -> None:
    """The estimate brackets the kept policies; a pass over ``memory_limit`` is refused
    before any instantiation, with the estimate in the message."""
    pal = palette(policy(rest()), policy(cruise_x()))
    wmap = free_map(0.0, 0.0, 4.0, 3.0, [{"rectangle": {"min": [1.7, 1.2], "max": [2.3, 1.8]}}])
    for spacing in (0.5, 0.25):
        low, high = estimate_library_size(pal, wmap, spacing, footprint_radius=0.1)
        lib = build_library(
            pal, wmap, footprint_radius=0.1, max_halvings=int(spacing < 0.5), coverage_samples=50
        )
        assert lib.spacing == spacing
        assert 0 < low <= len(lib) <= high
    limit = low * POLICY_BYTES - 1  # the d / 2 pass needs `low` policies at least
    lib = build_library(
        pal, wmap, footprint_radius=0.1, max_halvings=0, coverage_samples=50, memory_limit=limit
    )
    assert len(lib) > 0  # the pass at d fits
    with pytest.raises(ConfigError, match=r"halving 1.*memory_limit"):
        build_library(
            pal,
            wmap,
            footprint_radius=0.1,
            max_halvings=1,
            coverage_samples=50,
            memory_limit=limit,
        )
    with pytest.raises(ConfigError, match="memory_limit"):
        build_library(pal, wmap, memory_limit=-1.0)
    unlimited = build_library(
        pal, wmap, footprint_radius=0.1, max_halvings=1, coverage_samples=50, memory_limit=None
    )
    assert unlimited.spacing == 0.25


def test_compiled_clearance_is_the_maps_clearance() -> None:
    """The sweep check's compiled clearance agrees with WorldMap.clearance, inside, on
    obstacles, on the edge and outside the map."""
    from gracenav.library.sweep_check import clearance_at

    wmap = free_map(0.0, 0.0, 3.0, 2.0, [{"circle": {"center": [1.2, 0.9], "radius": 0.3}}])
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.uniform(-0.2, 3.2, size=(3000, 2)), [[0.0, 0.0], [3.0, 1.0]]])
    _, nearest = wmap._clearance_data()
    (x0, y0), (x1, y1) = wmap.bounds
    got = np.array(
        [
            clearance_at(x, y, nearest, wmap.occupied, 0.0, 0.0, wmap.resolution, x0, y0, x1, y1)
            for x, y in pts
        ]
    )
    want = wmap.clearance(pts)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.any(want == 0.0) and np.any(want > 0.3)
