"""The palette: the verified policies of a robot and controller, built, stored and loaded."""

from gracenav.palette.palette import (
    GAINS_RTOL,
    PALETTE_ENV,
    PALETTE_FORMAT,
    REGULATOR_NAME,
    Palette,
    build_palette,
    build_palette_for,
    cached_palette_path,
    load_palette,
    palette_key,
    shipped_palette_path,
)

__all__ = [
    "GAINS_RTOL",
    "PALETTE_ENV",
    "PALETTE_FORMAT",
    "REGULATOR_NAME",
    "Palette",
    "build_palette",
    "build_palette_for",
    "cached_palette_path",
    "load_palette",
    "palette_key",
    "shipped_palette_path",
]
