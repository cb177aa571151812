"""ROS map_server maps: the YAML description and its image, read and written.

A map_server map is a YAML file naming a PGM (P2/P5, 8 or 16 bit) or PNG image, read
with map_server's threshold semantics (trinary / scale / raw modes, ``negate``,
``occupied_thresh``, ``free_thresh``). Image row 0 is the *top* of the map and is flipped
on loading so that grid row 0 is the lowest y.
"""

from __future__ import annotations

import json
import os
import re
import struct
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav._io import atomic_write_bytes, atomic_write_text
from gracenav.errors import ConfigError, MapError
from gracenav.world._checks import check_keys, positive_field, read_bytes, real_field
from gracenav.world.geometry import BoolArray
from gracenav.world.occupancy import _MAX_CELLS, WorldMap

__all__ = ["map_from_ros_yaml", "read_pgm", "save_ros_map", "write_pgm"]

_ROS_REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_ROS_OPTIONAL = ("mode",)
_ROS_MODES = ("trinary", "scale", "raw")

_WHITESPACE = b" \t\r\n\v\f"


def _pgm_header(data: bytes, where: str) -> tuple[bytes, int, int, int, int]:
    """(magic, width, height, maxval, offset of the pixel data)."""
    magic = data[:2]
    if magic not in (b"P2", b"P5"):
        raise MapError(
            f"{where}: not a PGM image (magic {magic!r}, expected P2 or P5); "
            "convert it to a grayscale PGM or PNG"
        )
    pos = 2
    values: list[int] = []
    names = ("width", "height", "maxval")
    while len(values) < 3:
        while pos < len(data):
            c = data[pos : pos + 1]
            if c in _WHITESPACE and c:
                pos += 1
            elif c == b"#":
                while pos < len(data) and data[pos : pos + 1] not in (b"\n", b"\r"):
                    pos += 1
            else:
                break
        start = pos
        while pos < len(data) and data[pos : pos + 1] not in _WHITESPACE + b"#":
            pos += 1
        token = data[start:pos]
        if not token:
            raise MapError(
                f"{where}: truncated PGM header (no {names[len(values)]}); the file is "
                "corrupt, re-export the image"
            )
        if not token.isdigit() or len(token) > 9:
            raise MapError(
                f"{where}: corrupt PGM header: {names[len(values)]} is {token[:20]!r}, "
                "expected a positive integer; re-export the image"
            )
        values.append(int(token))
    if pos >= len(data) or data[pos : pos + 1] not in _WHITESPACE:
        raise MapError(f"{where}: truncated PGM: no pixel data after the header; re-export it")
    width, height, maxval = values
    if width < 1 or height < 1:
        raise MapError(f"{where}: PGM has zero width or height ({width} × {height})")
    if not 1 <= maxval <= 65535:
        raise MapError(f"{where}: PGM maxval must be in 1..65535, got {maxval}")
    if width * height > _MAX_CELLS:
        raise MapError(f"{where}: PGM of {width} × {height} pixels is too large")
    return magic, width, height, maxval, pos + 1


def read_pgm(path: str | os.PathLike[str]) -> tuple[NDArray[np.uint16], int]:
    """Read a PGM image (binary P5 or ASCII P2, 8 or 16 bit).

    Parameters
    ----------
    path : str or path-like
        The image file.

    Returns
    -------
    image : ndarray of uint16, shape (height, width)
        Gray values, row 0 the top of the image.
    maxval : int
        The white level (1..65535).

    Raises
    ------
    MapError
        If the file is missing, corrupt, truncated or its size does not match its header.
    """
    p = Path(path)
    return _decode_pgm(read_bytes(p, str(p)), str(p))


def _decode_pgm(data: bytes, where: str) -> tuple[NDArray[np.uint16], int]:
    magic, w, h, maxval, off = _pgm_header(data, where)
    n = w * h
    if magic == b"P5":
        nbytes = 1 if maxval < 256 else 2
        body = data[off:]
        need = n * nbytes
        if len(body) < need:
            raise MapError(
                f"{where}: truncated PGM: the header says {w} × {h} pixels ({need} bytes) but "
                f"only {len(body)} bytes follow; the file is corrupt, re-export it"
            )
        if body[need:].strip(_WHITESPACE):
            raise MapError(
                f"{where}: PGM has {len(body) - need} bytes beyond the {w} × {h} pixels its "
                "header declares; the image dimensions are inconsistent, re-export it"
            )
        dtype = np.dtype(np.uint8) if nbytes == 1 else np.dtype(">u2")
        img = np.frombuffer(body, dtype=dtype, count=n).astype(np.uint16)
    else:
        text = b"\n".join(line.split(b"#", 1)[0] for line in data[off:].splitlines())
        tokens = text.split()
        if len(tokens) != n:
            what = "truncated" if len(tokens) < n else "inconsistent"
            raise MapError(
                f"{where}: {what} PGM: the header says {w} × {h} = {n} pixels but {len(tokens)} "
                "values follow; fix the header or re-export the image"
            )
        bad = next((t for t in tokens if not t.isdigit() or len(t) > 5), None)
        if bad is not None:
            raise MapError(
                f"{where}: corrupt PGM: pixel value {bad[:20]!r} is not an integer in "
                f"0..{maxval}; re-export the image"
            )
        img = np.array([int(t) for t in tokens], dtype=np.int64)
        if np.any(img > maxval):
            raise MapError(
                f"{where}: corrupt PGM: pixel values exceed maxval {maxval}; re-export the image"
            )
        img = img.astype(np.uint16)
    if np.any(img > maxval):
        raise MapError(
            f"{where}: corrupt PGM: pixel values exceed maxval {maxval}; re-export the image"
        )
    return img.reshape(h, w), maxval


def write_pgm(
    path: str | os.PathLike[str],
    image: ArrayLike,
    *,
    maxval: int | None = None,
    binary: bool = True,
) -> None:
    """Write a grayscale PGM image atomically.

    Parameters
    ----------
    path : str or path-like
        Output file.
    image : array_like of int, shape (height, width)
        Gray values in ``0..maxval``; row 0 is the top of the image.
    maxval : int, optional
        White level (1..65535); default 255, or 65535 if a value exceeds 255.
    binary : bool
        P5 (binary, big-endian for 16 bit) if True, else P2 (ASCII).
    """
    img = np.asarray(image)
    if img.ndim != 2 or img.size == 0 or not np.issubdtype(img.dtype, np.integer):
        raise ConfigError(f"PGM image must be a non-empty 2D integer array, got {img.shape}")
    if maxval is None:
        maxval = 255 if int(img.max()) <= 255 else 65535
    if not 1 <= maxval <= 65535 or int(img.min()) < 0 or int(img.max()) > maxval:
        raise ConfigError(f"PGM values must lie in 0..maxval with maxval in 1..65535 ({maxval})")
    h, w = img.shape
    header = f"{'P5' if binary else 'P2'}\n# gracenav map\n{w} {h}\n{maxval}\n".encode("ascii")
    if binary:
        body = img.astype(np.uint8 if maxval < 256 else ">u2").tobytes()
    else:
        body = "\n".join(" ".join(str(int(v)) for v in row) for row in img).encode() + b"\n"
    atomic_write_bytes(Path(path), header + body)


# PNG: decoded here with zlib and numpy instead of matplotlib.image.imread. imread (via
# Pillow, a dependency we do not take) returns normalised floats and, in matplotlib 3.11,
# mis-scales 2- and 4-bit grayscale images (values come back > 1); map thresholds need
# the exact integer gray levels. The decoder handles every non-interlaced PNG: gray,
# gray+alpha, RGB, RGBA and palette, 1–16 bit, all five row filters. The filters are
# undone along anti-diagonals (each pixel depends on its left, upper and upper-left
# neighbours only), so a 1000 × 1000 image takes ~2000 vectorised steps.

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}


def _png_unfilter(
    filtered: NDArray[np.uint8], ftype: NDArray[np.uint8], bpp: int
) -> NDArray[np.uint8]:
    """Undo PNG row filters. ``filtered`` (h, stride) bytes, ``ftype`` (h,), ``bpp`` bytes
    per pixel (>= 1); returns the reconstructed bytes (h, stride)."""
    h, stride = filtered.shape
    if not np.any(ftype):
        return filtered.copy()
    npx = stride // bpp
    f = filtered.reshape(h, npx, bpp).astype(np.int16)
    rec = np.zeros((h + 1, npx + 1, bpp), dtype=np.int16)  # zero row/column of padding
    ft = ftype.astype(np.int16)
    for d in range(h + npx - 1):
        r = np.arange(max(0, d - npx + 1), min(h, d + 1))
        c = d - r
        a = rec[r + 1, c]  # left
        b = rec[r, c + 1]  # up
        cc = rec[r, c]  # up-left
        pa, pb, pc = np.abs(b - cc), np.abs(a - cc), np.abs(a + b - 2 * cc)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, cc))
        t = ft[r][:, None]
        pred = np.select([t == 1, t == 2, t == 3, t == 4], [a, b, (a + b) >> 1, paeth], 0)
        rec[r + 1, c + 1] = (f[r, c] + pred) & 0xFF
    return rec[1:, 1:].reshape(h, stride).astype(np.uint8)


def _decode_png(data: bytes, where: str) -> tuple[NDArray[np.uint16], int, bool]:
    """Pixels (h, w, channels) as RGB(A)/gray(+alpha), maxval, and whether the last
    channel is alpha."""
    pos = len(_PNG_SIGNATURE)
    ihdr: bytes | None = None
    plte: bytes | None = None
    idat: list[bytes] = []
    while True:
        if pos + 8 > len(data):
            raise MapError(f"{where}: truncated PNG (no IEND chunk); re-export the image")
        length, ctype = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 12 + length
        if end > len(data):
            raise MapError(f"{where}: truncated PNG ({ctype!r} chunk cut short); re-export it")
        body = data[pos + 8 : pos + 8 + length]
        if zlib.crc32(ctype + body) != int.from_bytes(data[end - 4 : end], "big"):
            raise MapError(f"{where}: corrupt PNG (bad CRC in {ctype!r} chunk); re-export it")
        if ctype == b"IHDR":
            ihdr = body
        elif ctype == b"PLTE":
            plte = body
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            break
        pos = end
    if ihdr is None or len(ihdr) != 13 or not idat:
        raise MapError(f"{where}: corrupt PNG (missing IHDR or IDAT chunk); re-export it")
    w, h, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", ihdr)
    if color not in _PNG_CHANNELS or depth not in _PNG_DEPTHS[color] or comp or filt:
        raise MapError(
            f"{where}: corrupt PNG header (bit depth {depth}, colour type {color}); re-export it"
        )
    if interlace:
        raise MapError(
            f"{where}: interlaced (Adam7) PNG is not supported; save it without interlacing"
        )
    if w < 1 or h < 1 or w * h > _MAX_CELLS:
        raise MapError(f"{where}: PNG size {w} × {h} is empty or too large")
    channels = _PNG_CHANNELS[color]
    bits = depth * channels
    stride = (w * bits + 7) // 8
    expected = h * (stride + 1)
    try:
        inflater = zlib.decompressobj()
        raw = inflater.decompress(b"".join(idat), expected + 1)
    except zlib.error as exc:
        raise MapError(f"{where}: corrupt PNG image data ({exc}); re-export it") from None
    if len(raw) != expected:
        what = "truncated" if len(raw) < expected else "inconsistent"
        raise MapError(
            f"{where}: {what} PNG: {w} × {h} pixels need {expected} bytes of image data, "
            f"found {'more' if len(raw) > expected else len(raw)}; re-export the image"
        )
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(h, stride + 1)
    ftype = rows[:, 0]
    if np.any(ftype > 4):
        raise MapError(f"{where}: corrupt PNG (unknown row filter type); re-export it")
    rec = _png_unfilter(rows[:, 1:], ftype, max(1, bits // 8))
    if depth == 16:
        values = rec.view(">u2").astype(np.uint16)
    elif depth == 8:
        values = rec.astype(np.uint16)
    else:
        bitplanes = np.unpackbits(rec, axis=1).reshape(h, -1, depth)
        weights = (1 << np.arange(depth - 1, -1, -1)).astype(np.uint16)
        values = (bitplanes.astype(np.uint16) * weights).sum(axis=2, dtype=np.uint16)
    pixels = values[:, : w * channels].reshape(h, w, channels)
    maxval = (1 << depth) - 1
    if color == 3:
        if plte is None or len(plte) % 3 or not plte:
            raise MapError(f"{where}: corrupt PNG (palette image without a valid PLTE chunk)")
        palette = np.frombuffer(plte, dtype=np.uint8).reshape(-1, 3).astype(np.uint16)
        index = pixels[..., 0]
        if int(index.max()) >= len(palette):
            raise MapError(f"{where}: corrupt PNG (palette index out of range); re-export it")
        return palette[index], 255, False
    return pixels, maxval, color in (4, 6)


def _read_image(path: Path, where: str) -> tuple[NDArray[np.uint16], int, bool]:
    """Pixels (h, w, c), maxval and has-alpha of a PGM or PNG file (kind from its bytes)."""
    data = read_bytes(path, where)
    if data.startswith(_PNG_SIGNATURE):
        return _decode_png(data, where)
    if data[:2] in (b"P2", b"P5"):
        img, maxval = _decode_pgm(data, where)
        return img[:, :, None], maxval, False
    raise MapError(
        f"{where}: unsupported image format (expected a PGM P2/P5 or a PNG); "
        "convert the image to PGM or PNG"
    )


def map_from_ros_yaml(doc: Mapping[Any, Any], path: Path) -> WorldMap:
    """Check a map_server YAML document read from ``path`` and load the image it names.

    Raises
    ------
    MapError
        If a field is missing or invalid, or the image is missing or unreadable.
    """
    where = str(path)
    check_keys(doc, where, "the ROS map YAML", _ROS_REQUIRED, _ROS_OPTIONAL)
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise MapError(f"{where}: field 'image' must be an image file name, got {image!r}")
    res = positive_field(doc["resolution"], where, "resolution", "m")
    origin = doc["origin"]
    if not isinstance(origin, Sequence) or isinstance(origin, str | bytes) or len(origin) != 3:
        raise MapError(f"{where}: field 'origin' must be [x, y, yaw] (m, m, rad), got {origin!r}")
    ox = real_field(origin[0], where, "origin[0]", "m")
    oy = real_field(origin[1], where, "origin[1]", "m")
    yaw = real_field(origin[2], where, "origin[2]", "rad")
    if yaw != 0.0:
        raise MapError(
            f"{where}: field 'origin' has yaw {yaw:g} rad; rotated maps are unsupported: "
            "rotate the image so the map axes align with the world and set yaw to 0"
        )
    negate = doc["negate"]
    if negate not in (0, 1) or not isinstance(negate, int):
        raise MapError(f"{where}: field 'negate' must be 0 or 1, got {negate!r}")
    occ_th = real_field(doc["occupied_thresh"], where, "occupied_thresh")
    free_th = real_field(doc["free_thresh"], where, "free_thresh")
    for label, th in (("occupied_thresh", occ_th), ("free_thresh", free_th)):
        if not 0.0 <= th <= 1.0:
            raise MapError(f"{where}: field '{label}' must be in [0, 1], got {th:g}")
    if occ_th <= free_th:
        raise MapError(
            f"{where}: field 'occupied_thresh' ({occ_th:g}) must exceed 'free_thresh' "
            f"({free_th:g}); typical values are 0.65 and 0.196"
        )
    mode = doc.get("mode", "trinary")
    if mode not in _ROS_MODES:
        raise MapError(
            f"{where}: field 'mode' must be one of {', '.join(_ROS_MODES)}, got {mode!r}"
        )
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    image_where = f"{where}: field 'image' ({image_path})"
    if not image_path.is_file():
        raise MapError(
            f"{where}: field 'image': file {image_path} not found; the image path is relative "
            "to the YAML file's folder"
        )
    pixels, maxval, has_alpha = _read_image(image_path, image_where)
    occupied, unknown = _classify(pixels, maxval, has_alpha, bool(negate), occ_th, free_th, mode)
    return WorldMap(
        np.array([ox, oy]),
        res,
        occupied[::-1],
        name=path.stem,
        source=where,
        unknown=unknown[::-1],
    )


def _classify(
    pixels: NDArray[np.uint16],
    maxval: int,
    has_alpha: bool,
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
    mode: str,
) -> tuple[BoolArray, BoolArray]:
    """map_server's cell classification, in image orientation (row 0 at the top).

    The gray level is the mean of the colour channels (a gray image has one; the alpha
    channel, as opacity, joins the mean in trinary mode only, as map_server does).
    ``p = (maxval − mean) / maxval`` (``mean / maxval`` if negated); a cell is occupied if
    p > occupied_thresh, free if p < free_thresh, unknown otherwise. In raw mode the cell
    value is the (negated) gray level itself and only 0 is free. Returns (occupied or
    unknown, unknown), both (h, w).
    """
    channels = pixels.shape[2]
    colour = channels - 1 if has_alpha else channels
    use = channels if (has_alpha and mode == "trinary") else colour
    sel = pixels[:, :, :use].astype(np.float64)
    if colour == 1 and use == 2:  # gray + alpha: the gray counts as R, G and B
        mean = (3.0 * sel[:, :, 0] + sel[:, :, 1]) / 4.0
    else:
        mean = sel.sum(axis=2) / use
    if mode == "raw":
        value = maxval - mean if negate else mean
        free = value == 0.0
        return ~free, np.zeros_like(free)
    p = mean / maxval if negate else (maxval - mean) / maxval
    occ = p > occupied_thresh
    free = p < free_thresh
    unknown = ~occ & ~free
    return ~free, unknown


def save_ros_map(
    world_map: WorldMap,
    path: str | os.PathLike[str],
    *,
    binary: bool = True,
) -> Path:
    """Write ``world_map`` as a ROS map_server map: ``path`` (YAML) and a PGM beside it.

    Occupied cells are written 0, unknown 205 and free 254 (map_saver's levels) with
    ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``, so
    :func:`load_map` reads back the same grid.

    Parameters
    ----------
    world_map : WorldMap
        The map to save.
    path : str or path-like
        The YAML file; the image is written next to it with suffix ``.pgm``.
    binary : bool
        Binary P5 (default) or ASCII P2 PGM.

    Returns
    -------
    Path
        The image file written.
    """
    yaml_path = Path(path)
    image_path = yaml_path.with_suffix(".pgm")
    img = np.full(world_map.grid_shape, 254, dtype=np.uint16)
    img[world_map.occupied] = 0
    if world_map.unknown is not None:
        img[world_map.unknown] = 205
    write_pgm(image_path, img[::-1], maxval=255, binary=binary)
    name = image_path.name
    if not re.fullmatch(r"[A-Za-z0-9_.+-]+", name):
        name = json.dumps(name)  # a JSON string is a valid YAML scalar
    ox, oy = (float(v) for v in world_map.origin)
    text = (
        f"image: {name}\n"
        "mode: trinary\n"
        f"resolution: {world_map.resolution!r}\n"
        f"origin: [{ox!r}, {oy!r}, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )
    atomic_write_text(yaml_path, text)
    return image_path
