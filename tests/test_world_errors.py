"""Maps refused with a MapError that names the file and says what to do: over the memory
budget (before anything of the map's size is allocated), unreadable files and images,
invalid numbers."""

from __future__ import annotations

import struct
import tracemalloc
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from gracenav import GracenavError, MapError
from gracenav.world import (
    MAP_BYTES_PER_CELL,
    MAX_MAP_CELLS,
    MAX_MAP_FILE_BYTES,
    MAX_POLYGON_POINTS,
    Circle,
    Polygon,
    Rectangle,
    load_map,
    office_map,
)

ROS_FIELDS = {
    "image": "img.pgm",
    "resolution": "0.05",
    "origin": "[0.0, 0.0, 0.0]",
    "negate": "0",
    "occupied_thresh": "0.65",
    "free_thresh": "0.196",
}


def ros_map(folder: Path, image_bytes: bytes, suffix: str = ".pgm", **fields: str) -> Path:
    (folder / f"img{suffix}").write_bytes(image_bytes)
    doc = {**ROS_FIELDS, "image": f"img{suffix}", **fields}
    path = folder / "map.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in doc.items()))
    return path


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width`` × ``height`` 8-bit gray pixels, with no pixels."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + body))
        return struct.pack(">I", len(body)) + kind + body + crc

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\x00"))
        + chunk(b"IEND", b"")
    )


def refused(load: Callable[[], Any]) -> tuple[str, int]:
    """The MapError message of ``load()`` and the peak memory (bytes) it allocated."""
    Image.init()  # import Pillow's format plugins now, not while measuring
    tracemalloc.start()
    try:
        with pytest.raises(MapError) as info:
            load()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # no chained traceback: nothing caused it, and any exception it replaced is hidden
    err = info.value
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__)
    return str(info.value), peak


# ----------------------------------------------------------------------------------------
# The memory budget
# ----------------------------------------------------------------------------------------


def test_budget_constants() -> None:
    assert MAX_MAP_CELLS == 10_000_000
    assert 30 <= MAP_BYTES_PER_CELL <= 64
    # the benchmark office (50 m at 5 cm) fits with room to spare; 200 m at 5 cm does not
    assert (50 / 0.05) ** 2 < MAX_MAP_CELLS / 5 and (200 / 0.05) ** 2 > MAX_MAP_CELLS


def test_inline_200m_map_at_default_resolution_is_refused_before_allocating() -> None:
    msg, peak = refused(lambda: load_map({"bounds": [[0, 0], [200, 200]]}))
    assert msg.startswith("inline map: the map would have 4,000 × 4,000 = 16,000,000 cells")
    assert f"{16_000_000 * MAP_BYTES_PER_CELL / 2**20:.0f} MiB" in msg
    assert "the limit is 10,000,000 cells" in msg
    assert "coarser 'resolution'" in msg and "smaller 'bounds'" in msg
    assert peak < 1_000_000  # a 4000 × 4000 bool grid alone would be 16 MB


def test_inline_budget_from_a_file_names_the_file(tmp_path: Path) -> None:
    f = tmp_path / "campus.yaml"
    f.write_text("bounds: [[-100, -100], [100, 100]]\nresolution: 0.02\n")
    msg, peak = refused(lambda: load_map(f))
    assert msg.startswith(f"{f}: the map would have 10,000 × 10,000 = 100,000,000 cells")
    assert peak < 1_000_000


def test_budget_boundary_is_inclusive() -> None:
    m = load_map({"bounds": [[0, 0], [250, 100]]})  # 5000 × 2000 cells, exactly the budget
    assert m.grid_shape == (2000, 5000)
    msg, _ = refused(lambda: load_map({"bounds": [[0, 0], [250, 100.05]]}))
    assert "5,000 × 2,001 = 10,005,000 cells" in msg


@pytest.mark.parametrize(
    ("bounds", "res"),
    [([[0, 0], [1, 1]], 1e-300), ([[0, 0], [1e6, 1]], 1e-310), ([[-1e308, 0], [1e308, 1]], 1.0)],
)
def test_absurd_inline_extent_is_refused(bounds: list[list[float]], res: float) -> None:
    # warnings are errors in the tests: no overflow warning on the way either
    msg, _ = refused(lambda: load_map({"bounds": bounds, "resolution": res}))
    assert "more cells than can be counted" in msg and "coarser 'resolution'" in msg


def test_office_map_over_budget_is_refused() -> None:
    msg, _ = refused(lambda: office_map(200.0))
    assert msg.startswith("office_map(size=200") and "16,000,000 cells" in msg


@pytest.mark.parametrize(
    ("image", "suffix"),
    [
        (b"P5\n5000 4000\n255\n", ".pgm"),  # no pixel data: only the header is read
        (b"P2\n5000 4000\n65535\n0 0 0\n", ".pgm"),
        (png_header_only(5000, 4000), ".png"),
    ],
)
def test_ros_image_over_budget_is_refused_from_its_header(
    tmp_path: Path, image: bytes, suffix: str
) -> None:
    path = ros_map(tmp_path, image, suffix)
    msg, peak = refused(lambda: load_map(path))
    assert msg.startswith(f"{path}: 'image' ({tmp_path / ('img' + suffix)}): "), msg
    assert "5,000 × 4,000 = 20,000,000 cells" in msg
    assert "crop the image" in msg and "downsample" in msg
    assert peak < 1_000_000


def test_ros_image_far_over_budget_is_refused(tmp_path: Path) -> None:
    # Pillow itself refuses images above twice its own limit before we see the size.
    path = ros_map(tmp_path, b"P5\n30000 30000\n255\n")
    msg, peak = refused(lambda: load_map(path))
    assert "far larger than the map budget of 10,000,000 cells" in msg
    assert "crop the image" in msg and peak < 1_000_000


def test_oversized_map_file_is_refused_before_reading(tmp_path: Path) -> None:
    f = tmp_path / "huge.yaml"
    with f.open("wb") as fh:
        fh.truncate(MAX_MAP_FILE_BYTES + 2**20)  # sparse: nothing is written
    msg, peak = refused(lambda: load_map(f))
    assert msg.startswith(f"{f}: the file is 17 MiB") and "at most 16 MiB" in msg
    assert peak < 1_000_000


# ----------------------------------------------------------------------------------------
# Unreadable map files and images
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "needles"),
    [
        ("name: café\n".encode("latin-1"), ["not UTF-8 text", "0xe9 at offset 9", "UTF-8"]),
        (b"\xff\xfe" + "bounds: 1".encode("utf-16-le"), ["not UTF-8 text", "offset 0"]),
        (b"\x89PNG\r\n\x1a\n\x00\x00", ["not a text file", "not its image"]),
        (b"- 1\n- 2\n", ["must hold a mapping", "'image'", "'bounds'", "got list"]),
        (b"just a string\n", ["must hold a mapping", "got str"]),
        (b"42\n", ["must hold a mapping", "got int"]),
        (b"", ["the file is empty", "'image'", "'bounds'"]),
        (b"# only a comment\n", ["the file is empty"]),
        (b"bounds: [[0, 0], [1, 1]\n", ["not valid YAML/JSON", "line", "fix the syntax"]),
        (b"{'bounds': }}", ["not valid YAML/JSON"]),
    ],
)
def test_unreadable_map_files(tmp_path: Path, data: bytes, needles: list[str]) -> None:
    f = tmp_path / "m.yaml"
    f.write_bytes(data)
    msg, _ = refused(lambda: load_map(f))
    assert msg.startswith(f"{f}: "), msg
    for needle in needles:
        assert needle in msg, msg


def test_missing_image_and_image_that_is_a_folder(tmp_path: Path) -> None:
    path = ros_map(tmp_path, b"", image="nowhere/img.pgm")
    msg, _ = refused(lambda: load_map(path))
    assert msg == (
        f"{path}: 'image': file {tmp_path / 'nowhere' / 'img.pgm'} not found; a relative path "
        "is taken from the folder of map.yaml"
    )
    (tmp_path / "dir.pgm").mkdir()
    path = ros_map(tmp_path, b"", image="dir.pgm")
    msg, _ = refused(lambda: load_map(path))
    assert f"{tmp_path / 'dir.pgm'} is a folder, not a file" in msg


GIF = b"GIF89a\x01\x00\x01\x00\x00\x00\x00;"


@pytest.mark.parametrize(
    ("image", "needles"),
    [
        (b"\xff\xd8\xff\xe0\x00\x10JFIF\x00", ["unsupported image format", "PGM or PNG"]),
        (GIF, ["unsupported image format", "convert the image"]),
        (b"hello, world", ["unsupported image format"]),
        (b"P5\n3 2\n255\n\x00", ["cannot decode the PGM", "truncated", "re-export"]),
        (png_header_only(3, 2), ["cannot decode the PNG", "re-export"]),
        (b"\x89PNG\r\n\x1a\n" + bytes(30), ["corrupt or truncated PNG"]),
        (b"Pf\n2 2\n-1.0\n" + bytes(16), ["unsupported pixel format 'F'"]),
    ],
)
def test_images_pillow_cannot_read(tmp_path: Path, image: bytes, needles: list[str]) -> None:
    path = ros_map(tmp_path, image)
    msg, _ = refused(lambda: load_map(path))
    assert msg.startswith(f"{path}: 'image' ({tmp_path / 'img.pgm'}): "), msg
    for needle in needles:
        assert needle in msg, msg


# ----------------------------------------------------------------------------------------
# Invalid numbers
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"resolution": "0"}, "'resolution' must be a positive number (m), got 0"),
        ({"resolution": "-0.05"}, "'resolution' must be a positive number (m), got -0.05"),
        ({"resolution": ".nan"}, "'resolution' must be a finite number (m), got nan"),
        ({"resolution": ".inf"}, "'resolution' must be a finite number (m), got inf"),
        (
            {"origin": "[.nan, 0, 0]"},
            "'origin' must be a list of 3 numbers [x, y, yaw] (m, m, rad) (finite), "
            "got [nan, 0, 0]",
        ),
        ({"origin": "[0, -.inf, 0]"}, "'origin' must be a list of 3 numbers [x, y, yaw]"),
        ({"origin": "[0, 0, .nan]"}, "(finite), got [0, 0, nan]"),
        ({"occupied_thresh": ".nan"}, "'occupied_thresh' must be a finite number, got nan"),
        ({"free_thresh": ".nan"}, "'free_thresh' must be a finite number, got nan"),
    ],
)
def test_ros_numbers(tmp_path: Path, fields: dict[str, str], message: str) -> None:
    path = ros_map(tmp_path, b"P5\n2 2\n255\n\xfe\xfe\xfe\xfe", **fields)
    msg, _ = refused(lambda: load_map(path))
    assert msg.startswith(f"{path}: '"), msg
    assert message in msg, msg


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"resolution": 0.0}, "'resolution' must be a positive number (m), got 0.0"),
        ({"resolution": -0.1}, "'resolution' must be a positive number (m), got -0.1"),
        ({"resolution": float("nan")}, "'resolution' must be a finite number (m), got nan"),
        ({"resolution": float("inf")}, "'resolution' must be a finite number (m), got inf"),
        (
            {"bounds": [[0, 0], [float("nan"), 1]]},
            "'bounds[1]' must be a list of 2 numbers [x, y] (m) (finite), got [nan, 1]",
        ),
        (
            {"bounds": [[0, float("-inf")], [1, 1]]},
            "'bounds[0]' must be a list of 2 numbers [x, y] (m) (finite), got [0, -inf]",
        ),
        (
            {"obstacles": [{"circle": {"center": [0.5, 0.5], "radius": float("nan")}}]},
            "'obstacles[0].circle.radius' must be a finite number (m), got nan",
        ),
        (
            {"obstacles": [{"polygon": {"points": [[0, 0], [1, float("nan")], [1, 1]]}}]},
            "'obstacles[0].polygon.points[1]' must be a list of 2 numbers [x, y] (m) (finite), "
            "got [1, nan]",
        ),
    ],
)
def test_inline_numbers(doc: dict[str, Any], message: str) -> None:
    msg, _ = refused(lambda: load_map({"bounds": [[0, 0], [1, 1]], **doc}))
    assert msg == f"inline map: {message}", msg


def test_every_refusal_is_a_gracenav_error() -> None:
    assert issubclass(MapError, GracenavError) and issubclass(MapError, ValueError)
    with pytest.raises(GracenavError):
        load_map({"bounds": [[0, 0], [200, 200]]})
    assert np.isfinite(MAP_BYTES_PER_CELL)


def test_shapes_with_huge_coordinates_are_refused() -> None:
    # found by fuzzing: the polygon checks multiplied these into an overflow
    with pytest.raises(MapError, match=r"polygon point 2 .* is beyond ±1e\+12 m"):
        Polygon(((0.0, 0.0), (0.0, 1.0), (0.0, 1.3407807929942597e154)))
    with pytest.raises(MapError, match="rectangle min must be finite"):
        Rectangle((10**400, 0.0), (1.0, 1.0))
    with pytest.raises(MapError, match="circle radius must be a positive, finite number"):
        Circle((0.0, 0.0), 10**400)
    with pytest.raises(MapError, match="up to 1e\\+12"):
        Circle((0.0, 0.0), 2e12)
    msg, _ = refused(
        lambda: load_map(
            {
                "bounds": [[0, 0], [1, 1]],
                "obstacles": [{"polygon": {"points": [[0, 0], [0, 1], [0, 1e154]]}}],
            }
        )
    )
    assert msg == (
        "inline map: 'obstacles[0].polygon.points[2]' entries must be within ±1e+12, "
        "got [0, 1e+154]"
    )


def test_duplicate_keys_in_a_map_file_are_errors(tmp_path) -> None:
    """The same strict YAML reading as scenario and parameter files."""
    path = tmp_path / "dup.yaml"
    path.write_text("bounds: [[0, 0], [3, 3]]\nresolution: 0.05\nresolution: 0.1\n")
    with pytest.raises(MapError, match=r"duplicate key 'resolution' \(first at line 2\)"):
        load_map(path)
    ros = tmp_path / "ros.yaml"
    ros.write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\nnegate: 1\n")
    with pytest.raises(MapError, match="duplicate key 'negate'"):
        load_map(ros)


def test_polygons_over_the_point_limit_are_refused_before_the_pair_check() -> None:
    # the simplicity check compares every pair of edges: quadratic in the point count
    points = tuple((float(k), float(k % 2)) for k in range(MAX_POLYGON_POINTS + 1))
    with pytest.raises(MapError) as info:
        Polygon(points)
    assert str(info.value) == (
        f"a polygon has at most {MAX_POLYGON_POINTS} points, got {MAX_POLYGON_POINTS + 1}; "
        "split it into several polygons or simplify its outline"
    )
    doc = {"bounds": [[0, 0], [1, 1]], "obstacles": [{"polygon": {"points": list(points)}}]}
    msg, _ = refused(lambda: load_map(doc))
    assert msg == (
        f"inline map: 'obstacles[0].polygon.points' has {MAX_POLYGON_POINTS + 1} entries; at "
        f"most {MAX_POLYGON_POINTS} are allowed; split the polygon into several or simplify "
        "its outline"
    )


def test_the_name_is_checked_when_given_and_the_file_stem_is_not(tmp_path: Path) -> None:
    f = tmp_path / ("m" * 240 + ".yaml")  # longer than a given name may be
    f.write_text("bounds: [[0, 0], [1, 1]]\n")
    assert load_map(f).name == "m" * 240
    f.write_text('bounds: [[0, 0], [1, 1]]\nname: "lab\\e[2J"\n')
    msg, _ = refused(lambda: load_map(f))
    assert msg == (
        f"{f}: 'name' must be a non-empty one-line string of at most 200 characters without "
        "control characters, got 'lab\\x1b[2J'"
    )
