"""ROS map_server maps: the YAML description and its image, read and written.

A map_server map is a YAML file naming an image, read with map_server's threshold
semantics (trinary / scale / raw modes, ``negate``, ``occupied_thresh``,
``free_thresh``). Images are decoded by Pillow: PNG (gray, gray + alpha, RGB, RGBA or
palette; 1 to 16 bit) and netpbm (PGM P2/P5 of any maxval up to 65535, PBM, PPM). Image
row 0 is the *top* of the map and is flipped on loading so that grid row 0 is the lowest
y.
"""

from __future__ import annotations

import io
import json
import os
import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, Literal, TypeAlias

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageFile

from gracenav._util.io import atomic_write_bytes, atomic_write_text
from gracenav._util.validate import Fields
from gracenav.errors import ConfigError, MapError
from gracenav.world.geometry import BoolArray
from gracenav.world.occupancy import MAX_MAP_CELLS, WorldMap, check_map_budget

__all__ = ["map_from_ros_yaml", "save_ros_map"]

_ROS_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")
_ROS_MODES = ("trinary", "scale", "raw")

# ----------------------------------------------------------------------------------------
# Images
# ----------------------------------------------------------------------------------------

_IMAGE_FORMATS = ("PNG", "PPM")  # Pillow's names; its PPM plugin reads PBM, PGM and PPM

Pixels: TypeAlias = NDArray[np.uint16]

_TOO_LARGE = (
    "crop the image to the area the robot uses (map_server maps are often mostly unknown "
    "space), or downsample it and scale 'resolution' to match"
)

_NETPBM_KINDS = {b"P1": "PBM", b"P4": "PBM", b"P2": "PGM", b"P5": "PGM", b"P3": "PPM", b"P6": "PPM"}


def _kind(data: bytes) -> str:
    """What the first bytes of an image file claim it is, for error messages."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "PNG"
    return _NETPBM_KINDS.get(data[:2], "image")


def _declared_maxval(im: ImageFile.ImageFile) -> int | None:
    """The maxval a PGM/PPM header declared, or None if Pillow kept the values as stored.

    Pillow rescales netpbm values to 0..255 (maxval < 256) or 0..65535 with rounding, and
    keeps the declared maxval only in the arguments of its "ppm" / "ppm_plain" decoders
    (``tile[0]`` = (decoder, box, offset, (rawmode, maxval))). Read before ``load()``.
    """
    if im.format != "PPM" or not im.tile:
        return None
    args = im.tile[0][3]
    if isinstance(args, tuple) and len(args) == 2 and isinstance(args[1], int):
        return int(args[1])
    return None


def _pixels(im: Image.Image, declared: int | None, where: str) -> tuple[Pixels, int, bool]:
    """Pixels (h, w, channels), white level and has-alpha of a loaded Pillow image."""
    mode = im.mode
    if mode == "1":
        return np.asarray(im.convert("L"), dtype=np.uint16)[:, :, None], 255, False
    if mode == "P":
        index = np.asarray(im)
        palette = np.array(im.getpalette("RGB") or [], dtype=np.uint16).reshape(-1, 3)
        if index.size and int(index.max()) >= len(palette):
            raise MapError(
                f"{where}: corrupt PNG (palette index {int(index.max())} beyond its "
                f"{len(palette)} colours); re-export the image"
            )
        return palette[index], 255, False  # transparency is ignored, as map_server does
    if mode in ("L", "LA", "RGB", "RGBA"):
        full = 255
    elif mode in ("I", "I;16", "I;16B", "I;16L"):
        full = 65535
    else:
        raise MapError(
            f"{where}: unsupported pixel format {mode!r}; save the map as an 8 or 16 bit "
            "gray, RGB or RGBA PNG, or as a PGM"
        )
    values = np.asarray(im)
    if values.ndim == 2:
        values = values[:, :, None]
    if declared is not None and declared != full and mode in ("L", "I"):
        # Undo Pillow's rescaling v' = round(v · full / declared): exact, since
        # full / declared > 1 spaces the rescaled levels at least one apart.
        values = np.rint(values * (declared / full))
        full = declared
    return values.astype(np.uint16), full, mode in ("LA", "RGBA")


def _decode_image(source: bytes | Path, where: str) -> tuple[Pixels, int, bool]:
    """Decode a PNG or netpbm image: a file, or its bytes.

    Returns
    -------
    pixels : ndarray of uint16, shape (h, w, channels)
        Gray, gray + alpha, RGB or RGBA levels, row 0 the top of the image. Palette
        images come back as RGB; bitmaps and 2- and 4-bit gray PNGs scaled to 0..255;
        16-bit RGB(A) PNGs as their high bytes (Pillow keeps 8 bits per colour channel,
        as map_server's libpng reader does).
    maxval : int
        The white level: 255, 65535 or a PGM's declared maxval.
    has_alpha : bool
        Whether the last channel is opacity.

    Raises
    ------
    MapError
        If the image is not a PNG or netpbm image, is corrupt or truncated, or is larger
        than the map budget (checked from its header, before decoding).
    """
    try:
        fp: IO[bytes] = source.open("rb") if isinstance(source, Path) else io.BytesIO(source)
    except OSError as exc:
        raise MapError(f"{where}: cannot read the file ({exc.strerror})") from None
    with fp:
        kind = _kind(fp.read(8))
        fp.seek(0)
        im = _open_image(fp, kind, where)
        with im:
            w, h = im.size
            if w < 1 or h < 1:
                raise MapError(f"{where}: the image is empty ({w} × {h} pixels); re-export it")
            check_map_budget(h, w, where, _TOO_LARGE)
            declared = _declared_maxval(im)
            try:
                im.load()
            except Exception as exc:  # Pillow raises many types on corrupt pixel data
                raise MapError(
                    f"{where}: cannot decode the {kind} ({exc}); the file is corrupt or "
                    "truncated, re-export it"
                ) from None
            return _pixels(im, declared, where)


def _open_image(fp: IO[bytes], kind: str, where: str) -> ImageFile.ImageFile:
    """Pillow's lazy image (header read, no pixels decoded) of the PNG or netpbm in ``fp``."""
    with warnings.catch_warnings():
        # The caller checks the size against the map budget before any pixel is decoded.
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        try:
            return Image.open(fp, formats=_IMAGE_FORMATS)
        except Image.DecompressionBombError as exc:
            raise MapError(
                f"{where}: the image is far larger than the map budget of {MAX_MAP_CELLS:,} "
                f"cells ({exc}); {_TOO_LARGE}"
            ) from None
        except Image.UnidentifiedImageError:
            if kind != "image":
                raise MapError(
                    f"{where}: corrupt or truncated {kind} (its header cannot be read); "
                    "re-export the image"
                ) from None
            raise MapError(
                f"{where}: unsupported image format (expected a PGM or PNG image, or "
                "another netpbm P1–P6 image); convert the image to PGM or PNG"
            ) from None
        except Exception as exc:  # Pillow raises many types on corrupt headers
            raise MapError(f"{where}: corrupt {kind} header ({exc}); re-export the image") from None


# ----------------------------------------------------------------------------------------
# ROS map_server maps
# ----------------------------------------------------------------------------------------


def map_from_ros_yaml(doc: Mapping[Any, Any], path: Path) -> WorldMap:
    """Check a map_server YAML document read from ``path`` and load the image it names.

    The fields are read with :class:`gracenav._util.validate.Fields`; the image path is
    relative to ``path``'s folder (or absolute), as map_server reads it.

    Raises
    ------
    MapError
        If a field is missing or invalid, or the image is missing or unreadable; the
        message names ``path`` and the field.
    """
    where = str(path)
    f = Fields(doc, "", where, error=MapError)
    f.check_keys(_ROS_KEYS)
    res = f.number("resolution", positive=True, unit="m")
    ox, oy, yaw = f.vector("origin", 3, what="[x, y, yaw] (m, m, rad)")
    if yaw != 0.0:
        raise f.fail(
            f"'origin' has yaw {yaw:g} rad; rotated maps are unsupported: rotate the image so "
            "the map axes align with the world and set yaw to 0"
        )
    negate = f.integer("negate", minimum=0, maximum=1)
    occ_th = f.number("occupied_thresh", minimum=0.0, maximum=1.0)
    free_th = f.number("free_thresh", minimum=0.0, maximum=1.0)
    if occ_th <= free_th:
        raise f.fail(
            f"'occupied_thresh' ({occ_th:g}) must exceed 'free_thresh' ({free_th:g}); "
            "typical values are 0.65 and 0.196"
        )
    mode = f.choice("mode", _ROS_MODES, "trinary")
    image_path = f.file("image", path.parent)
    pixels, maxval, has_alpha = _decode_image(image_path, f"{where}: 'image' ({image_path})")
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
    pixels: Pixels,
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
    if colour == 1 and use == 2:  # gray + alpha: the gray counts as R, G and B
        mean = (3.0 * pixels[:, :, 0] + pixels[:, :, 1]) / 4.0
    else:  # sums of integer levels are exact in float64
        mean = pixels[:, :, :use].sum(axis=2, dtype=np.float64) / use
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
    image_format: Literal["pgm", "png"] = "pgm",
) -> Path:
    """Write ``world_map`` as a ROS map_server map: ``path`` (YAML) and an image beside it.

    Occupied cells are written 0, unknown 205 and free 254 (map_saver's levels) with
    ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``, so
    :func:`load_map` reads back the same grid.

    Parameters
    ----------
    world_map : WorldMap
        The map to save.
    path : str or path-like
        The YAML file; the image is written next to it with the suffix of its format.
    image_format : {"pgm", "png"}
        An 8-bit binary PGM (P5, as map_saver writes) or an 8-bit gray PNG.

    Returns
    -------
    Path
        The image file written.
    """
    if image_format not in ("pgm", "png"):
        raise ConfigError(f"image_format must be 'pgm' or 'png', got {image_format!r}")
    yaml_path = Path(path)
    image_path = yaml_path.with_suffix(f".{image_format}")
    img = np.full(world_map.grid_shape, 254, dtype=np.uint8)
    img[world_map.occupied] = 0
    if world_map.unknown is not None:
        img[world_map.unknown] = 205
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img[::-1])).save(
        buf, format="PPM" if image_format == "pgm" else "PNG"
    )
    atomic_write_bytes(image_path, buf.getvalue())
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
