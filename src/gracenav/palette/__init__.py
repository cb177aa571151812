"""The motion policy palette Π(Σ): verified policies stored as a versioned data file.

A palette file is a single ``.npz`` archive (no pickle) holding a JSON header
and the sampled primitives of every policy. The header carries a key, a hash
of everything the palette is built from (robot parameters, the controller's
design inputs, verification options, distance parameter d, primitive set
options, file format and algorithm version: inputs only, never a computed
float), and the designed gains, which are compared within a tolerance when
the palette is loaded. Loading checks the archive's integrity and the key; a
stale, corrupt or mismatched file is never used: :func:`load_palette` builds
and caches a matching palette, or raises :class:`gracenav.errors.CacheError`
for a file the user forced. Files are written atomically.

Modules: :mod:`~gracenav.palette.palette` (the palette and its storage),
:mod:`~gracenav.palette.files` (keys, shipped and cached files, loading),
:mod:`~gracenav.palette.build` (sizing and verifying every policy),
:mod:`~gracenav.palette.limits` (the limits a palette is built to, stated once).
"""

from gracenav.palette.build import (
    build_palette,
)
from gracenav.palette.files import (
    GAINS_RTOL,
    PALETTE_ENV,
    SHIPPED_PALETTES,
    build_palette_for,
    cached_palette_path,
    forget_read_palettes,
    load_palette,
    palette_file,
    shipped_palette_path,
)
from gracenav.palette.limits import PaletteLimits, catch_speeds_for
from gracenav.palette.palette import (
    PALETTE_FORMAT,
    REGULATOR_NAME,
    Palette,
    palette_key,
)

__all__ = [
    "GAINS_RTOL",
    "PALETTE_ENV",
    "PALETTE_FORMAT",
    "REGULATOR_NAME",
    "SHIPPED_PALETTES",
    "Palette",
    "PaletteLimits",
    "build_palette",
    "build_palette_for",
    "cached_palette_path",
    "catch_speeds_for",
    "forget_read_palettes",
    "load_palette",
    "palette_file",
    "palette_key",
    "shipped_palette_path",
]
