"""Maps: ROS map_server and inline-geometry loading, rasterisation, clearance, errors."""

from __future__ import annotations

import io
import json
import math
import struct
import tempfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from gracenav import ConfigError, MapError
from gracenav.world import (
    DEFAULT_RESOLUTION,
    Circle,
    Polygon,
    Rectangle,
    Shape,
    WorldMap,
    load_map,
    office_map,
    save_ros_map,
)

DATA = Path(__file__).parent / "data" / "maps"
EXAMPLES = Path(__file__).parent.parent / "examples" / "maps"


# ----------------------------------------------------------------------------------------
# Independent writers (not the module's) for PGM, PNG and map YAML
# ----------------------------------------------------------------------------------------


def pgm_bytes(img: np.ndarray, maxval: int = 255, *, binary: bool = True) -> bytes:
    h, w = img.shape
    head = f"{'P5' if binary else 'P2'}\n# test image\n{w} {h}\n# comment\n{maxval}\n"
    if binary:
        return head.encode() + img.astype(">u2" if maxval > 255 else np.uint8).tobytes()
    rows = "\n".join(" ".join(str(int(v)) for v in r) + " # row" for r in img)
    return head.encode() + rows.encode() + b"\n"


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png_bytes(
    img: np.ndarray,
    bits: int = 8,
    color: int = 0,
    *,
    filters: np.ndarray | None = None,
    palette: np.ndarray | None = None,
    interlace: int = 0,
) -> bytes:
    """A PNG of ``img`` (h, w) or (h, w, channels) with the given per-row filter types."""
    h, w = img.shape[:2]
    flat = np.asarray(img, dtype=np.int64).reshape(h, -1)
    if bits == 16:
        raw = flat.astype(">u2").view(np.uint8).reshape(h, -1).astype(np.int64)
    elif bits == 8:
        raw = flat
    else:  # pack several samples per byte, most significant first
        per = 8 // bits
        pad = (-flat.shape[1]) % per
        f = np.pad(flat, ((0, 0), (0, pad))).reshape(h, -1, per)
        raw = np.zeros(f.shape[:2], dtype=np.int64)
        for k in range(per):
            raw |= f[:, :, k] << (bits * (per - 1 - k))
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[color]
    bpp = max(1, bits * channels // 8)
    a = np.zeros_like(raw)
    a[:, bpp:] = raw[:, :-bpp]
    b = np.zeros_like(raw)
    b[1:] = raw[:-1]
    c = np.zeros_like(raw)
    c[1:, bpp:] = raw[:-1, :-bpp]
    p = a + b - c
    pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
    paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
    preds = [np.zeros_like(raw), a, b, (a + b) // 2, paeth]
    ftype = np.zeros(h, dtype=np.int64) if filters is None else np.asarray(filters)
    out = b""
    for r in range(h):
        row = (raw[r] - preds[ftype[r]][r]) % 256
        out += bytes([int(ftype[r])]) + row.astype(np.uint8).tobytes()
    ihdr = struct.pack(">IIBBBBB", w, h, bits, color, 0, 0, interlace)
    chunks = _chunk(b"IHDR", ihdr)
    if palette is not None:
        chunks += _chunk(b"PLTE", np.asarray(palette, dtype=np.uint8).tobytes())
    return (
        b"\x89PNG\r\n\x1a\n" + chunks + _chunk(b"IDAT", zlib.compress(out)) + _chunk(b"IEND", b"")
    )


def ros_yaml(
    folder: Path,
    image: str,
    *,
    name: str = "map.yaml",
    resolution: Any = 0.05,
    origin: Any = (0.0, 0.0, 0.0),
    negate: Any = 0,
    occupied_thresh: Any = 0.65,
    free_thresh: Any = 0.196,
    extra: str = "",
) -> Path:
    path = folder / name
    o = ", ".join(str(v) for v in origin) if isinstance(origin, tuple) else origin
    path.write_text(
        f"image: {image}\nresolution: {resolution}\norigin: [{o}]\nnegate: {negate}\n"
        f"occupied_thresh: {occupied_thresh}\nfree_thresh: {free_thresh}\n{extra}"
    )
    return path


def ros_map(folder: Path, image_bytes: bytes, suffix: str = ".pgm", **yaml_kw: Any) -> Path:
    (folder / f"img{suffix}").write_bytes(image_bytes)
    return ros_yaml(folder, f"img{suffix}", **yaml_kw)


def grid_image(occupied: np.ndarray) -> np.ndarray:
    """Image (row 0 on top) of a grid (row 0 at the lowest y): black occupied, white free."""
    return np.where(occupied, 0, 254)[::-1]


# ----------------------------------------------------------------------------------------
# ROS map_server maps
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("binary", [True, False])
def test_ros_round_trip_cells_and_origin(tmp_path: Path, binary: bool) -> None:
    rng = np.random.default_rng(1)
    grid = rng.random((7, 11)) < 0.3
    path = ros_map(tmp_path, pgm_bytes(grid_image(grid), binary=binary), origin=(1.5, -2.25, 0.0))
    m = load_map(path)
    np.testing.assert_array_equal(m.occupied, grid)
    np.testing.assert_allclose(m.origin, [1.5, -2.25], rtol=0, atol=0)
    assert m.resolution == 0.05
    assert m.grid_shape == (7, 11)
    (x0, y0), (x1, y1) = m.bounds
    assert (x0, y0) == (1.5, -2.25)
    assert x1 == pytest.approx(1.5 + 11 * 0.05, abs=1e-12)
    assert y1 == pytest.approx(-2.25 + 7 * 0.05, abs=1e-12)
    assert m.name == "map" and m.source == str(path)
    assert m.shapes is None
    assert not np.any(m.unknown)


def test_image_path_is_relative_to_yaml_and_may_be_absolute(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "a.pgm").write_bytes(pgm_bytes(np.full((2, 3), 254)))
    m = load_map(ros_yaml(tmp_path, "sub/a.pgm"))
    assert m.grid_shape == (2, 3) and not m.occupied.any()
    other = tmp_path / "elsewhere"
    other.mkdir()
    m2 = load_map(ros_yaml(other, str(tmp_path / "sub" / "a.pgm")))
    assert m2.grid_shape == (2, 3)


def test_flip_top_of_image_is_large_y(tmp_path: Path) -> None:
    img = np.full((10, 4), 254)
    img[0, :] = 0  # top row of the image
    m = load_map(ros_map(tmp_path, pgm_bytes(img), origin=(0.0, 0.0, 0.0)))
    assert m.occupied[-1].all() and not m.occupied[:-1].any()
    assert not m.is_free([0.1, 0.49])  # top cell row spans y in [0.45, 0.5)
    assert m.is_free([0.1, 0.01])


# Pixel values around the thresholds 0.65 / 0.196 (p = (255 − v) / 255):
# 89 -> 0.651 occupied, 90 -> 0.647 unknown, 205 -> 0.19608 unknown, 206 -> 0.192 free.
LEVELS = np.array([[0, 89, 90, 100, 205, 206, 254, 255]])


@pytest.mark.parametrize(
    ("negate", "mode", "occupied", "unknown"),
    [
        (0, None, [1, 1, 1, 1, 1, 0, 0, 0], [0, 0, 1, 1, 1, 0, 0, 0]),
        (0, "trinary", [1, 1, 1, 1, 1, 0, 0, 0], [0, 0, 1, 1, 1, 0, 0, 0]),
        (0, "scale", [1, 1, 1, 1, 1, 0, 0, 0], [0, 0, 1, 1, 1, 0, 0, 0]),
        # negate: p = v / 255; free below 0.196 (v <= 49), occupied above 0.65 (v >= 166)
        (1, None, [0, 1, 1, 1, 1, 1, 1, 1], [0, 1, 1, 1, 0, 0, 0, 0]),
        # raw: the (negated) gray level is the cell value; only 0 is free
        (0, "raw", [0, 1, 1, 1, 1, 1, 1, 1], [0] * 8),
        (1, "raw", [1, 1, 1, 1, 1, 1, 1, 0], [0] * 8),
    ],
)
def test_map_server_threshold_semantics(
    tmp_path: Path, negate: int, mode: str | None, occupied: list[int], unknown: list[int]
) -> None:
    extra = f"mode: {mode}\n" if mode else ""
    m = load_map(ros_map(tmp_path, pgm_bytes(LEVELS), negate=negate, extra=extra))
    np.testing.assert_array_equal(m.occupied[0], np.array(occupied, dtype=bool))
    assert m.unknown is not None
    np.testing.assert_array_equal(m.unknown[0], np.array(unknown, dtype=bool))


def test_thresholds_are_strict_inequalities(tmp_path: Path) -> None:
    # v = 102: p = 153/255 = 0.6 exactly -> not > 0.6: unknown.
    # v = 204: p = 51/255 = 0.2 exactly -> not < 0.2: unknown.
    img = np.array([[101, 102, 203, 204, 205]])
    m = load_map(ros_map(tmp_path, pgm_bytes(img), occupied_thresh=0.6, free_thresh=0.2))
    assert m.unknown is not None
    np.testing.assert_array_equal(m.unknown[0], [False, True, True, True, False])
    np.testing.assert_array_equal(m.occupied[0], [True, True, True, True, False])


def test_sixteen_bit_pgm_uses_maxval(tmp_path: Path) -> None:
    img = np.array([[0, 20000, 60000, 65535]])  # p = 1, 0.695, 0.0845, 0
    for binary in (True, False):
        m = load_map(ros_map(tmp_path, pgm_bytes(img, 65535, binary=binary)))
        np.testing.assert_array_equal(m.occupied[0], [True, True, False, False])
    # a maxval other than 255 scales the same way: 40/100 -> p = 0.6, unknown
    m = load_map(ros_map(tmp_path, pgm_bytes(np.array([[0, 40, 100]]), 100)))
    np.testing.assert_array_equal(m.occupied[0], [True, True, False])
    assert m.unknown is not None and m.unknown[0].tolist() == [False, True, False]


def test_png_gray_colour_alpha_palette(tmp_path: Path) -> None:
    gray = LEVELS
    expect = np.array([1, 1, 1, 1, 1, 0, 0, 0], dtype=bool)
    m = load_map(ros_map(tmp_path, png_bytes(gray), ".png"))
    np.testing.assert_array_equal(m.occupied[0], expect)
    m = load_map(ros_map(tmp_path, png_bytes(gray * 257, bits=16), ".png"))
    np.testing.assert_array_equal(m.occupied[0], expect)
    rgb = np.repeat(gray[..., None], 3, axis=2)
    m = load_map(ros_map(tmp_path, png_bytes(rgb, color=2), ".png"))
    np.testing.assert_array_equal(m.occupied[0], expect)
    # colour channels are averaged: (255 + 255 + 0) / 3 = 170 -> p = 0.333: unknown
    m = load_map(ros_map(tmp_path, png_bytes(np.array([[[255, 255, 0]]]), color=2), ".png"))
    assert m.unknown is not None and m.unknown[0, 0]
    # trinary mode averages opacity in (as map_server); other modes ignore it
    rgba = np.array([[[255, 255, 255, 0], [255, 255, 255, 255]]])
    m = load_map(ros_map(tmp_path, png_bytes(rgba, color=6), ".png"))
    np.testing.assert_array_equal(m.occupied[0], [True, False])  # mean 191.25: p = 0.25
    m = load_map(ros_map(tmp_path, png_bytes(rgba, color=6), ".png", extra="mode: scale\n"))
    np.testing.assert_array_equal(m.occupied[0], [False, False])
    ga = np.array([[[254, 255], [0, 255], [254, 0]]])
    m = load_map(ros_map(tmp_path, png_bytes(ga, color=4), ".png"))
    np.testing.assert_array_equal(m.occupied[0], [False, True, True])
    pal = np.array([[0, 0, 0], [254, 254, 254], [128, 128, 128]])
    m = load_map(
        ros_map(tmp_path, png_bytes(np.array([[1, 0, 2, 1]]), color=3, palette=pal), ".png")
    )
    np.testing.assert_array_equal(m.occupied[0], [False, True, True, False])
    for bits in (1, 2, 4):
        top = (1 << bits) - 1
        m = load_map(ros_map(tmp_path, png_bytes(np.array([[0, top, 0, top, top]]), bits), ".png"))
        np.testing.assert_array_equal(m.occupied[0], [True, False, True, False, False])


@pytest.mark.parametrize(("bits", "color"), [(8, 0), (16, 0), (8, 2), (16, 6), (8, 4), (4, 0)])
def test_png_decoder_undoes_every_row_filter(tmp_path: Path, bits: int, color: int) -> None:
    from gracenav.world.ros_map import _decode_image as _decode_png

    rng = np.random.default_rng(bits * 10 + color)
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[color]
    img = rng.integers(0, 1 << bits, size=(23, 17, channels))
    filters = rng.integers(0, 5, size=23)
    pixels, maxval, alpha = _decode_png(png_bytes(img, bits, color, filters=filters), "test")
    if bits == 16 and color != 0:  # Pillow keeps 8 bits per colour channel (the high byte)
        np.testing.assert_array_equal(pixels, img >> 8)
        assert maxval == 255
    elif bits < 8:  # 2- and 4-bit gray come back scaled to 0..255 (exactly: 17 · v)
        np.testing.assert_array_equal(pixels, img * (255 // ((1 << bits) - 1)))
        assert maxval == 255
    else:
        np.testing.assert_array_equal(pixels, img)
        assert maxval == (1 << bits) - 1
    assert alpha == (color in (4, 6))


def test_png_written_by_matplotlib_decodes_exactly() -> None:
    import matplotlib.image as mpimg

    from gracenav.world.ros_map import _decode_image as _decode_png

    rng = np.random.default_rng(3)
    rgba = rng.integers(0, 256, size=(31, 29, 4)).astype(np.uint8)
    rgba[..., 3] = 255
    buf = io.BytesIO()
    mpimg.imsave(buf, rgba, format="png")
    pixels, maxval, _ = _decode_png(buf.getvalue(), "test")
    assert maxval == 255
    np.testing.assert_array_equal(pixels[..., :3], rgba[..., :3])


def test_committed_test_maps_and_examples_load() -> None:
    p2 = load_map(DATA / "tiny_p2.yaml")
    p5 = load_map(DATA / "tiny_p5.yaml")
    png = load_map(DATA / "tiny_png.yaml")
    for m in (p2, p5, png):
        np.testing.assert_array_equal(m.occupied, p2.occupied)
        np.testing.assert_allclose(m.origin, [-1.0, 0.5], rtol=0, atol=1e-12)
    assert p2.occupied[-1, 0] and not p2.occupied[0, 0]  # top-left image pixel is black
    free = load_map(EXAMPLES / "free_area_3p5m.yaml")
    assert free.bounds == ((0.0, 0.0), (3.5, 3.5)) and not free.occupied.any()
    fig5 = load_map(EXAMPLES / "fig5_two_obstacles.yaml")
    assert fig5.width == pytest.approx(3.0, abs=1e-12) and len(fig5.shapes or ()) == 2
    assert fig5.is_free([2.0, 2.0]) and not fig5.is_free([1.0, 1.25])
    lab = load_map(EXAMPLES / "lab_ros.yaml")
    assert lab.unknown is not None and lab.unknown.any()
    assert lab.is_free([1.5, 1.0]) and not lab.is_free([-0.25, -0.25])


def test_save_ros_map_round_trip(tmp_path: Path) -> None:
    m = office_map(20.0, 0.1, seed=4)
    unknown = np.zeros(m.grid_shape, dtype=bool)
    unknown[:3, :] = True
    m = WorldMap(
        m.origin + np.array([2.0, -1.0]), m.resolution, m.occupied | unknown, unknown=unknown
    )
    for image_format in ("pgm", "png"):
        image = save_ros_map(m, tmp_path / "saved.yaml", image_format=image_format)
        assert image == tmp_path / f"saved.{image_format}"
        back = load_map(tmp_path / "saved.yaml")
        np.testing.assert_array_equal(back.occupied, m.occupied)
        assert back.unknown is not None
        np.testing.assert_array_equal(back.unknown, unknown)
        np.testing.assert_allclose(back.origin, m.origin, rtol=0, atol=0)
        assert back.resolution == m.resolution


# ----------------------------------------------------------------------------------------
# Inline geometry
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("res", [0.05, 0.1])
def test_rasterise_rectangle(res: float) -> None:
    r = {"min": [0.33, 1.07], "max": [2.61, 1.98]}
    m = load_map({"bounds": [[0, 0], [3, 3]], "obstacles": [{"rectangle": r}], "resolution": res})
    c = m.cell_centers()
    expect = (c[..., 0] >= 0.33) & (c[..., 0] <= 2.61) & (c[..., 1] >= 1.07) & (c[..., 1] <= 1.98)
    np.testing.assert_array_equal(m.occupied, expect)
    area = (2.61 - 0.33) * (1.98 - 1.07)
    perimeter = 2 * ((2.61 - 0.33) + (1.98 - 1.07))
    assert abs(m.occupied.sum() * res**2 - area) <= perimeter * res / 2
    assert m.shapes == (Rectangle((0.33, 1.07), (2.61, 1.98)),)


@pytest.mark.parametrize("res", [0.02, 0.05])
def test_rasterise_circle(res: float) -> None:
    m = load_map(
        {
            "bounds": [[-2, -2], [2, 2]],
            "obstacles": [{"circle": {"center": [0.13, -0.21], "radius": 1.37}}],
            "resolution": res,
        }
    )
    c = m.cell_centers()
    expect = np.hypot(c[..., 0] - 0.13, c[..., 1] + 0.21) <= 1.37
    np.testing.assert_array_equal(m.occupied, expect)
    assert abs(m.occupied.sum() * res**2 - math.pi * 1.37**2) <= 2 * math.pi * 1.37 * res / 2
    assert m.shapes is not None and m.shapes[0].area == pytest.approx(math.pi * 1.37**2)


def test_rasterise_polygon_against_matplotlib_path() -> None:
    from matplotlib.path import Path as MplPath

    pts = [[0.21, 0.33], [2.73, 0.41], [2.52, 2.61], [1.43, 1.17], [0.38, 2.47]]  # concave
    res = 0.05
    m = load_map({"bounds": [[0, 0], [3, 3]], "obstacles": [{"polygon": {"points": pts}}]})
    expect = MplPath(pts).contains_points(m.cell_centers().reshape(-1, 2)).reshape(m.grid_shape)
    np.testing.assert_array_equal(m.occupied, expect)
    poly = Polygon(tuple(map(tuple, pts)))  # type: ignore[arg-type]
    x, y = np.array(pts).T
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert poly.area == pytest.approx(area, rel=1e-12)
    perimeter = float(np.sum(np.hypot(*(np.roll(pts, -1, axis=0) - pts).T)))
    assert abs(m.occupied.sum() * res**2 - area) <= perimeter * res / 2
    # a repeated closing vertex is accepted and dropped
    closed = Polygon((*poly.points, poly.points[0]))
    assert closed.points == poly.points


def test_inline_from_yaml_and_json_files(tmp_path: Path) -> None:
    doc = {
        "bounds": [[0, 0], [2, 1]],
        "obstacles": [{"circle": {"center": [1, 0.5], "radius": 0.3}}],
    }
    (tmp_path / "m.json").write_text(json.dumps(doc))
    (tmp_path / "m.yaml").write_text(
        "bounds: [[0, 0], [2, 1]]\nobstacles:\n  - circle: {center: [1, 0.5], radius: 0.3}\n"
    )
    ref = load_map(doc)
    assert ref.resolution == DEFAULT_RESOLUTION and ref.source == "inline map"
    for f in ("m.json", "m.yaml"):
        m = load_map(tmp_path / f)
        np.testing.assert_array_equal(m.occupied, ref.occupied)
        assert m.name == "m" and m.source == str(tmp_path / f)
    assert load_map(str(tmp_path / "m.yaml")).shapes == ref.shapes


def test_shapes_to_dict_round_trip() -> None:
    shapes: list[Shape] = [
        Rectangle((0.1, 0.2), (0.5, 0.9)),
        Circle((1.5, 1.5), 0.25),
        Polygon(((2.0, 0.2), (2.8, 0.3), (2.5, 0.9))),
    ]
    doc = {"bounds": [[0, 0], [3, 2]], "obstacles": [s.to_dict() for s in shapes]}
    assert load_map(doc).shapes == tuple(shapes)


# ----------------------------------------------------------------------------------------
# Queries: is_free, clearance
# ----------------------------------------------------------------------------------------


def test_is_free_shapes_and_outside() -> None:
    m = load_map(
        {
            "bounds": [[0, 0], [2, 2]],
            "obstacles": [{"rectangle": {"min": [0.5, 0.5], "max": [1, 1]}}],
        }
    )
    pts = np.array([[[0.75, 0.75], [0.2, 0.2]], [[-0.01, 1.0], [2.0, 1.0]]])
    free = m.is_free(pts)
    assert free.shape == (2, 2)
    np.testing.assert_array_equal(free, [[False, True], [False, False]])  # x = 2 is outside
    assert not m.is_free([np.nan, 1.0]) and not m.is_free([np.inf, 1.0])
    assert m.is_free(np.zeros((0, 2))).shape == (0,)
    with pytest.raises(ConfigError, match=r"\(\.\.\., 2\)"):
        m.is_free([1.0, 2.0, 3.0])


def _box_distance(p: np.ndarray, lo: tuple[float, float], hi: tuple[float, float]) -> np.ndarray:
    dx = np.maximum(np.maximum(lo[0] - p[..., 0], p[..., 0] - hi[0]), 0.0)
    dy = np.maximum(np.maximum(lo[1] - p[..., 1], p[..., 1] - hi[1]), 0.0)
    return np.hypot(dx, dy)


def _edge_distance(p: np.ndarray, size: float) -> np.ndarray:
    return np.minimum(
        np.minimum(p[..., 0], size - p[..., 0]), np.minimum(p[..., 1], size - p[..., 1])
    )


@pytest.mark.parametrize("res", [0.05, 0.1])
def test_clearance_circle_analytic(res: float) -> None:
    c, r, size = np.array([4.03, 5.51]), 1.27, 10.0
    m = load_map(
        {
            "bounds": [[0, 0], [size, size]],
            "obstacles": [{"circle": {"center": c.tolist(), "radius": r}}],
            "resolution": res,
        }
    )
    p = np.random.default_rng(0).uniform(0, size, size=(4000, 2))
    exact = np.maximum(np.minimum(np.hypot(*(p - c).T) - r, _edge_distance(p, size)), 0.0)
    got = m.clearance(p)
    assert got.shape == (4000,)
    np.testing.assert_allclose(got, exact, rtol=0, atol=res)
    np.testing.assert_array_equal(got[~m.is_free(p)], 0.0)
    np.testing.assert_allclose(m.clearance([[-1.0, 5.0], [5.0, 10.5]]), [0.0, 0.0], rtol=0, atol=0)
    np.testing.assert_allclose(m.clearance(c), 0.0, rtol=0, atol=0)
    grid = m.clearance_grid
    centres = m.cell_centers()
    assert grid.shape == m.grid_shape and not grid.flags.writeable
    assert np.all(m.clearance(centres) <= grid + 1e-12)
    np.testing.assert_allclose(m.clearance(centres), grid, rtol=0, atol=res)


def test_clearance_rectangle_analytic() -> None:
    lo, hi, size, res = (3.12, 2.04), (6.47, 4.93), 10.0, 0.05
    m = load_map(
        {"bounds": [[0, 0], [size, size]], "obstacles": [{"rectangle": {"min": lo, "max": hi}}]}
    )
    p = np.random.default_rng(1).uniform(0, size, size=(60, 70, 2))
    exact = np.minimum(_box_distance(p, lo, hi), _edge_distance(p, size))
    got = m.clearance(p)
    assert got.shape == (60, 70)
    np.testing.assert_allclose(got, exact, rtol=0, atol=res)


def test_clearance_of_empty_map_is_distance_to_edge() -> None:
    m = load_map({"bounds": [[-1, -1], [1, 2]], "resolution": 0.1})
    p = np.array([[0.0, 0.5], [0.93, 1.97], [-0.5, -0.2]])
    np.testing.assert_allclose(m.clearance(p), [1.0, 0.03, 0.5], rtol=0, atol=1e-12)


def test_clearance_is_cached() -> None:
    m = office_map(16.0, 0.1)
    assert m.clearance_grid is m.clearance_grid


# ----------------------------------------------------------------------------------------
# The synthetic office
# ----------------------------------------------------------------------------------------


def test_office_map_deterministic_and_sane() -> None:
    a, b, c = office_map(30.0, seed=5), office_map(30.0, seed=5), office_map(30.0, seed=6)
    np.testing.assert_array_equal(a.occupied, b.occupied)
    assert not np.array_equal(a.occupied, c.occupied)
    assert a.bounds == ((0.0, 0.0), (30.0, 30.0))
    frac = a.occupied.mean()
    assert 0.03 < frac < 0.3
    assert a.is_free([1.2, 15.0])  # the west corridor
    assert not a.is_free([0.1, 15.0])  # the outer wall
    # every free cell is reachable from the west corridor (doors, margins around furniture)
    from scipy import ndimage

    labels, _ = ndimage.label(~a.occupied)
    start = labels[int(15.0 / a.resolution), int(1.2 / a.resolution)]
    assert np.mean(labels[~a.occupied] == start) > 0.99
    with pytest.raises(ConfigError, match="size"):
        office_map(5.0)


def test_office_map_50m_loads_with_clearance() -> None:
    # Its time (well under a second) is measured by bench/bench_library.py.
    m = office_map(50.0, 0.05, seed=0)
    assert m.grid_shape == (1000, 1000)
    assert m.clearance_grid.shape == m.grid_shape


# ----------------------------------------------------------------------------------------
# Errors
# ----------------------------------------------------------------------------------------


def _valid_inline() -> dict[str, Any]:
    return {
        "bounds": [[0, 0], [2, 2]],
        "resolution": 0.1,
        "obstacles": [
            {"rectangle": {"min": [0.2, 0.2], "max": [0.6, 0.6]}},
            {"circle": {"center": [1.5, 1.5], "radius": 0.2}},
            {"polygon": {"points": [[1.0, 0.2], [1.8, 0.2], [1.4, 0.9]]}},
        ],
    }


def _set(doc: dict[str, Any], path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    target: Any = doc
    for key in path[:-1]:
        target = target[key]
    if value is _DELETE:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return doc


_DELETE = object()

INLINE_ERRORS = [
    (("bounds",), _DELETE, ["missing key 'bounds'"]),
    (
        ("obstacle",),
        [],
        ["unknown key(s) 'obstacle'; allowed: bounds, name, obstacles, resolution"],
    ),
    (("resolution",), 0, ["'resolution' must be a positive number (m), got 0"]),
    (("resolution",), -0.1, ["'resolution' must be a positive number (m), got -0.1"]),
    (
        ("resolution",),
        "0.1",
        ["'resolution' must be a finite number (m), got '0.1' (a string: write numbers without"],
    ),
    (("resolution",), True, ["'resolution' must be a finite number (m), got true"]),
    (("resolution",), 0.3, ["whole number of cells", "'resolution'"]),
    (("bounds",), [[0, 0], [0, 2]], ["'bounds' max", "must exceed"]),
    (("bounds",), [[0, 0]], ["'bounds'", "[[xmin, ymin], [xmax, ymax]]"]),
    (("bounds",), [[0, "a"], [2, 2]], ["'bounds[0]' must be a list of 2 numbers [x, y] (m)"]),
    (("bounds",), [[0, float("nan")], [2, 2]], ["'bounds[0]'", "(finite), got [0, nan]"]),
    (("obstacles",), "rect", ["'obstacles' must be a list of shapes", "got 'rect'"]),
    (
        ("obstacles", 0),
        {"triangle": {}},
        ["'obstacles[0]' must hold exactly one of the keys rectangle, circle, polygon, got 'tri"],
    ),
    (
        ("obstacles", 0),
        {"rectangle": {}, "circle": {}},
        ["'obstacles[0]' must hold exactly one", "got 'rectangle', 'circle'"],
    ),
    (("obstacles", 0), 7, ["'obstacles[0]' must be a mapping with one of the keys rectangle"]),
    (
        ("obstacles", 0, "rectangle", "max"),
        [0.1, 0.6],
        ["'obstacles[0].rectangle'", "must exceed min"],
    ),
    (
        ("obstacles", 0, "rectangle", "min"),
        [0.2],
        ["'obstacles[0].rectangle.min' must be a list of 2 numbers [x, y] (m), got [0.2]"],
    ),
    (
        ("obstacles", 0, "rectangle", "size"),
        1,
        ["unknown key(s) 'obstacles[0].rectangle.size'; allowed: max, min"],
    ),
    (
        ("obstacles", 1, "circle", "radius"),
        0,
        ["'obstacles[1].circle.radius' must be a positive number (m), got 0"],
    ),
    (
        ("obstacles", 1, "circle", "radius"),
        -1.0,
        ["'obstacles[1].circle.radius' must be a positive number (m), got -1.0"],
    ),
    (("obstacles", 1, "circle", "radius"), _DELETE, ["missing key 'obstacles[1].circle.radius'"]),
    (("obstacles", 1, "circle", "radius"), 0.6, ["'obstacles[1]'", "outside the map bounds"]),
    (("obstacles", 0, "rectangle", "min"), [-0.1, 0.2], ["'obstacles[0]'", "outside the map"]),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1, 1], [1.5, 1]],
        ["'obstacles[2].polygon'", "at least 3"],
    ),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1.0, 0.2], [1.8, 0.8], [1.8, 0.2], [1.0, 0.8]],  # bow tie
        ["'obstacles[2].polygon'", "not simple", "intersect"],
    ),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1.0, 0.2], [1.4, 0.2], [1.8, 0.2]],
        ["'obstacles[2].polygon'", "not simple"],
    ),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1.0, 0.2], [1.8, 0.2], [1.8, 0.8], [1.4, 0.2], [1.0, 0.8]],  # vertex on an edge
        ["'obstacles[2].polygon'", "intersect"],
    ),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1.0, 0.2], [1.8, 0.2], [1.4, 0.2], [1.4, 0.8]],  # folds back along itself
        ["'obstacles[2].polygon'", "fold back"],
    ),
    (("obstacles", 2, "polygon", "points"), [[1, 1], [1, 1], [1.5, 1.5]], ["coincide"]),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1, 1], [1.5, "x"], [1.5, 1.5]],
        ["'obstacles[2].polygon.points[1]' must be a list of 2 numbers", "got [1.5, 'x']"],
    ),
    (
        ("obstacles", 2, "polygon", "points"),
        [[1, 1]] * 2001,
        ["'obstacles[2].polygon.points' has 2001 entries; at most 2000 are allowed; split"],
    ),
    (("obstacles", 2, "polygon"), [[1, 1]], ["'obstacles[2].polygon' must be a mapping"]),
    (("name",), 3, ["'name' must be a non-empty one-line string", "got 3"]),
    (
        ("obstacles", 0, "rectangle", "max"),
        [0.6, 0.23],  # 0.03 m thick, between the cell centre rows at 0.15 and 0.25
        ["'obstacles[0]' (rectangle) contains no cell centre", "finer resolution"],
    ),
]


@pytest.mark.parametrize(("path", "value", "needles"), INLINE_ERRORS)
def test_inline_errors_name_field_and_source(
    path: tuple[Any, ...], value: Any, needles: list[str]
) -> None:
    doc = _set(_valid_inline(), path, value)
    with pytest.raises(MapError) as info:
        load_map(doc)
    msg = str(info.value)
    assert msg.startswith("inline map: ")
    for needle in needles:
        assert needle in msg, msg


def test_inline_errors_in_a_file_name_the_file(tmp_path: Path) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(
        "bounds: [[0, 0], [1, 1]]\nobstacles:\n  - circle: {center: [0.5, 0.5], radius: -1}\n"
    )
    with pytest.raises(
        MapError, match=r"bad\.yaml: 'obstacles\[0\]\.circle\.radius' must be a positive number"
    ):
        load_map(f)


def test_polygon_edges_crossing_and_valid_concave() -> None:
    with pytest.raises(MapError, match="edges 0 and 2 intersect"):
        Polygon(((0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)))
    # a concave, simple polygon whose non-adjacent edges come close but do not meet
    Polygon(((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (1.0, 0.001), (0.0, 2.0)))


def _good_pgm() -> bytes:
    return pgm_bytes(np.full((3, 4), 254))


ROS_ERRORS: list[tuple[dict[str, Any], list[str]]] = [
    ({"resolution": 0}, ["'resolution' must be a positive number (m), got 0"]),
    ({"resolution": -0.05}, ["'resolution' must be a positive number (m), got -0.05"]),
    ({"resolution": "abc"}, ["'resolution' must be a finite number (m), got 'abc'"]),
    ({"origin": "1, 2"}, ["'origin' must be a list of 3 numbers [x, y, yaw]", "got [1, 2]"]),
    ({"origin": "1, two, 0"}, ["'origin' must be a list of 3", "(finite), got [1, 'two', 0]"]),
    ({"origin": (0.0, 0.0, 0.5)}, ["'origin'", "yaw", "unsupported", "set yaw to 0"]),
    ({"negate": 2}, ["'negate' must be an integer in [0, 1], got 2"]),
    ({"negate": "true"}, ["'negate' must be an integer in [0, 1], got true"]),
    ({"negate": 0.0}, ["'negate' must be an integer in [0, 1], got 0.0"]),
    ({"occupied_thresh": 1.5}, ["'occupied_thresh' must be a number in [0, 1], got 1.5"]),
    ({"free_thresh": -0.1}, ["'free_thresh' must be a number in [0, 1], got -0.1"]),
    ({"occupied_thresh": 0.2, "free_thresh": 0.3}, ["'occupied_thresh'", "must exceed"]),
    ({"occupied_thresh": 0.3, "free_thresh": 0.3}, ["'occupied_thresh'", "must exceed"]),
    ({"free_thresh": "low"}, ["'free_thresh' must be a finite number, got 'low'"]),
    ({"extra": "mode: ternary\n"}, ["'mode' must be one of trinary, scale, raw, got 'ternary'"]),
    ({"extra": "foo: 1\n"}, ["unknown key(s) 'foo'; allowed: free_thresh, image, mode, negate"]),
]


@pytest.mark.parametrize(("kw", "needles"), ROS_ERRORS)
def test_ros_yaml_errors(tmp_path: Path, kw: dict[str, Any], needles: list[str]) -> None:
    path = ros_map(tmp_path, _good_pgm(), **kw)
    with pytest.raises(MapError) as info:
        load_map(path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    for needle in needles:
        assert needle in msg, msg


def test_ros_missing_key_and_missing_image(tmp_path: Path) -> None:
    f = tmp_path / "m.yaml"
    f.write_text(
        "image: x.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.2\n"
    )
    with pytest.raises(MapError, match=r"m\.yaml: missing key 'negate'$"):
        load_map(f)
    path = ros_yaml(tmp_path, "nope.pgm")
    with pytest.raises(MapError) as info:
        load_map(path)
    msg = str(info.value)
    assert msg == (
        f"{path}: 'image': file {tmp_path / 'nope.pgm'} not found; a relative path is taken "
        "from the folder of map.yaml"
    )


IMAGE_ERRORS: list[tuple[bytes, list[str]]] = [
    (b"P5\n4 3\n255\n" + bytes(5), ["cannot decode the PGM", "truncated", "re-export"]),
    (b"P5\n4 3\n", ["corrupt PGM header", "EOF", "re-export"]),
    (b"P5\n4 x3\n255\n" + bytes(12), ["corrupt PGM header", "x3"]),
    (b"P5\n4 3\n70000\n" + bytes(24), ["corrupt PGM header", "maxval"]),
    (b"P5\n0 3\n255\n", ["corrupt or truncated PGM"]),
    (b"P2\n2 2\n255\n1 2 3\n", ["cannot decode the PGM", "not enough image data"]),
    (b"P2\n2 2\n255\n1 2 3 x\n", ["cannot decode the PGM", "'x'"]),
    (b"P2\n2 2\n100\n1 2 3 101\n", ["cannot decode the PGM", "101"]),
    (b"\xff\xd8\xff\xe0JFIF", ["unsupported image format", "PGM or PNG"]),
    (b"", ["unsupported image format"]),
]


@pytest.mark.parametrize(("data", "needles"), IMAGE_ERRORS)
def test_corrupt_images(tmp_path: Path, data: bytes, needles: list[str]) -> None:
    path = ros_map(tmp_path, data)
    with pytest.raises(MapError) as info:
        load_map(path)
    msg = str(info.value)
    assert str(path) in msg and "img.pgm" in msg, msg
    for needle in needles:
        assert needle in msg, msg


def test_netpbm_files_with_trailing_data_or_clamped_values_load(tmp_path: Path) -> None:
    # A netpbm file may hold several images one after another: the first one is read.
    m = load_map(ros_map(tmp_path, b"P5\n4 3\n255\n" + bytes([254] * 12) + b"extra"))
    assert m.grid_shape == (3, 4) and not m.occupied.any()
    m = load_map(ros_map(tmp_path, b"P2\n2 2\n255\n254 254 0 254 7\n"))
    np.testing.assert_array_equal(m.occupied, [[True, False], [False, False]])
    # Pillow clamps binary samples above maxval to maxval (white: free here).
    m = load_map(ros_map(tmp_path, b"P5\n2 2\n100\n\x00\x64\x64\xff"))
    np.testing.assert_array_equal(m.occupied, [[False, False], [True, False]])


def test_corrupt_pngs(tmp_path: Path) -> None:
    good = png_bytes(np.full((4, 5), 200))
    bad_crc = bytearray(good)
    bad_crc[20] ^= 0xFF  # inside IHDR
    rows = b"".join(b"\x00" + bytes(range(k, k + 60)) for k in range(50))
    stream = zlib.compress(rows)
    cut_stream = (
        good[:8]
        + _chunk(b"IHDR", struct.pack(">IIBBBBB", 60, 50, 8, 0, 0, 0, 0))
        + _chunk(b"IDAT", stream[: len(stream) // 2])
        + _chunk(b"IEND", b"")
    )
    cases = [
        (good[:40], "corrupt or truncated PNG"),
        (bytes(bad_crc), "corrupt or truncated PNG"),
        (png_bytes(np.full((4, 5), 200), interlace=1), "cannot decode the PNG"),
        (cut_stream, "cannot decode the PNG.*truncated"),
        (good[:8] + _chunk(b"IEND", b""), "corrupt or truncated PNG"),
        (png_bytes(np.full((2, 2), 200), filters=np.array([3, 4])), ""),  # control: loads
    ]
    for data, needle in cases:
        path = ros_map(tmp_path, data, ".png")
        if not needle:
            assert load_map(path).grid_shape == (2, 2)
            continue
        with pytest.raises(MapError, match=needle) as info:
            load_map(path)
        assert "img.png" in str(info.value)


def test_file_level_errors(tmp_path: Path) -> None:
    cases: list[tuple[Any, str]] = [
        (tmp_path / "missing.yaml", "missing.yaml: file not found"),
        (tmp_path, "file not found"),
        (42, "must be a file path or a mapping, got int"),
        (None, "must be a file path or a mapping"),
        ([1, 2], "must be a file path or a mapping, got list"),
    ]
    (tmp_path / "syntax.yaml").write_text("bounds: [[0, 0], [1, 1]\n")
    cases.append((tmp_path / "syntax.yaml", "syntax.yaml: not valid YAML"))
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    cases.append((tmp_path / "list.yaml", "list.yaml: a map file must hold a mapping"))
    (tmp_path / "both.yaml").write_text("image: a.pgm\nbounds: [[0, 0], [1, 1]]\n")
    cases.append((tmp_path / "both.yaml", "keep one"))
    (tmp_path / "neither.yaml").write_text("resolution: 0.05\n")
    cases.append((tmp_path / "neither.yaml", "missing required key 'image' (ROS map) or 'bounds'"))
    (tmp_path / "image.pgm").write_bytes(b"P5\n2 2\n255\n\x00\xff\xfe\x80")
    cases.append((tmp_path / "image.pgm", "not a text file; give the map's YAML file"))
    for source, needle in cases:
        with pytest.raises(MapError) as info:
            load_map(source)
        assert needle in str(info.value), str(info.value)


def test_direct_construction_errors() -> None:
    occ = np.zeros((2, 3), dtype=bool)
    with pytest.raises(MapError, match="resolution"):
        WorldMap(np.zeros(2), 0.0, occ)
    with pytest.raises(MapError, match="origin"):
        WorldMap(np.zeros(3), 0.1, occ)
    with pytest.raises(MapError, match="2D and non-empty"):
        WorldMap(np.zeros(2), 0.1, np.zeros((0, 3), dtype=bool))
    with pytest.raises(MapError, match="also be marked occupied"):
        WorldMap(np.zeros(2), 0.1, occ, unknown=~occ)
    with pytest.raises(MapError, match="Rectangle, Circle or Polygon"):
        WorldMap(np.zeros(2), 0.1, occ, shapes=("box",))  # type: ignore[arg-type]
    with pytest.raises(MapError, match="'obstacles\\[0\\]' is not a shape"):
        WorldMap.from_shapes([[0, 0], [1, 1]], ["box"])  # type: ignore[list-item]
    with pytest.raises(MapError, match="radius"):
        Circle((0.0, 0.0), math.inf)
    with pytest.raises(MapError, match="cells"):
        WorldMap.from_shapes([[0.0, 0.0], [1e6, 1e6]], resolution=0.01)
    m = WorldMap(np.zeros(2), 0.1, occ)
    with pytest.raises(AttributeError):
        m.resolution = 0.2  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        m.occupied[0, 0] = True


def test_pgm_writer_and_reader_agree(tmp_path: Path) -> None:
    from PIL import Image

    from gracenav.world.ros_map import _decode_image

    img = (np.arange(12).reshape(3, 4) * 20).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PPM")
    back, maxval, alpha = _decode_image(buf.getvalue(), "test")
    assert maxval == 255 and not alpha
    np.testing.assert_array_equal(back[..., 0], img)
    m = WorldMap(np.zeros(2), 0.1, np.zeros((2, 3), dtype=bool))
    with pytest.raises(ConfigError, match="image_format"):
        save_ros_map(m, tmp_path / "b.yaml", image_format="bmp")  # type: ignore[arg-type]
    with pytest.raises(MapError, match="file not found"):
        load_map(tmp_path / "none.yaml")


# ----------------------------------------------------------------------------------------
# Property-based tests
# ----------------------------------------------------------------------------------------


@st.composite
def inline_maps(draw: st.DrawFn) -> tuple[dict[str, Any], list[tuple[list[float], float]]]:
    """A valid inline map and, per obstacle, an interior point with a lower bound on its
    distance to the obstacle's boundary (m)."""
    res = draw(st.sampled_from([0.05, 0.1, 0.25]))
    nx, ny = draw(st.integers(8, 60)), draw(st.integers(8, 60))
    x0, y0 = draw(st.integers(-40, 40)) * res, draw(st.integers(-40, 40)) * res
    x1, y1 = x0 + nx * res, y0 + ny * res
    frac = st.floats(0.0, 1.0)
    obstacles: list[dict[str, Any]] = []
    interior: list[tuple[list[float], float]] = []
    for _ in range(draw(st.integers(0, 5))):
        kind = draw(st.sampled_from(["rectangle", "circle", "polygon"]))
        if kind == "rectangle":
            ax, bx = sorted([draw(frac), draw(frac)])
            ay, by = sorted([draw(frac), draw(frac)])
            if (bx - ax) * nx < 1.0 or (by - ay) * ny < 1.0:  # at least a cell wide
                continue
            lo = [x0 + ax * (x1 - x0), y0 + ay * (y1 - y0)]
            hi = [x0 + bx * (x1 - x0), y0 + by * (y1 - y0)]
            obstacles.append({"rectangle": {"min": lo, "max": hi}})
            mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2]
            interior.append((mid, min(hi[0] - lo[0], hi[1] - lo[1]) / 2))
            continue
        cx = x0 + draw(st.floats(0.05, 0.95)) * (x1 - x0)
        cy = y0 + draw(st.floats(0.05, 0.95)) * (y1 - y0)
        rmax = min(cx - x0, x1 - cx, cy - y0, y1 - cy)
        r = rmax * draw(st.floats(0.05, 1.0))
        if r < res:
            continue
        if kind == "circle":
            obstacles.append({"circle": {"center": [cx, cy], "radius": r}})
            interior.append(([cx, cy], r))
            continue
        # star-shaped about (cx, cy), angular gaps < pi: simple, with (cx, cy) inside
        n = draw(st.integers(4, 9))
        jitter = draw(st.lists(st.floats(-0.45, 0.45), min_size=n, max_size=n))
        radii = draw(st.lists(st.floats(0.3, 1.0), min_size=n, max_size=n))
        ang = [(k + j) * 2 * math.pi / n for k, j in enumerate(jitter)]
        pts = np.array(
            [
                [cx + r * q * math.cos(a), cy + r * q * math.sin(a)]
                for a, q in zip(ang, radii, strict=True)
            ]
        )
        c = np.array([cx, cy])
        d = np.roll(pts, -1, axis=0) - pts
        t = np.clip(np.sum((c - pts) * d, axis=1) / np.sum(d * d, axis=1), 0.0, 1.0)
        margin = float(np.hypot(*(pts + t[:, None] * d - c).T).min())
        if margin < res:  # too thin to be sure it covers a cell centre
            continue
        obstacles.append({"polygon": {"points": pts.tolist()}})
        interior.append(([cx, cy], margin))
    doc = {"bounds": [[x0, y0], [x1, y1]], "resolution": res, "obstacles": obstacles}
    return doc, interior


@settings(max_examples=120, deadline=None)
@given(inline_maps())
def test_random_valid_inline_maps_load_and_block_interiors(
    case: tuple[dict[str, Any], list[tuple[list[float], float]]],
) -> None:
    doc, interior = case
    m = load_map(doc)
    res = doc["resolution"]
    shapes = m.shapes
    assert shapes is not None and len(shapes) == len(doc["obstacles"])
    union = np.zeros(m.grid_shape, dtype=bool)
    centres = m.cell_centers()
    for s in shapes:
        union |= s.contains(centres)
    np.testing.assert_array_equal(m.occupied, union)
    for shape, (point, margin) in zip(shapes, interior, strict=True):
        assert shape.contains(point)
        # margin >= res/2 per axis: the cell holding the point has its centre inside too
        assert margin >= 0.5 * res
        assert not m.is_free(point)
        assert m.clearance(point) == 0.0
    assert np.all(m.clearance_grid >= 0.0)


_garbage = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**30), 10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(
            st.text(max_size=8)
            | st.sampled_from(
                [
                    "bounds",
                    "obstacles",
                    "resolution",
                    "circle",
                    "rectangle",
                    "polygon",
                    "points",
                    "min",
                    "max",
                    "center",
                    "radius",
                    "image",
                    "name",
                ]
            ),
            children,
            max_size=4,
        )
    ),
    max_leaves=12,
)


def _paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for k, v in enumerate(doc):
            out += _paths(v, (*prefix, k))
    return out


@settings(max_examples=300, deadline=None)
@given(_garbage)
def test_garbage_sources_raise_map_error_only(value: Any) -> None:
    try:
        load_map(value)
    except MapError:
        pass


@settings(max_examples=300, deadline=None)
@given(st.data(), _garbage)
def test_mutated_inline_maps_raise_map_error_only(data: st.DataObject, value: Any) -> None:
    doc = _valid_inline()
    path = data.draw(st.sampled_from(_paths(doc)))
    _set(doc, path, value)
    try:
        m = load_map(doc)
    except MapError:
        return
    assert m.grid_shape[0] >= 1


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from(
        ["resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode", "image"]
    ),
    _garbage,
    st.binary(max_size=64),
    st.sampled_from([b"P5\n", b"P2\n", b"\x89PNG\r\n\x1a\n", b""]),
)
def test_garbage_ros_files_raise_map_error_only(
    key: str, value: Any, tail: bytes, magic: bytes
) -> None:
    import yaml

    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        (folder / "img.pgm").write_bytes(magic + tail)
        doc: dict[str, Any] = {
            "image": "img.pgm",
            "resolution": 0.05,
            "origin": [0.0, 0.0, 0.0],
            "negate": 0,
            "occupied_thresh": 0.65,
            "free_thresh": 0.196,
        }
        doc[key] = value
        (folder / "m.yaml").write_text(yaml.safe_dump(doc))
        (folder / "raw.yaml").write_bytes(tail)
        for f in ("m.yaml", "raw.yaml"):
            try:
                load_map(folder / f)
            except MapError:
                pass


@settings(max_examples=100, deadline=None)
@given(
    hnp.arrays(
        st.sampled_from([np.uint8, np.uint16]),
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=12),
    ),
    st.booleans(),
    st.booleans(),
)
def test_random_grids_round_trip_through_pgm(img: np.ndarray, binary: bool, negate: bool) -> None:
    from PIL import Image

    from gracenav.world.ros_map import _decode_image

    maxval = 255 if img.dtype == np.uint8 else 65535
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        # the test's own writer, then Pillow's (binary P5 only)
        (folder / "a.pgm").write_bytes(pgm_bytes(img, maxval, binary=binary))
        back, mv, _ = _decode_image((folder / "a.pgm").read_bytes(), "a.pgm")
        np.testing.assert_array_equal(back[..., 0], img)
        assert mv == maxval
        Image.fromarray(img).save(folder / "b.pgm", format="PPM")
        back, mv, _ = _decode_image((folder / "b.pgm").read_bytes(), "b.pgm")
        np.testing.assert_array_equal(back[..., 0], img)
        assert mv == maxval
        m = load_map(ros_yaml(folder, "a.pgm", negate=int(negate)))
        p = img / maxval if negate else (maxval - img.astype(float)) / maxval
        np.testing.assert_array_equal(m.occupied, ~(p < 0.196)[::-1])
        assert m.unknown is not None
        np.testing.assert_array_equal(m.unknown, ((p >= 0.196) & (p <= 0.65))[::-1])


@settings(max_examples=60, deadline=None)
@given(
    hnp.arrays(np.uint8, hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=10)),
    st.data(),
)
def test_random_grids_round_trip_through_png(img: np.ndarray, data: st.DataObject) -> None:
    from gracenav.world.ros_map import _decode_image as _decode_png

    filters = np.array(data.draw(st.lists(st.integers(0, 4), min_size=len(img), max_size=len(img))))
    pixels, maxval, alpha = _decode_png(png_bytes(img, filters=filters), "test")
    assert maxval == 255 and not alpha
    np.testing.assert_array_equal(pixels[..., 0], img)
