"""Regenerate the generated example maps as ROS map_server files (YAML + PNG):

* ``forest_ros``: a 4.5 m x 16 m field of 0.15 m posts (seed 0), traversable by a
  0.2 m footprint from x = 1 m to x = 15 m;
* ``warehouse_ros``: a 30 m x 50 m warehouse at 3 cm (seed 0): shelves with unknown
  insides, aisles of 1.0-2.5 m, a cross aisle, pillars;
* ``office_ros``: a 20 m office floor at 5 cm with 0.8 m doors (seed 0).

Usage: python examples/maps/make_generated_maps.py [OUTPUT_DIR]   (default: this folder)
"""

from __future__ import annotations

import sys
from pathlib import Path

from gracenav.world import WorldMap, forest_map, office_map, save_ros_map, warehouse_map


def maps() -> dict[str, WorldMap]:
    """The maps by file stem."""
    return {
        "forest_ros": forest_map(seed=0),
        "warehouse_ros": warehouse_map(30.0, 50.0, resolution=0.03, seed=0),
        "office_ros": office_map(20.0, resolution=0.05, seed=0, door=0.8),
    }


def main(argv: list[str]) -> int:
    out = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parent
    for stem, world in maps().items():
        image = save_ros_map(world, out / f"{stem}.yaml", image_format="png")
        print(f"wrote {out / (stem + '.yaml')} and {image}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
