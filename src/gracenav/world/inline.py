"""Inline maps: a mapping (or a YAML/JSON document) of bounds and obstacle shapes.

The description is ``{"bounds": [[xmin, ymin], [xmax, ymax]], "obstacles": [...],
"resolution": 0.05, "name": "..."}`` in metres; each obstacle is
``{"rectangle": {"min": [x, y], "max": [x, y]}}``, ``{"circle": {"center": [x, y],
"radius": r}}`` or ``{"polygon": {"points": [[x, y], ...]}}``. This module reads the
description with :class:`gracenav._util.validate.Fields` (types, key paths) and hands the
shapes to :meth:`WorldMap.from_shapes`; the shapes check their own geometry (a rectangle's
corners in order, a simple polygon) and the grid its extent and budget.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from gracenav._util.validate import Fields
from gracenav.errors import MapError
from gracenav.world.geometry import (
    MAX_COORDINATE,
    MAX_POLYGON_POINTS,
    Circle,
    Polygon,
    Rectangle,
    Shape,
)
from gracenav.world.occupancy import DEFAULT_RESOLUTION, WorldMap

__all__ = ["map_from_description"]

_KEYS = ("bounds", "obstacles", "resolution", "name")
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "rectangle": ("min", "max"),
    "circle": ("center", "radius"),
    "polygon": ("points",),
}
_XY = "[x, y] (m)"


def _shape(item: Any, where: str, source: str) -> Shape:
    """The obstacle ``item`` at key path ``where`` (``obstacles[k]``)."""
    shape = Fields(
        item,
        where,
        source,
        error=MapError,
        expect="a mapping with one of the keys rectangle, circle, polygon",
    )
    kind, body = shape.variant(tuple(_SHAPE_KEYS))
    body.check_keys(_SHAPE_KEYS[kind])
    if kind == "rectangle":
        lo = body.vector("min", 2, bound=MAX_COORDINATE, what=_XY)
        hi = body.vector("max", 2, bound=MAX_COORDINATE, what=_XY)
        return _built(body, Rectangle, (lo[0], lo[1]), (hi[0], hi[1]))
    if kind == "circle":
        c = body.vector("center", 2, bound=MAX_COORDINATE, what=_XY)
        r = body.number("radius", positive=True, unit="m")  # Circle checks its upper limit
        return _built(body, Circle, (c[0], c[1]), r)
    pts = body.points(
        "points",
        max_len=MAX_POLYGON_POINTS,
        bound=MAX_COORDINATE,
        what="vertices [x, y] (m)",
        item=_XY,
        advice="split the polygon into several or simplify its outline",
    )
    return _built(body, Polygon, tuple((p[0], p[1]) for p in pts))


def _built(body: Fields, shape: Callable[..., Shape], *args: Any) -> Shape:
    """``shape(*args)``; its own geometry check (corners in order, a simple polygon) is
    refused under the key path of ``body``."""
    try:
        return shape(*args)
    except MapError as exc:
        raise body.fail(f"'{body.where}': {exc}") from None


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
        If a key is unknown or missing, or a value is invalid; the message names
        ``where`` and the key path (``'obstacles[2].circle.radius'``).
    """
    top = Fields(doc, "", where, error=MapError)
    top.check_keys(_KEYS)
    lo, hi = top.points(
        "bounds",
        min_len=2,
        max_len=2,
        what="corners [[xmin, ymin], [xmax, ymax]] (m)",
        item=_XY,
    )
    res = top.number("resolution", DEFAULT_RESOLUTION, positive=True, unit="m")
    name = top.string("name") if "name" in top.data else default_name  # the file's stem
    if top.get("obstacles", None) is None:  # "obstacles:" with nothing after it
        raw: list[Any] = []
    else:
        raw = top.items(
            "obstacles", what="shapes ({rectangle: ...}, {circle: ...}, {polygon: ...})"
        )
    shapes = [_shape(item, f"obstacles[{k}]", where) for k, item in enumerate(raw)]
    return WorldMap.from_shapes([lo, hi], shapes, resolution=res, name=name, source=where)
