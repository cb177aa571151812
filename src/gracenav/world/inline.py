"""Inline maps: a mapping (or a YAML/JSON document) of bounds and obstacle shapes.

The description is ``{"bounds": [[xmin, ymin], [xmax, ymax]], "obstacles": [...],
"resolution": 0.05, "name": "..."}`` in metres; each obstacle is
``{"rectangle": {"min": [x, y], "max": [x, y]}}``, ``{"circle": {"center": [x, y],
"radius": r}}`` or ``{"polygon": {"points": [[x, y], ...]}}``. This module checks the
description field by field and hands the shapes to :meth:`WorldMap.from_shapes`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from gracenav.errors import MapError
from gracenav.world._checks import check_keys, pair_field, positive_field, real_field
from gracenav.world.geometry import Circle, Polygon, Rectangle, Shape
from gracenav.world.occupancy import DEFAULT_RESOLUTION, WorldMap

__all__ = ["map_from_description"]

_GEOMETRY_REQUIRED = ("bounds",)
_GEOMETRY_OPTIONAL = ("obstacles", "resolution", "name")
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "rectangle": ("min", "max"),
    "circle": ("center", "radius"),
    "polygon": ("points",),
}


def _shape_from_doc(item: object, where: str, name: str) -> Shape:
    if not isinstance(item, Mapping) or len(item) != 1:
        raise MapError(
            f"{where}: '{name}' must be a mapping with exactly one of the keys "
            f"rectangle, circle, polygon, got {item!r}"
        )
    ((kind, body),) = item.items()
    if kind not in _SHAPE_KEYS:
        raise MapError(
            f"{where}: '{name}' has unknown shape {kind!r}; use rectangle, circle or polygon"
        )
    field_name = f"{name}.{kind}"
    if not isinstance(body, Mapping):
        raise MapError(f"{where}: '{field_name}' must be a mapping, got {body!r}")
    check_keys(body, where, f"'{field_name}'", _SHAPE_KEYS[kind])
    try:
        if kind == "rectangle":
            return Rectangle(
                pair_field(body["min"], where, f"{field_name}.min"),
                pair_field(body["max"], where, f"{field_name}.max"),
            )
        if kind == "circle":
            center = pair_field(body["center"], where, f"{field_name}.center")
            radius = real_field(body["radius"], where, f"{field_name}.radius", "m")
            if radius <= 0.0:
                raise MapError(
                    f"{where}: field '{field_name}.radius' must be > 0 m, got {radius:g}; "
                    "give the circle a positive radius"
                )
            return Circle(center, radius)
        points = body["points"]
        if not isinstance(points, Sequence) or isinstance(points, str | bytes):
            raise MapError(
                f"{where}: field '{field_name}.points' must be a list of [x, y] pairs, "
                f"got {points!r}"
            )
        pts = tuple(pair_field(p, where, f"{field_name}.points[{k}]") for k, p in enumerate(points))
        return Polygon(pts)
    except MapError as exc:
        msg = str(exc)
        if msg.startswith(where):
            raise
        raise MapError(f"{where}: '{field_name}': {msg}") from None


def map_from_description(doc: Mapping[Any, Any], where: str, default_name: str) -> WorldMap:
    """Check an inline-map description and rasterise it.

    Parameters
    ----------
    doc : mapping
        The description (see the module docstring); lengths in m.
    where : str
        The file it came from, or ``"inline map"``; starts every error message.
    default_name : str
        The map's name when ``doc`` gives none.

    Raises
    ------
    MapError
        If a key is unknown or missing, or a value is invalid.
    """
    check_keys(doc, where, "the inline map", _GEOMETRY_REQUIRED, _GEOMETRY_OPTIONAL)
    bounds = doc["bounds"]
    if not isinstance(bounds, Sequence) or isinstance(bounds, str | bytes) or len(bounds) != 2:
        raise MapError(
            f"{where}: field 'bounds' must be [[xmin, ymin], [xmax, ymax]] in m, got {bounds!r}"
        )
    lo = pair_field(bounds[0], where, "bounds[0]")
    hi = pair_field(bounds[1], where, "bounds[1]")
    res = positive_field(doc.get("resolution", DEFAULT_RESOLUTION), where, "resolution", "m")
    name = doc.get("name", default_name)
    if not isinstance(name, str):
        raise MapError(f"{where}: field 'name' must be a string, got {name!r}")
    obstacles = doc.get("obstacles")
    if obstacles is None:
        obstacles = []
    if not isinstance(obstacles, Sequence) or isinstance(obstacles, str | bytes):
        raise MapError(f"{where}: field 'obstacles' must be a list of shapes, got {obstacles!r}")
    shapes = [_shape_from_doc(item, where, f"obstacles[{k}]") for k, item in enumerate(obstacles)]
    return WorldMap.from_shapes([lo, hi], shapes, resolution=res, name=name, source=where)
