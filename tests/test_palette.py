"""The palette file: round trip, integrity, keys, atomic writes."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import gracenav.palette.files as palette_module
from gracenav import BallbotParams, CacheError
from gracenav.control import ControllerGains, LQRWeights, design_gains
from gracenav.execution.smoothness import planned_jerk
from gracenav.palette import (
    PALETTE_ENV,
    Palette,
    PaletteLimits,
    cached_palette_path,
    forget_read_palettes,
    load_palette,
    palette_key,
    shipped_palette_path,
)
from gracenav.policies import PrimitiveKind, VerificationOptions
from gracenav.policies.primitive import SampledPrimitive
from gracenav.primitives import PrimitiveSetOptions


def test_shipped_palette_loads_and_round_trips(tmp_path) -> None:
    pal = load_palette()
    path = pal.save(tmp_path / "p.npz")
    again = load_palette(path)
    assert again.names == pal.names
    assert again.key == pal.key
    for a, b in zip(pal.policies, again.policies, strict=True):
        np.testing.assert_array_equal(a.primitive.states, b.primitive.states)
        assert a.report == b.report and a.start_radii == b.start_radii
        assert a.still_report == b.still_report


def test_a_palette_read_before_is_read_again_once_the_read_palettes_are_forgotten(
    monkeypatch, tmp_path
) -> None:
    """An unchanged file read before gives the same palette without reading it; after
    :func:`forget_read_palettes` the next load reads the file again (a new palette)."""
    copy = tmp_path / "p.npz"
    copy.write_bytes(shipped_palette_path().read_bytes())
    reads: list[str] = []
    from_bytes = Palette.from_bytes

    def counted(data: bytes, *, source: str = "palette") -> Palette:
        reads.append(source)
        return from_bytes(data, source=source)

    monkeypatch.setattr(Palette, "from_bytes", counted)
    first = load_palette(copy)
    assert load_palette(copy) is first and len(reads) == 1
    forget_read_palettes()
    again = load_palette(copy)
    assert again is not first and len(reads) == 2
    assert again.key == first.key
    assert load_palette(copy) is again and len(reads) == 2


def test_corrupt_file_is_refused(tmp_path) -> None:
    data = bytearray(shipped_palette_path().read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = b"\xa5" * 64  # zeros may hit zeros
    bad = tmp_path / "bad.npz"
    bad.write_bytes(bytes(data))
    with pytest.raises(CacheError, match="corrupt or unreadable palette file"):
        load_palette(bad)
    trunc = tmp_path / "trunc.npz"
    trunc.write_bytes(bytes(data[:1000]))
    with pytest.raises(CacheError, match="gracenav palette build"):
        load_palette(trunc)


def test_missing_file(tmp_path) -> None:
    with pytest.raises(CacheError, match="cannot read palette file"):
        load_palette(tmp_path / "none.npz")


def _perturbed(gains: ControllerGains, rel: float) -> ControllerGains:
    """The same design with every gain scaled by (1 + rel)."""
    return dataclasses.replace(gains, lqr=gains.lqr * (1.0 + rel))


def test_key_hashes_inputs_not_computed_gains() -> None:
    params = BallbotParams()
    gains = design_gains(params)
    options = VerificationOptions()
    key = palette_key(params, gains, options, 0.5)
    # the designed gains are an output: noise in them must not change the key
    assert palette_key(params, _perturbed(gains, 1e-6), options, 0.5) == key
    # every design input does
    other_weights = design_gains(params, LQRWeights(position=201.0))
    assert palette_key(params, other_weights, options, 0.5) != key
    assert (
        palette_key(params, design_gains(params, friction_compensation=False), options, 0.5) != key
    )
    assert palette_key(params, design_gains(params, friction_midpoint=True), options, 0.5) != key
    heavier = dataclasses.replace(params, body_mass=60.0)
    assert palette_key(heavier, gains, options, 0.5) != key
    assert palette_key(params, gains, VerificationOptions(boundary_points=65), 0.5) != key
    assert palette_key(params, gains, options, 0.25) != key


def test_shipped_key_is_recomputed_from_its_header() -> None:
    path = shipped_palette_path()
    with np.load(path, allow_pickle=False) as z:
        header = json.loads(z["header"].tobytes().decode())
    gp = header["gains"]
    gains = ControllerGains(
        lqr=np.asarray(gp["lqr"]),
        params=BallbotParams.from_dict(gp["params"]),
        max_lean_compensation=gp["max_lean_compensation"],
        friction_compensation=gp["friction_compensation"],
        weights=LQRWeights(**gp["weights"]),
    )
    recomputed = palette_key(
        BallbotParams.from_dict(header["params"]),
        gains,
        VerificationOptions(**header["options"]),
        header["d"],
        PrimitiveSetOptions.from_dict(header["primitive_options"]),
    )
    assert header["key"] == recomputed
    # and the shipped palette is the one this version's defaults ask for
    limits = PaletteLimits()
    assert recomputed == palette_key(
        BallbotParams(),
        design_gains(),
        limits.verification_options(),
        0.5,
        limits.primitive_options(),
    )


@pytest.mark.parametrize("forced", [False, True])
def test_floating_point_noise_in_gains_is_accepted(forced: bool) -> None:
    """Gains redesigned on another numpy/scipy build differ by ~1e-14: still the palette."""
    gains = _perturbed(design_gains(), 1e-12)
    path = shipped_palette_path() if forced else None
    pal = load_palette(path, gains=gains, build=False)
    assert pal.key == load_palette(build=False).key
    assert pal.gains.relative_difference(gains) == pytest.approx(1e-12, rel=1e-3)


def test_real_change_of_gains_is_refused_with_what_differs() -> None:
    gains = _perturbed(design_gains(), 1e-6)
    with pytest.raises(
        CacheError, match=r"gains differ .* by a relative 1\.0e-06 \(tolerance 1e-08\)"
    ):
        load_palette(shipped_palette_path(), gains=gains)
    with pytest.raises(CacheError, match="no palette matches"):
        load_palette(gains=gains, build=False)


def test_forced_file_for_other_inputs_says_what_differs(monkeypatch, tmp_path) -> None:
    heavier = dataclasses.replace(BallbotParams(), body_mass=60.0)
    with pytest.raises(CacheError, match=r"robot parameter body_mass: 51\.66 in the file, 60\.0"):
        load_palette(shipped_palette_path(), params=heavier)
    with pytest.raises(CacheError, match=r"verification option goal_position_extent: 0\.08"):
        load_palette(shipped_palette_path(), options=VerificationOptions(goal_position_extent=0.05))
    nonic = PaletteLimits(reference="nonic", max_ball_jerk=6.0, shift_max_ball_jerk=12.0)
    with pytest.raises(
        CacheError, match=r"option reference: 'limited' in the file, the default requested"
    ):
        load_palette(shipped_palette_path(), limits=nonic)
    assert load_palette("nonic", limits=nonic).key == load_palette("nonic").key
    # Not forced, the shipped palette built to the requested limits is found.
    assert load_palette(limits=nonic, build=False).key == load_palette("nonic").key
    # $GRACENAV_PALETTE forces a file like --palette does
    monkeypatch.setenv(PALETTE_ENV, str(shipped_palette_path()))
    with pytest.raises(CacheError, match="cannot be used"):
        load_palette(params=heavier)
    monkeypatch.setenv(PALETTE_ENV, str(tmp_path / "missing.npz"))
    with pytest.raises(CacheError, match="cannot read palette file"):
        load_palette()


def test_mismatch_is_rebuilt_once_then_cached_and_corrupt_cache_rebuilt(
    monkeypatch, tmp_path
) -> None:
    """The rebuild path, with the (slow) build replaced by a relabelled shipped palette."""
    monkeypatch.setenv("GRACENAV_CACHE_DIR", str(tmp_path))
    shipped = load_palette(build=False)
    heavier = dataclasses.replace(BallbotParams(), body_mass=52.0)
    builds: list[float] = []

    def fake_build(*, params, gains, options, d, processes, progress, primitive_options):  # type: ignore[no-untyped-def]
        builds.append(params.body_mass)
        return dataclasses.replace(
            shipped,
            policies=tuple(dataclasses.replace(p, gains=gains) for p in shipped.policies),
            params=params,
            key=palette_key(params, gains, options, d, primitive_options),
        )

    monkeypatch.setattr(palette_module, "build_palette_for", fake_build)
    first = load_palette(params=heavier)
    assert builds == [52.0] and first.params.body_mass == 52.0
    cached = cached_palette_path(first.key)
    assert cached.is_file() and [p.name for p in tmp_path.iterdir()] == [cached.name]
    again = load_palette(params=heavier)
    assert builds == [52.0] and again.key == first.key  # read from the cache
    cached.write_bytes(cached.read_bytes()[:5000])  # corrupt it
    load_palette(params=heavier)
    assert builds == [52.0, 52.0]
    assert load_palette(params=heavier).key == first.key and len(builds) == 2
    with pytest.raises(CacheError, match="no palette matches"):
        load_palette(params=dataclasses.replace(heavier, body_mass=53.0), build=False)


@pytest.mark.slow
def test_real_rebuild_for_other_parameters(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("GRACENAV_CACHE_DIR", str(tmp_path))
    heavier = dataclasses.replace(BallbotParams(), body_mass=53.0)
    # Without the scale ladder and the catches, and with the nonics (planned in about 2 s
    # where the default palette's references take 25 s): the rebuild path is the same,
    # at a fraction of the cost.
    options = VerificationOptions(scale_ladder=(), catch=None)
    nonic = PaletteLimits(reference="nonic", max_ball_jerk=6.0, shift_max_ball_jerk=12.0)
    pal = load_palette(params=heavier, options=options, limits=nonic, progress=False)
    assert len(pal) >= 35 and pal.params == heavier and pal.options == options
    assert pal.primitive_options == nonic.primitive_options()
    assert all(p.report is not None and p.report.passed for p in pal.policies)
    assert cached_palette_path(pal.key).is_file()
    # Read from the cache (build=False; bench/bench_palette.py times a palette read).
    again = load_palette(params=heavier, options=options, limits=nonic, build=False)
    with pytest.raises(CacheError, match="no palette matches"):
        load_palette(params=heavier, options=options, build=False)  # the default limits
    assert again.names == pal.names
    np.testing.assert_array_equal(again.gains.lqr, pal.gains.lqr)


def test_edited_content_is_detected(tmp_path) -> None:
    pal = load_palette()
    edited = dataclasses.replace(pal, d=0.25)  # content no longer matches its key
    path = edited.save(tmp_path / "edited.npz")
    with pytest.raises(CacheError, match="does not match the inputs stored in it"):
        load_palette(path)


def test_atomic_save_leaves_no_temporary_files(tmp_path) -> None:
    pal = load_palette()
    pal.save(tmp_path / "a.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]
    assert isinstance(Palette.from_bytes((tmp_path / "a.npz").read_bytes()), Palette)


def test_forced_file_defaults_to_what_it_was_built_for(tmp_path) -> None:
    """A palette built for another robot, forced by path, loads without restating that
    robot; its gains are still designed anew and compared."""
    shipped = load_palette(build=False)
    heavier = dataclasses.replace(BallbotParams(), body_mass=52.0)
    gains = design_gains(heavier)
    options = shipped.options
    other = dataclasses.replace(
        shipped,
        policies=tuple(dataclasses.replace(p, gains=gains) for p in shipped.policies),
        params=heavier,
        key=palette_key(heavier, gains, options, shipped.d, shipped.primitive_options),
    )
    path = other.save(tmp_path / "heavier.npz")
    pal = load_palette(path)
    assert pal.params == heavier and pal.key == other.key
    assert load_palette(path, params=heavier).key == other.key
    with pytest.raises(CacheError, match=r"body_mass: 52\.0 in the file, 51\.66 requested"):
        load_palette(path, params=BallbotParams())
    noisy = dataclasses.replace(other.gains, lqr=other.gains.lqr * (1 + 1e-6))
    edited = dataclasses.replace(
        other, policies=tuple(dataclasses.replace(p, gains=noisy) for p in other.policies)
    )
    with pytest.raises(CacheError, match=r"gains differ .* relative 1\.0e-06"):
        load_palette(edited.save(tmp_path / "edited.npz"))


def test_stored_members_are_the_zip_members_and_compressed_ones_are_refused() -> None:
    """The one-pass reader returns every member's bytes exactly as zipfile reads them
    (an independent reader, which checks each CRC itself), and refuses what
    ``np.savez`` never writes."""
    import io
    import zipfile

    from gracenav.palette.palette import _stored_members

    data = shipped_palette_path().read_bytes()
    members = _stored_members(data)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert sorted(members) == sorted(archive.namelist())
        for name in archive.namelist():
            assert bytes(members[name]) == archive.read(name)
    buf = io.BytesIO()
    np.savez_compressed(buf, a=np.arange(10.0))
    with pytest.raises(ValueError, match="compressed"):
        _stored_members(buf.getvalue())


def test_palette_limits_give_the_default_options_and_read_back_the_shipped_palette() -> None:
    import dataclasses
    import math

    from gracenav.errors import ConfigError
    from gracenav.palette import PaletteLimits, load_palette
    from gracenav.policies import VerificationOptions
    from gracenav.primitives import PrimitiveSetOptions

    limits = PaletteLimits()
    # The default palette's maneuvers are limited references within 3 m/s³ of ball jerk,
    # and so are its shifts; the nonic palette's limits are the options' own defaults.
    assert limits.primitive_options() == PrimitiveSetOptions(reference="limited", max_ball_jerk=3.0)
    base = VerificationOptions()
    assert base.catch is not None
    assert limits.verification_options() == dataclasses.replace(
        base, catch=dataclasses.replace(base.catch, shift_max_ball_jerk=3.0)
    )
    nonic = PaletteLimits(reference="nonic", max_ball_jerk=6.0, shift_max_ball_jerk=12.0)
    assert nonic.primitive_options() == PrimitiveSetOptions()
    assert nonic.verification_options() == base
    assert PaletteLimits.of(load_palette()) == limits
    fast = PaletteLimits(cruise_speeds=(0.5, 1.0, 1.2), max_speed=1.35, reference="limited")
    prim = fast.primitive_options()
    assert (prim.cruise_speed, prim.cruise_speeds, prim.reference) == (0.5, (1.0, 1.2), "limited")
    slower = dataclasses.replace(limits, max_lean=math.radians(4.0))
    catch = slower.verification_options().catch
    assert catch is not None and catch.max_lean == pytest.approx(math.radians(4.0), abs=1e-15)
    assert slower.primitive_options().max_lean == pytest.approx(math.radians(4.0), abs=1e-15)
    text = limits.describe(60.0)
    assert "lean 4.5° planned, 8° verified" in text and "torque 60 N m" in text
    with pytest.raises(ConfigError, match="below verified_lean"):
        PaletteLimits(max_lean=math.radians(9.0))
    with pytest.raises(ConfigError, match="ascending"):
        PaletteLimits(cruise_speeds=(0.5, 0.4))


def test_catches_reach_past_the_top_cruise_speed() -> None:
    """A palette with speed levels gets catches up to 0.3 m/s above its top cruise
    speed (a 16 N s push adds about 0.35 m/s; a catch serves 0.16 m/s around its own),
    in the default steps; the one-speed palette keeps the default catches."""
    from gracenav.palette import PaletteLimits, catch_speeds_for
    from gracenav.palette.limits import CATCH_HEADROOM
    from gracenav.policies import CatchOptions

    assert catch_speeds_for((0.5,)) == CatchOptions().speeds
    fast = catch_speeds_for((0.5, 1.0, 1.2))
    assert fast[: len(CatchOptions().speeds)] == CatchOptions().speeds
    assert fast[-1] == pytest.approx(1.2 + CATCH_HEADROOM, abs=1e-9)
    assert np.allclose(np.diff(fast), 0.1)
    limits = PaletteLimits(cruise_speeds=(0.5, 1.0, 1.2), max_speed=1.32, catch_speeds=fast)
    catch = limits.verification_options().catch
    assert catch is not None and catch.speeds == fast
    assert "catches from up to 1.5 m/s" in limits.describe(60.0)
    from gracenav.errors import ConfigError

    with pytest.raises(ConfigError, match="finite"):
        catch_speeds_for((0.5, float("inf")))


def _shipped_as_built(
    name: str, limits: PaletteLimits, *, friction_midpoint: bool = False
) -> Palette:
    """The shipped palette ``name``, checked to be what `gracenav palette build` writes for
    ``limits`` on the CMU robot with its designed gains (the key of those inputs; with
    ``friction_midpoint``, the gains of ``--friction-midpoint``), and that every policy
    it keeps passed verification."""
    from gracenav.palette import palette_file

    params = BallbotParams()
    pal = load_palette(name)
    assert palette_file(name) == shipped_palette_path(name)
    assert (shipped_palette_path(name) == shipped_palette_path()) == (name == "gentle")
    gains = design_gains(params, friction_midpoint=friction_midpoint)
    assert pal.gains.friction_midpoint == friction_midpoint
    assert pal.key == palette_key(
        params, gains, limits.verification_options(), 0.5, limits.primitive_options()
    )
    assert PaletteLimits.of(pal) == limits
    kept = (*pal.policies, *pal.catches, *pal.shifts)
    assert all(p.report is not None and p.report.passed for p in kept)
    return pal


def test_the_speed_palette_is_shipped_and_is_what_its_build_command_asks_for() -> None:
    """`--palette speed` is the file `gracenav palette build --cruise-speeds 1.0 1.2
    --max-ball-jerk 6 --shift-max-ball-jerk 12` writes: its key is that of the command's inputs (the
    CMU robot, its designed gains, the command's limits), so it is reproducible; every
    policy it keeps passed verification and it carries the three levels."""
    from gracenav.palette import catch_speeds_for

    speeds = (0.5, 1.0, 1.2)
    limits = PaletteLimits(
        cruise_speeds=speeds,
        catch_speeds=catch_speeds_for(speeds),
        max_speed=max(0.8, 1.1 * speeds[-1]),
        max_ball_jerk=6.0,
        shift_max_ball_jerk=12.0,
    )
    pal = _shipped_as_built("speed", limits)
    for name in ("cruise2_x", "cruise3_xy", "rest_to_cruise2_x_3_0"):
        assert name in pal.names, name
    assert "catch_1.3[pushed,S=1G]" in {c.label for c in pal.catches}
    assert pal.key != load_palette().key and len(pal.policies) > len(load_palette().policies)


def _maneuvers(p: Palette) -> dict[str, SampledPrimitive]:
    """The palette's maneuvers by name (no larger-domain variants, fine copies or
    captures)."""
    return {
        q.primitive.name: q.primitive
        for q in p.policies
        if q.primitive.kind is PrimitiveKind.MANEUVER and not q.label and not q.capture
    }


def _ball_jerk(prim: SampledPrimitive) -> float:
    """Largest ball jerk of a maneuver's 3D plan, differentiated as the run summaries do."""
    return planned_jerk(prim.position[:, 2:4], prim.dt)


def test_the_smooth_palette_is_shipped_and_is_what_its_build_command_asks_for() -> None:
    """`--palette smooth` is the file `gracenav palette build --max-ball-jerk 2
    --shift-max-ball-jerk 2` writes (its key is that of the command's inputs); every
    policy it keeps passed verification; it has the nonic palette's 36 maneuvers, whose
    3D plans keep the ball's jerk (differentiated as the run summaries do, with the trims
    around each) within 2 m/s³ to 1 % (measured: 1.99-2.01; the nonics' reach 6.88), for
    8.5 % more of their total duration (118.375 s against 109.125 s)."""
    limits = PaletteLimits(max_ball_jerk=2.0, shift_max_ball_jerk=2.0)
    pal = _shipped_as_built("smooth", limits)
    default = load_palette("nonic")

    smooth, fast = _maneuvers(pal), _maneuvers(default)
    assert len(smooth) == 36 and set(smooth) == set(fast)
    assert max(_ball_jerk(p) for p in smooth.values()) <= 2.0 * 1.01
    assert max(_ball_jerk(p) for p in fast.values()) > 3 * 2.0
    total = sum(p.duration for p in smooth.values())
    assert (
        sum(p.duration for p in fast.values())
        < total
        <= 1.1 * sum(p.duration for p in fast.values())
    )


def test_the_calm_palette_is_shipped_and_keeps_the_tight_maneuvers_at_its_lower_speed() -> None:
    """`--palette calm` is the file `gracenav palette build --cruise-speed 0.4
    --max-ball-jerk 1.15 --shift-max-ball-jerk 1.15 --friction-midpoint` writes; every
    policy it keeps passed verification. At 0.4 m/s the one- and two-cell maneuvers
    (starts and stops over one d, the 90° turns over (d, d), the 45° turns over (2d, d))
    stay within 1.15 m/s³, which at 0.5 m/s none of them does within 1.25: the tight
    maneuvers' jerk grows with the cube of the speed. Three rest-to-rest maneuvers are
    not in it (their references within 1.15 m/s³ last longer than the palette's 4.5 s).
    Its maneuvers' 3D plans keep the ball's jerk within the bound to 1 % (measured:
    1.13-1.15)."""
    from gracenav.primitives.design import _plan_maneuver

    limits = PaletteLimits(cruise_speeds=(0.4,), max_ball_jerk=1.15, shift_max_ball_jerk=1.15)
    pal = _shipped_as_built("calm", limits, friction_midpoint=True)
    calm, nonic = _maneuvers(pal), _maneuvers(load_palette("nonic"))
    omitted = {"rest_to_rest_2_1", "rest_to_rest_1_2", "rest_to_rest_2_2"}
    assert set(calm) == set(nonic) - omitted
    assert max(_ball_jerk(p) for p in calm.values()) <= 1.15 * 1.01
    assert pal.primitive_options.cruise_speed == 0.4
    tight = [
        ("rest", "cruise_x", (1, 0)),
        ("cruise_x", "rest", (1, 0)),
        ("cruise_x", "cruise_y", (1, 1)),
        ("cruise_x", "cruise_xy", (2, 1)),
    ]
    assert {f"{a}_to_{b}_{c[0]}_{c[1]}" for a, b, c in tight} <= set(calm)
    # The same maneuvers at 0.5 m/s within 1.25 m/s³: planned, none feasible.
    faster = PaletteLimits(max_ball_jerk=1.25, shift_max_ball_jerk=1.25).primitive_options()
    for start, end, cells in tight:
        assert _plan_maneuver(start, end, cells, 0.5, BallbotParams(), faster) is None


def test_the_default_palette_is_what_the_build_command_writes_by_default() -> None:
    """The default palette (also shipped as `--palette gentle`) is the file `gracenav
    palette build` writes with its defaults, :class:`PaletteLimits` (its key is that of
    those inputs); every policy it keeps passed verification; it has the nonic
    palette's 36 maneuvers, whose 3D plans keep the ball's jerk within 3 m/s³ to 1 %
    (measured: 2.96-3.02; the nonics' reach 6.88), in at most the nonics' total duration
    (107.75 s against 109.125 s), each within 1.15 times its nonic's (measured: at most
    1.125, the 2 s lane changes taking 2.25 s)."""
    limits = PaletteLimits(reference="limited", max_ball_jerk=3.0, shift_max_ball_jerk=3.0)
    assert limits == PaletteLimits()
    pal = _shipped_as_built("gentle", limits)
    assert load_palette().key == pal.key
    nonic_palette = _shipped_as_built(
        "nonic", PaletteLimits(reference="nonic", max_ball_jerk=6.0, shift_max_ball_jerk=12.0)
    )

    gentle, nonic = _maneuvers(pal), _maneuvers(nonic_palette)
    assert len(gentle) == 36 and set(gentle) == set(nonic)
    assert max(_ball_jerk(p) for p in gentle.values()) <= 3.0 * 1.01
    assert max(_ball_jerk(p) for p in nonic.values()) > 2 * 3.0
    assert sum(p.duration for p in gentle.values()) <= sum(p.duration for p in nonic.values())
    assert all(gentle[n].duration <= 1.15 * nonic[n].duration for n in gentle)
    assert pal.key not in {load_palette(n).key for n in ("nonic", "speed", "smooth", "calm")}


def test_shipped_palettes_by_name_and_files_of_those_names(monkeypatch, tmp_path) -> None:
    from gracenav.palette import SHIPPED_PALETTES, palette_file

    assert set(SHIPPED_PALETTES) == {"default", "gentle", "nonic", "speed", "smooth", "calm"}
    assert load_palette("default").key == load_palette().key
    monkeypatch.setenv(PALETTE_ENV, "speed")
    assert load_palette().key == load_palette("speed").key
    monkeypatch.delenv(PALETTE_ENV)
    # A Path, or a string with a directory, is a file, never a shipped name.
    monkeypatch.chdir(tmp_path)
    assert palette_file("./speed") == Path("speed") != shipped_palette_path("speed")
    with pytest.raises(CacheError, match="cannot read palette file speed"):
        load_palette(Path("speed"))
    with pytest.raises(CacheError, match="shipped: default, gentle, nonic, speed, smooth, calm"):
        shipped_palette_path("fast")


@pytest.mark.parametrize("name", ["default", "nonic", "speed", "smooth", "calm"])
def test_policies_that_start_at_rest_were_verified_from_the_still_band(name: str) -> None:
    """Every kept policy that starts at rest, other than the rest trims and the capture
    regulators, carries its verification from the corners of the still band at both
    placements (the hybrid controller starts it from a hold only when it passed); the
    others carry none. The maneuvers from rest sized by bisection all pass."""
    pal = load_palette(name)
    at_rest = [
        p
        for p in pal.policies
        if not p.capture
        and p.primitive.kind is not PrimitiveKind.REST
        and not np.any(p.primitive.start_velocity != 0.0)
    ]
    assert at_rest
    others = [p for p in pal.policies if all(p is not q for q in at_rest)]
    assert all(p.still_report is not None and p.still_report.runs > 0 for p in at_rest)
    assert all(p.still_report is None and not p.starts_from_still_band for p in others)
    for p in at_rest:
        assert p.starts_from_still_band == p.still_report.passed
    base = [p for p in at_rest if not p.label]
    assert base and all(p.starts_from_still_band for p in base)


def test_the_controllers_friction_feed_forward_is_kept_in_the_file() -> None:
    """A palette whose controller feeds friction forward at the mid-period rate reads back
    with it (and its key, a design input set); the shipped files, written before the
    option, read as the measured rate's."""
    shipped = load_palette("smooth")
    assert not shipped.gains.friction_midpoint
    gains = dataclasses.replace(shipped.gains, friction_midpoint=True)
    policies = tuple(dataclasses.replace(p, gains=gains) for p in shipped.policies)
    midpoint = dataclasses.replace(shipped, policies=policies)
    back = Palette.from_bytes(midpoint.to_bytes())
    assert back.gains.friction_midpoint and back.gains.friction_compensation
    assert all(p.gains.friction_midpoint for p in back.policies)
    assert back.gains.design_inputs() == gains.design_inputs() != shipped.gains.design_inputs()
