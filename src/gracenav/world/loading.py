"""One entry point for every map source: :func:`load_map`.

It tells the kinds of source apart (an inline mapping, a ROS map_server YAML file, an
inline-map YAML/JSON file), reads the file and hands the document to
:mod:`gracenav.world.inline` or :mod:`gracenav.world.ros_map`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from gracenav._util.io import StrictLoader, yaml_error_message
from gracenav.errors import MapError
from gracenav.world.inline import map_from_description
from gracenav.world.occupancy import INLINE, WorldMap
from gracenav.world.ros_map import map_from_ros_yaml

__all__ = ["MAX_MAP_FILE_BYTES", "load_map"]

#: Largest map description file (bytes) read: a YAML/JSON map is a few hundred bytes (a
#: ROS map) to a few hundred kilobytes (an inline map with many obstacles); a larger file
#: is almost certainly not a map description, and parsing it would take gigabytes.
MAX_MAP_FILE_BYTES = 16 * 2**20

_IMAGE_MAGIC = (b"\x89PNG", b"P1", b"P2", b"P3", b"P4", b"P5", b"P6", b"\xff\xd8", b"GIF8", b"BM")


def _read_bytes(path: Path, where: str) -> bytes:
    if not path.is_file():
        raise MapError(f"{where}: file not found; check the path")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise MapError(f"{where}: cannot read the file ({exc.strerror})") from None


def load_map(source: str | os.PathLike[str] | Mapping[str, Any]) -> WorldMap:
    """Load a map from a file or an inline description.

    Parameters
    ----------
    source : str, path-like or mapping
        * a mapping: inline geometry ``{"bounds": [[xmin, ymin], [xmax, ymax]],
          "obstacles": [...], "resolution": 0.05, "name": "..."}`` (m);
        * a YAML (or JSON) file holding either a ROS map_server description (key
          ``image``) or inline geometry (key ``bounds``).

    Returns
    -------
    WorldMap

    Raises
    ------
    MapError
        If the file is missing, not UTF-8, not a mapping, larger than
        :data:`MAX_MAP_FILE_BYTES` or malformed, or its image is missing or unreadable, or
        the map would exceed :data:`~gracenav.world.occupancy.MAX_MAP_CELLS` cells (checked
        before the grid or the image is allocated); the message names the file (or
        ``"inline map"``) and the offending field, and says how to fix it.

    Notes
    -----
    ROS maps follow map_server: ``image`` (relative to the YAML file's folder),
    ``resolution`` (m/cell), ``origin`` [x, y, yaw] (only yaw = 0 is supported),
    ``negate``, ``occupied_thresh``, ``free_thresh`` and optional ``mode`` (trinary,
    scale or raw). Unknown cells count as occupied. Obstacles of inline maps are
    ``{"rectangle": {"min": [x, y], "max": [x, y]}}``, ``{"circle": {"center": [x, y],
    "radius": r}}`` or ``{"polygon": {"points": [[x, y], ...]}}``, entirely inside the
    bounds; a cell is occupied iff its centre is inside some obstacle.
    """
    if isinstance(source, Mapping):
        return map_from_description(source, INLINE, "map")
    if not isinstance(source, str | os.PathLike):
        raise MapError(f"map source must be a file path or a mapping, got {type(source).__name__}")
    try:
        path = Path(source)
    except TypeError:
        raise MapError(f"map source {source!r} is not a valid path") from None
    where = str(path)
    try:
        size = path.stat().st_size if path.is_file() else 0
    except OSError:
        size = 0  # _read_bytes reports it
    if size > MAX_MAP_FILE_BYTES:
        raise MapError(
            f"{where}: the file is {size / 2**20:.0f} MiB; a map description (YAML/JSON) is at "
            f"most {MAX_MAP_FILE_BYTES // 2**20} MiB: give the map's YAML file, not its image"
        )
    data = _read_bytes(path, where)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        if data.startswith(_IMAGE_MAGIC):
            raise MapError(
                f"{where}: not a text file; give the map's YAML file, not its image"
            ) from None
        raise MapError(
            f"{where}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
            "save the map file as UTF-8"
        ) from None
    try:
        doc = yaml.load(text, Loader=StrictLoader)  # safe; duplicate keys are errors
    except yaml.YAMLError as exc:
        raise MapError(
            f"{where}: not valid YAML/JSON ({yaml_error_message(exc)}); fix the syntax"
        ) from None
    except (ValueError, RecursionError) as exc:
        raise MapError(f"{where}: not valid YAML/JSON ({exc}); fix the syntax") from None
    if doc is None:
        raise MapError(
            f"{where}: the file is empty; a map file holds a mapping with key 'image' (ROS "
            "map) or 'bounds' (inline geometry)"
        )
    if not isinstance(doc, Mapping):
        raise MapError(
            f"{where}: a map file must hold a mapping with key 'image' (ROS map) or "
            f"'bounds' (inline geometry), got {type(doc).__name__}"
        )
    has_image, has_bounds = "image" in doc, "bounds" in doc
    if has_image and has_bounds:
        raise MapError(
            f"{where}: has both 'image' (ROS map) and 'bounds' (inline geometry); keep one"
        )
    if has_image:
        return map_from_ros_yaml(doc, path)
    if has_bounds:
        return map_from_description(doc, where, path.stem)
    raise MapError(
        f"{where}: missing required key 'image' (ROS map) or 'bounds' (inline geometry); add one"
    )
