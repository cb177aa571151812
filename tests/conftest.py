"""Shared test set-up: single-threaded BLAS, headless plotting, a private cache, and
the palette and libraries several modules use.

The primitive cache (``gracenav.primitives.cache_dir``) and matplotlib's font cache go
to a temporary directory of this test session, never to the user's home.

The session fixtures are built once per session and shared by every module that asks
for them. Tests only read them: a library, a graph and a palette are frozen (their
arrays read-only); what their owners cache of them is derived
from them alone (a capture planner, terminal regulators, sparse matrices, placement
tables), so which test fills it first changes no result. A test that needs to change
one builds its own (e.g. with ``dataclasses.replace``).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
import yaml

if TYPE_CHECKING:  # gracenav (and numpy) are imported after the environment is set
    from gracenav.library import PolicyLibrary
    from gracenav.palette import Palette
    from gracenav.planning.graph import PreparesGraph

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

_CACHE = tempfile.mkdtemp(prefix="gracenav-test-cache-")
os.environ["GRACENAV_CACHE_DIR"] = _CACHE
os.environ.setdefault("MPLCONFIGDIR", os.path.join(_CACHE, "matplotlib"))

#: The 5 m room with a central 1 m box (examples/maps/room_5m_box.yaml, inline).
BOX_ROOM = {
    "bounds": [[0.0, 0.0], [5.0, 5.0]],
    "resolution": 0.05,
    "obstacles": [{"rectangle": {"min": [2.0, 2.0], "max": [3.0, 3.0]}}],
}


def pytest_unconfigure(config: object) -> None:
    shutil.rmtree(_CACHE, ignore_errors=True)


@pytest.fixture(scope="session")
def palette() -> Palette:
    """The shipped palette (``load_palette()``)."""
    from gracenav.palette import load_palette

    return load_palette()


@pytest.fixture(scope="session")
def fig5_library(palette: Palette) -> PolicyLibrary:
    """The library of the paper's Fig. 5 map (fig5_point_to_point.yaml): footprint
    0.2 m, one halving, seed 0, the default stopping allowance."""
    from gracenav.library import build_library
    from gracenav.world import load_map

    scenarios = Path(str(resources.files("gracenav") / "data" / "scenarios"))
    doc = yaml.safe_load((scenarios / "fig5_point_to_point.yaml").read_text())
    return build_library(palette, load_map(doc["map"]), max_halvings=1)


@pytest.fixture(scope="session")
def fig5_graph(fig5_library: PolicyLibrary) -> PreparesGraph:
    from gracenav.planning.graph import build_graph

    return build_graph(fig5_library)


@pytest.fixture(scope="session")
def box_room_library(palette: Palette) -> PolicyLibrary:
    """The library of :data:`BOX_ROOM`: footprint 0.2 m, one halving, seed 0, the
    default stopping allowance."""
    from gracenav.library import build_library
    from gracenav.world import load_map

    return build_library(palette, load_map(BOX_ROOM), footprint_radius=0.2, max_halvings=1)


@pytest.fixture(scope="session")
def box_room_graph(box_room_library: PolicyLibrary) -> PreparesGraph:
    from gracenav.planning.graph import build_graph

    return build_graph(box_room_library)
