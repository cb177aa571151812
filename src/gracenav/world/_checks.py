"""Checks shared by the map readers: field values of map descriptions and file reads.

Each check raises :class:`~gracenav.errors.MapError` with a message that starts with
``where`` (a file path or ``"inline map"``), names the field and says what to do.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gracenav.errors import MapError

__all__ = ["check_keys", "is_real", "pair_field", "positive_field", "read_bytes", "real_field"]


def is_real(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def real_field(value: object, where: str, name: str, unit: str = "") -> float:
    unit_txt = f" ({unit})" if unit else ""
    if not is_real(value):
        raise MapError(
            f"{where}: field '{name}' must be a number{unit_txt}, got {value!r}; "
            "write a plain number without quotes"
        )
    try:
        x = float(value)  # type: ignore[arg-type]
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise MapError(f"{where}: field '{name}' must be finite, got {x}")
    return x


def positive_field(value: object, where: str, name: str, unit: str) -> float:
    x = real_field(value, where, name, unit)
    if x <= 0.0:
        raise MapError(
            f"{where}: field '{name}' must be > 0 {unit}, got {x:g}; give a positive value"
        )
    return x


def pair_field(value: object, where: str, name: str) -> tuple[float, float]:
    if not isinstance(value, Sequence) or isinstance(value, str | bytes) or len(value) != 2:
        raise MapError(f"{where}: field '{name}' must be a pair [x, y] in m, got {value!r}")
    return (
        real_field(value[0], where, f"{name}[0]", "m"),
        real_field(value[1], where, f"{name}[1]", "m"),
    )


def check_keys(
    doc: Mapping[Any, Any],
    where: str,
    name: str,
    required: Sequence[str],
    optional: Sequence[str] = (),
) -> None:
    allowed = (*required, *optional)
    unknown = [k for k in doc if k not in allowed]
    if unknown:
        raise MapError(
            f"{where}: unknown key {unknown[0]!r} in {name}; allowed keys are "
            f"{', '.join(allowed)}; remove or rename it"
        )
    missing = [k for k in required if k not in doc]
    if missing:
        raise MapError(f"{where}: missing required key '{missing[0]}' in {name}; add it")


def read_bytes(path: Path, where: str) -> bytes:
    if not path.is_file():
        raise MapError(f"{where}: file not found; check the path")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise MapError(f"{where}: cannot read the file ({exc.strerror})") from None
