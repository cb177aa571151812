"""The palette file: round trip, integrity, keys, atomic writes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gracenav import BallbotParams, CacheError
from gracenav.palette import Palette, load_palette, shipped_palette_path
from gracenav.policies import VerificationOptions


def test_shipped_palette_loads_and_round_trips(tmp_path) -> None:
    pal = load_palette()
    path = pal.save(tmp_path / "p.npz")
    again = load_palette(path)
    assert again.names == pal.names
    assert again.key == pal.key
    for a, b in zip(pal.policies, again.policies, strict=True):
        np.testing.assert_array_equal(a.primitive.states, b.primitive.states)
        assert a.report == b.report and a.start_radii == b.start_radii


def test_corrupt_file_is_refused(tmp_path) -> None:
    data = bytearray(shipped_palette_path().read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = b"\0" * 64
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


def test_mismatched_parameters_are_refused() -> None:
    heavier = dataclasses.replace(BallbotParams(), body_mass=60.0)
    with pytest.raises(CacheError, match="built for other robot parameters"):
        load_palette(params=heavier)
    with pytest.raises(CacheError, match="built for other"):
        load_palette(options=VerificationOptions(goal_position_extent=0.05))


def test_edited_content_is_detected(tmp_path) -> None:
    pal = load_palette()
    edited = dataclasses.replace(pal, d=0.25)  # content no longer matches its key
    path = edited.save(tmp_path / "edited.npz")
    with pytest.raises(CacheError, match="does not match its content"):
        load_palette(path)


def test_atomic_save_leaves_no_temporary_files(tmp_path) -> None:
    pal = load_palette()
    pal.save(tmp_path / "a.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]
    assert isinstance(Palette.from_bytes((tmp_path / "a.npz").read_bytes()), Palette)
