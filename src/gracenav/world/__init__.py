"""The world the robot navigates: occupancy-grid maps and their sources.

A :class:`WorldMap` is a 2D occupancy grid (paper Sec. IV-A: motion policies are
instantiated on a map M and kept only where they are obstacle free). It comes from

* a ROS ``map_server`` map: a YAML file naming a PGM or PNG image, read with
  map_server's threshold semantics (:mod:`~gracenav.world.ros_map`); or
* inline geometry: map bounds and rectangle / circle / polygon obstacles in metres
  (:mod:`~gracenav.world.geometry`), given as a mapping or a YAML/JSON file
  (:mod:`~gracenav.world.inline`), rasterised at a chosen resolution
  (:mod:`~gracenav.world.occupancy`); the exact shapes are kept for plotting; or
* seeded synthetic offices, forests and warehouses of :mod:`~gracenav.world.synthetic`.

:func:`load_map` reads any of the first two. Every map is held to a budget of
:data:`MAX_MAP_CELLS` cells, checked before its grid or image is allocated.
"""

from __future__ import annotations

from gracenav.world.geometry import (
    MAX_COORDINATE,
    MAX_POLYGON_POINTS,
    Circle,
    Polygon,
    Rectangle,
    Shape,
)
from gracenav.world.loading import MAX_MAP_FILE_BYTES, load_map
from gracenav.world.moving import MovingObstacle
from gracenav.world.occupancy import DEFAULT_RESOLUTION, MAP_BYTES_PER_CELL, MAX_MAP_CELLS, WorldMap
from gracenav.world.ros_map import save_ros_map
from gracenav.world.synthetic import footprint_connected, forest_map, office_map, warehouse_map

__all__ = [
    "DEFAULT_RESOLUTION",
    "MAP_BYTES_PER_CELL",
    "MAX_COORDINATE",
    "MAX_MAP_CELLS",
    "MAX_MAP_FILE_BYTES",
    "MAX_POLYGON_POINTS",
    "Circle",
    "MovingObstacle",
    "Polygon",
    "Rectangle",
    "Shape",
    "WorldMap",
    "footprint_connected",
    "forest_map",
    "load_map",
    "office_map",
    "save_ros_map",
    "warehouse_map",
]
