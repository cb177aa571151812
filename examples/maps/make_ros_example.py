"""Regenerate the ROS map_server example (lab_ros.yaml + lab_ros.pgm).

A 3 m x 3 m room with 0.1 m walls, a table and a pillar, surrounded by a 0.5 m
band of unknown space (as a SLAM map would show it), at 0.05 m per cell.

Usage: python examples/maps/make_ros_example.py [OUTPUT_DIR]   (default: this folder)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gracenav.world import Circle, Rectangle, Shape, WorldMap, load_map, save_ros_map


def build() -> WorldMap:
    """The example lab as a map with an unknown border."""
    walls: list[Shape] = [
        Rectangle((0.0, 0.0), (3.0, 0.1)),
        Rectangle((0.0, 2.9), (3.0, 3.0)),
        Rectangle((0.0, 0.0), (0.1, 3.0)),
        Rectangle((2.9, 0.0), (3.0, 1.8)),  # east wall with a 0.8 m doorway
        Rectangle((2.9, 2.6), (3.0, 3.0)),
    ]
    furniture: list[Shape] = [Rectangle((0.6, 1.9), (1.6, 2.4)), Circle((2.0, 1.0), 0.15)]
    room = WorldMap.from_shapes([[-0.5, -0.5], [3.5, 3.5]], [*walls, *furniture], name="lab")
    centers = room.cell_centers()
    inside = np.all((centers >= 0.0) & (centers <= 3.0), axis=-1)
    unknown = ~inside & ~room.occupied
    return WorldMap(
        room.origin, room.resolution, room.occupied | unknown, name="lab", unknown=unknown
    )


def main(argv: list[str]) -> int:
    out = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parent
    yaml_path = out / "lab_ros.yaml"
    save_ros_map(build(), yaml_path)
    lab = load_map(yaml_path)
    print(f"wrote {yaml_path}: {lab}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
