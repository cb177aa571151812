"""ROS map_server maps through images that Pillow writes: every pixel format map_server
reads, each mode and negate, against a per-pixel reference classifier."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from gracenav.world import WorldMap, load_map, save_ros_map


def ros_yaml(folder: Path, image: str, *, negate: int = 0, mode: str = "trinary") -> Path:
    path = folder / "map.yaml"
    path.write_text(
        f"image: {image}\nmode: {mode}\nresolution: 0.1\norigin: [-1.0, 2.0, 0.0]\n"
        f"negate: {negate}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    return path


def reference(
    pixels: np.ndarray, maxval: int, has_alpha: bool, negate: int, mode: str
) -> tuple[np.ndarray, np.ndarray]:
    """map_server's classification, pixel by pixel (image orientation): (occupied or
    unknown, unknown). The mean runs over the colour channels, plus opacity in trinary
    mode; a gray + alpha pixel counts its gray as R, G and B."""
    h, w, channels = pixels.shape
    occupied = np.zeros((h, w), dtype=bool)
    unknown = np.zeros((h, w), dtype=bool)
    for i in range(h):
        for j in range(w):
            px = [float(v) for v in pixels[i, j]]
            if has_alpha and channels == 2:
                px = [px[0], px[0], px[0], px[1]]
            use = px if (mode == "trinary" or not has_alpha) else px[:-1]
            mean = sum(use) / len(use)
            if mode == "raw":
                value = maxval - mean if negate else mean
                occupied[i, j] = value != 0.0
                continue
            p = mean / maxval if negate else (maxval - mean) / maxval
            if p > 0.65:
                occupied[i, j] = True
            elif not p < 0.196:
                occupied[i, j] = unknown[i, j] = True
    return occupied, unknown


def _levels(rng: np.random.Generator, shape: tuple[int, ...], top: int) -> np.ndarray:
    """Random levels in 0..top, with the threshold neighbourhoods well represented."""
    edges = np.array([0.196, 0.65, 0.804, 0.35])  # p and 1 − p for both thresholds
    near = np.clip(np.rint(edges * top)[None, :] + np.arange(-2, 3)[:, None], 0, top).ravel()
    pool = np.concatenate([near, rng.integers(0, top + 1, size=64), [0, top]])
    levels = rng.choice(pool, size=shape).astype(np.int64)
    levels[0, 0], levels[0, 1] = 0, top  # black and white pixels (all channels)
    return levels


# kind -> (file suffix, Pillow image, pixels the map sees (h, w, c), maxval, has_alpha)
def _image(kind: str, rng: np.random.Generator) -> tuple[str, Image.Image, np.ndarray, int, bool]:
    h, w = 9, 13
    if kind in ("pgm8", "png8"):
        g = _levels(rng, (h, w), 255).astype(np.uint8)
        return kind[:3], Image.fromarray(g), g[..., None], 255, False
    if kind in ("pgm16", "png16"):
        g = _levels(rng, (h, w), 65535).astype(np.uint16)
        return kind[:3], Image.fromarray(g), g[..., None], 65535, False
    if kind == "rgb":
        c = _levels(rng, (h, w, 3), 255).astype(np.uint8)
        return "png", Image.fromarray(c), c, 255, False
    if kind == "rgba":
        c = _levels(rng, (h, w, 4), 255).astype(np.uint8)
        return "png", Image.fromarray(c), c, 255, True
    if kind == "gray_alpha":
        c = _levels(rng, (h, w, 2), 255).astype(np.uint8)
        im = Image.merge("LA", [Image.fromarray(c[..., 0]), Image.fromarray(c[..., 1])])
        return "png", im, c, 255, True
    if kind == "palette":
        colours = _levels(rng, (16, 3), 255).astype(np.uint8)
        index = rng.integers(0, 16, size=(h, w)).astype(np.uint8)
        colours[0], colours[1] = 0, 255
        index[0, 0], index[0, 1] = 0, 1
        im = Image.fromarray(index).convert("P")
        im.putpalette(colours.ravel().tolist())
        return "png", im, colours[index], 255, False
    if kind == "bitmap":
        bits = rng.random((h, w)) < 0.5
        return "png", Image.fromarray(bits), np.where(bits, 255, 0)[..., None], 255, False
    raise AssertionError(kind)


KINDS = ["pgm8", "pgm16", "png8", "png16", "rgb", "rgba", "gray_alpha", "palette", "bitmap"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(
    ("negate", "mode"),
    [(0, "trinary"), (1, "trinary"), (0, "scale"), (1, "scale"), (0, "raw"), (1, "raw")],
)
def test_pillow_written_images_match_map_server(
    tmp_path: Path, kind: str, negate: int, mode: str
) -> None:
    rng = np.random.default_rng(KINDS.index(kind))
    suffix, im, pixels, maxval, has_alpha = _image(kind, rng)
    im.save(tmp_path / f"img.{suffix}")
    m = load_map(ros_yaml(tmp_path, f"img.{suffix}", negate=negate, mode=mode))
    occupied, unknown = reference(pixels, maxval, has_alpha, negate, mode)
    np.testing.assert_array_equal(m.occupied, occupied[::-1])
    assert m.unknown is not None
    np.testing.assert_array_equal(m.unknown, unknown[::-1])
    assert m.resolution == 0.1 and m.grid_shape == pixels.shape[:2]
    np.testing.assert_allclose(m.origin, [-1.0, 2.0], rtol=0, atol=0)
    # the classification must be non-trivial for the comparison to mean something
    assert occupied.any() and (~occupied).any()


def test_sixteen_bit_colour_png_reads_its_high_bytes(tmp_path: Path) -> None:
    # Pillow keeps 8 bits per colour channel, as map_server's libpng reader does: the low
    # byte cannot move a pixel across a threshold unless it is within 1/256 of it.
    import struct
    import zlib

    rgb = np.array([[[0x5900, 0x59FF, 0x5980], [0xCE00, 0xCEFF, 0xCE80]]], dtype=">u2")
    raw = b"".join(b"\x00" + row.tobytes() for row in rgb)

    def chunk(kind: bytes, body: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + body))
        return struct.pack(">I", len(body)) + kind + body + crc

    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 1, 16, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )
    (tmp_path / "img.png").write_bytes(png)
    m = load_map(ros_yaml(tmp_path, "img.png"))
    # high bytes 0x59 = 89 (p = 0.651: occupied) and 0xCE = 206 (p = 0.192: free)
    np.testing.assert_array_equal(m.occupied, [[True, False]])


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize(("maxval", "level"), [(100, 35), (1000, 350), (200, 70)])
def test_pgm_maxval_is_kept_exactly(tmp_path: Path, binary: bool, maxval: int, level: int) -> None:
    # p = (maxval − level) / maxval = 0.65 exactly: not above occupied_thresh, so unknown.
    # Pillow rescales such a PGM to 0..255 / 0..65535 (35 -> 89, p = 0.651: occupied);
    # the loader undoes that.
    img = np.array([[0, level, level + 1, level - 1, maxval]])
    head = f"{'P5' if binary else 'P2'}\n{img.shape[1]} 1\n{maxval}\n".encode()
    if binary:
        body = img.astype(">u2" if maxval > 255 else np.uint8).tobytes()
    else:
        body = " ".join(str(v) for v in img.ravel()).encode() + b"\n"
    (tmp_path / "img.pgm").write_bytes(head + body)
    m = load_map(ros_yaml(tmp_path, "img.pgm"))
    assert m.unknown is not None
    np.testing.assert_array_equal(m.occupied[0], [True, True, True, True, False])
    np.testing.assert_array_equal(m.unknown[0], [False, True, True, False, False])


@pytest.mark.parametrize("image_format", ["pgm", "png"])
def test_save_ros_map_writes_map_saver_levels(tmp_path: Path, image_format: Any) -> None:
    occupied = np.array([[True, False, True], [False, False, True]])
    unknown = np.array([[False, False, True], [False, False, False]])
    m = WorldMap(np.array([0.5, -0.25]), 0.2, occupied, unknown=unknown)
    image = save_ros_map(m, tmp_path / "out.yaml", image_format=image_format)
    with Image.open(image) as im:
        assert im.format == ("PPM" if image_format == "pgm" else "PNG")
        assert im.mode == "L"
        levels = np.asarray(im)
    # image row 0 is the top of the map (the grid's last row)
    np.testing.assert_array_equal(levels, [[254, 254, 0], [0, 254, 205]])
    text = (tmp_path / "out.yaml").read_text()
    assert f"image: out.{image_format}\n" in text and "origin: [0.5, -0.25, 0.0]" in text
    back = load_map(tmp_path / "out.yaml")
    np.testing.assert_array_equal(back.occupied, occupied)
    assert back.unknown is not None
    np.testing.assert_array_equal(back.unknown, unknown)
