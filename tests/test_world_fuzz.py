"""Property-based fuzzing of the map loaders: every input either loads or raises a
GracenavError subclass, never another exception (a user must never see a traceback).

Inputs: arbitrary structures and near-valid inline maps, shapes built directly, raw
bytes as a map file, ROS YAML documents with arbitrary field values, and images that are
random, mutated from valid Pillow-written PGM/PNG files, or headers with random fields.
Each property is bounded (max_examples) so the whole file runs in a few seconds.
"""

from __future__ import annotations

import io
import struct
import tempfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context
from PIL import Image

from gracenav import GracenavError
from gracenav.world import Circle, Polygon, Rectangle, WorldMap, load_map

FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

_numbers = (
    st.integers(-(10**20), 10**20)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.floats(-50, 50)
    | st.sampled_from([0, 1, -1, 0.05, 0.1, 1e-300, 1e300, True, False])
)
_scalars = st.none() | _numbers | st.text(max_size=6) | st.binary(max_size=6)
_KEYS = [
    "bounds", "obstacles", "resolution", "name", "rectangle", "circle", "polygon",
    "points", "min", "max", "center", "radius", "image", "origin", "negate",
    "occupied_thresh", "free_thresh", "mode",
]  # fmt: skip
_anything = st.recursive(
    _scalars,
    lambda children: (
        st.lists(children, max_size=4)
        | st.tuples(children, children)
        | st.dictionaries(st.sampled_from(_KEYS) | st.text(max_size=4), children, max_size=4)
    ),
    max_leaves=16,
)


def loads_or_refuses(source: Any) -> WorldMap | None:
    """load_map(source), or None if it raised a GracenavError; anything else fails."""
    try:
        m = load_map(source)
    except GracenavError as exc:
        if currently_in_test_context():
            event(f"refused: {type(exc).__name__}")
        return None
    if currently_in_test_context():
        event("loaded")
    return m


# ----------------------------------------------------------------------------------------
# Inline maps and shapes
# ----------------------------------------------------------------------------------------


@FAST
@given(_anything)
def test_any_structure_as_an_inline_map(doc: Any) -> None:
    loads_or_refuses(doc)
    if isinstance(doc, dict):
        loads_or_refuses({"bounds": [[0, 0], [1, 1]], **doc})


_pair = st.tuples(st.floats(-12, 12) | _numbers, st.floats(-12, 12) | _numbers)
_shape_doc = st.one_of(
    st.fixed_dictionaries({"rectangle": st.fixed_dictionaries({"min": _pair, "max": _pair})}),
    st.fixed_dictionaries(
        {"circle": st.fixed_dictionaries({"center": _pair, "radius": st.floats(-1, 5) | _numbers})}
    ),
    st.fixed_dictionaries(
        {"polygon": st.fixed_dictionaries({"points": st.lists(_pair | _anything, max_size=7)})}
    ),
    _anything,
)


@FAST
@given(
    st.integers(-10, 10),
    st.integers(-10, 10),
    st.integers(1, 200),
    st.integers(1, 200),
    st.sampled_from([0.05, 0.1, 0.25, 0.5]) | st.floats(0.02, 3.0) | _numbers,
    st.lists(_shape_doc, max_size=4),
)
def test_near_valid_inline_maps(
    x0: int, y0: int, nx: int, ny: int, res: Any, obstacles: list[Any]
) -> None:
    step = res if isinstance(res, float) and 0.02 <= res <= 3.0 else 0.1
    doc = {
        "bounds": [[x0, y0], [x0 + nx * step, y0 + ny * step]],
        "resolution": res,
        "obstacles": obstacles,
    }
    m = loads_or_refuses(doc)
    if m is not None:
        assert m.occupied.shape == m.grid_shape and m.grid_shape[0] * m.grid_shape[1] >= 1
        assert np.all(m.clearance_grid >= 0.0)


_any_float = st.floats() | st.sampled_from([1e308, -1e308, 5e-324, 1e-310, 0.05])


@FAST
@given(st.lists(_any_float | st.integers(-3, 3), min_size=4, max_size=4), _any_float)
def test_any_numbers_as_bounds_and_resolution(v: list[float], res: float) -> None:
    m = loads_or_refuses({"bounds": [[v[0], v[1]], [v[2], v[3]]], "resolution": res})
    if m is not None:
        assert m.grid_shape[0] * m.grid_shape[1] <= 10_000_000


@FAST
@given(_anything | _pair, _anything | _pair, st.lists(_anything | _pair, max_size=6))
def test_shapes_built_directly(a: Any, b: Any, points: list[Any]) -> None:
    for build in (
        lambda: Rectangle(a, b),
        lambda: Circle(a, b),
        lambda: Polygon(points),  # type: ignore[arg-type]
        lambda: Polygon(a),
        lambda: WorldMap.from_shapes(a, [], resolution=b),
        lambda: WorldMap.from_shapes([[0, 0], [2, 2]], [a], resolution=0.1),
    ):
        try:
            build()
        except GracenavError:
            pass


# ----------------------------------------------------------------------------------------
# Map files
# ----------------------------------------------------------------------------------------


@FAST
@given(st.binary(max_size=200) | st.text(max_size=200).map(lambda s: s.encode("utf-8")))
def test_any_bytes_as_a_map_file(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "m.yaml"
        f.write_bytes(data)
        loads_or_refuses(f)
        f.write_bytes(b"image: img.pgm\nresolution: 0.1\n" + data)
        loads_or_refuses(f)


_ROS = {
    "image": "img.png",
    "resolution": 0.05,
    "origin": [0.0, 0.0, 0.0],
    "negate": 0,
    "occupied_thresh": 0.65,
    "free_thresh": 0.196,
}


def _gray_png() -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.array([[0, 205, 254], [254, 0, 100]], dtype=np.uint8)).save(buf, "PNG")
    return buf.getvalue()


_unit = st.floats(0, 1) | st.sampled_from([0.0, 0.196, 0.65, 1.0])
_plausible = {
    "image": st.sampled_from(["img.png", "./img.png", "missing.png", "", "."]),
    "resolution": st.floats(1e-3, 10.0) | st.sampled_from([0.05, 0.0, -0.05]),
    "origin": st.lists(st.floats(-100, 100) | st.sampled_from([0.0, -0.0]), min_size=2, max_size=4),
    "negate": st.sampled_from([0, 1, 2, -1, 0.0]),
    "occupied_thresh": _unit,
    "free_thresh": _unit,
    "mode": st.sampled_from(["trinary", "scale", "raw", "Trinary", ""]),
    "extra": st.just(1),
}


@st.composite
def ros_changes(draw: st.DrawFn) -> dict[str, Any]:
    keys = draw(st.lists(st.sampled_from(list(_plausible)), max_size=3, unique=True))
    return {k: draw(_plausible[k] | _anything) for k in keys}


@FAST
@given(ros_changes(), st.lists(st.sampled_from(list(_ROS)), max_size=2))
def test_ros_yaml_with_any_field_values(changes: dict[str, Any], dropped: list[str]) -> None:
    doc = {**_ROS, **changes}
    for key in dropped:
        doc.pop(key, None)
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        (folder / "img.png").write_bytes(_gray_png())
        f = folder / "m.yaml"
        try:
            f.write_text(yaml.safe_dump(doc))
        except yaml.YAMLError:  # bytes and some floats cannot be dumped: not a map file
            return
        m = loads_or_refuses(f)
        if m is not None:
            assert m.grid_shape == (2, 3)


def _pillow_images() -> list[bytes]:
    rng = np.random.default_rng(0)
    g8 = rng.integers(0, 256, (5, 7)).astype(np.uint8)
    images = []
    for im, fmt in (
        (Image.fromarray(g8), "PPM"),
        (Image.fromarray(g8.astype(np.uint16) * 257), "PPM"),
        (Image.fromarray(g8), "PNG"),
        (Image.fromarray(g8.astype(np.uint16) * 257), "PNG"),
        (Image.fromarray(np.dstack([g8, g8, g8, g8])), "PNG"),
        (Image.fromarray(g8).convert("P"), "PNG"),
        (Image.fromarray(g8 > 128), "PNG"),
    ):
        buf = io.BytesIO()
        im.save(buf, fmt)
        images.append(buf.getvalue())
    return images


VALID_IMAGES = _pillow_images()


@st.composite
def mutated_images(draw: st.DrawFn) -> bytes:
    data = bytearray(draw(st.sampled_from(VALID_IMAGES)))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
        pos = draw(st.integers(0, max(0, len(data) - 1)))
        if op == "flip" and data:
            data[pos] ^= draw(st.integers(1, 255))
        elif op == "cut":
            del data[pos:]
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif data:
            del data[pos : pos + draw(st.integers(1, 8))]
    return bytes(data)


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


@st.composite
def png_headers(draw: st.DrawFn) -> bytes:
    """PNGs with valid chunk framing and random header fields and image data."""
    w, h = draw(st.integers(0, 5000)), draw(st.integers(0, 5000))
    depth = draw(st.sampled_from([1, 2, 4, 8, 16, 3, 0]))
    colour = draw(st.sampled_from([0, 2, 3, 4, 6, 1, 7]))
    interlace = draw(st.sampled_from([0, 1, 2]))
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, interlace)
    chunks = _chunk(b"IHDR", ihdr)
    if draw(st.booleans()):
        chunks += _chunk(b"PLTE", draw(st.binary(max_size=12)))
    chunks += _chunk(b"IDAT", zlib.compress(draw(st.binary(max_size=64))))
    return b"\x89PNG\r\n\x1a\n" + chunks + _chunk(b"IEND", b"")


@st.composite
def netpbm_headers(draw: st.DrawFn) -> bytes:
    """netpbm files with random magic, header tokens and pixel bytes."""
    magic = draw(st.sampled_from([b"P1", b"P2", b"P3", b"P4", b"P5", b"P6", b"Pf", b"P7"]))
    token = st.integers(-2, 70000).map(lambda v: str(v).encode()) | st.binary(max_size=4)
    tokens = draw(st.lists(token, min_size=0, max_size=4))
    sep = draw(st.sampled_from([b" ", b"\n", b"\n# c\n"]))
    return magic + sep + sep.join(tokens) + sep + draw(st.binary(max_size=64))


_images = (
    mutated_images()
    | png_headers()
    | netpbm_headers()
    | st.binary(max_size=64)
    | st.sampled_from([b"\x89PNG\r\n\x1a\n", b"P5", b"P2\n"]).flatmap(
        lambda magic: st.binary(max_size=64).map(lambda tail: magic + tail)
    )
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_images, st.sampled_from(["trinary", "scale", "raw"]), st.sampled_from([0, 1]))
def test_ros_maps_with_any_image(image: bytes, mode: str, negate: int) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        (folder / "img.bin").write_bytes(image)
        f = folder / "m.yaml"
        f.write_text(yaml.safe_dump({**_ROS, "image": "img.bin", "mode": mode, "negate": negate}))
        m = loads_or_refuses(f)
        if m is not None:
            assert m.unknown is not None and not np.any(m.unknown & ~m.occupied)


def test_the_mutations_exercise_both_outcomes() -> None:
    # the valid images load, and a header cut short does not
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        f = folder / "m.yaml"
        f.write_text(yaml.safe_dump({**_ROS, "image": "img.bin"}))
        for data in VALID_IMAGES:
            (folder / "img.bin").write_bytes(data)
            assert loads_or_refuses(f) is not None
            (folder / "img.bin").write_bytes(data[:12])
            assert loads_or_refuses(f) is None
