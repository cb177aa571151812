"""Validation of user documents (scenarios, parameter files, maps): one reader, one style.

A :class:`Fields` wraps one mapping of a parsed document at a key path (``task``,
``disturbances[0]``) and reads typed values from it. Every failure is a
:class:`gracenav.errors.ConfigError` (or the subclass given as ``error``) whose one-line
message names the file, the full key path and the offending value, shortened::

    lab.yaml: 'task.starts[1]' must be a list of 4 numbers, got [0, 'a']

Numbers are Python ``int``/``float`` only (not ``bool``), finite, and within the bounds
the caller states; ranges appear in the message with their unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from gracenav.errors import ConfigError

__all__ = ["Fields", "as_number", "require_mapping", "show"]

_MISSING: Any = ...


def show(value: Any, limit: int = 40) -> str:
    """A short, user-facing rendering of a parsed value for error messages."""
    if value is None:
        return "null (nothing)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Mapping):
        return "a mapping" if value else "an empty mapping"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, int):
        if abs(value) < 10**15:
            return str(value)
        sign = "-" if value < 0 else ""
        return f"{sign}~1e{int(abs(value).bit_length() * math.log10(2))}"  # any size
    if isinstance(value, (list, tuple)):
        items = ", ".join(show(v, limit) for v in value[:5])
        text = f"[{items}{', ...' if len(value) > 5 else ''}]"
    elif isinstance(value, str):
        text = repr(value)
    else:
        text = f"a {type(value).__name__}"
    return text if len(text) <= limit else text[: limit - 4] + " ..."


def _kind(value: Any) -> str:
    if value is None:
        return "nothing (an empty document or null)"
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, (int, float)):
        return "a number"
    return f"a {type(value).__name__}"


def as_number(value: Any) -> float | None:
    """``value`` as a finite float, or None if it is not a finite int/float (bool excluded)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        f = float(value)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def require_mapping(
    data: Any, source: str, what: str, keys: Sequence[str], error: type[ConfigError] = ConfigError
) -> Mapping[Any, Any]:
    """The top level of a document must be a mapping; say which keys it should have.

    ``what`` names the document's kind in the message ("scenario", "parameter").
    """
    if isinstance(data, Mapping):
        return data
    raise error(
        f"{source}: expected a mapping of {what} keys ({', '.join(keys)}), got {_kind(data)}"
    )


class Fields:
    """Typed, path-aware access to one mapping of a parsed document.

    Parameters
    ----------
    data : Any
        The value at ``where``; it must be a mapping.
    where : str
        Key path of ``data`` in the document ("" for the top level).
    source : str
        The file (or "scenario", "parameters") named in messages.
    error : type of ConfigError
        Exception raised on invalid input.
    """

    def __init__(
        self, data: Any, where: str, source: str, *, error: type[ConfigError] = ConfigError
    ) -> None:
        self.error = error
        self.where = where
        self.source = source
        if not isinstance(data, Mapping):
            raise self.fail(f"'{where}' must be a mapping, got {_kind(data)}")
        self.data = data

    def fail(self, message: str) -> ConfigError:
        """The exception to raise for ``message`` (prefixed with the source)."""
        return self.error(f"{self.source}: {message}")

    def path(self, key: str) -> str:
        """Full key path of ``key``."""
        return f"{self.where}.{key}" if self.where else key

    def check_keys(self, allowed: Sequence[str] | set[str]) -> None:
        """Refuse keys not in ``allowed``."""
        unknown = sorted(show(k, 20).strip("'") for k in self.data if k not in allowed)
        if unknown:
            shown = ", ".join(repr(self.path(k)) for k in unknown[:5])
            raise self.fail(
                f"unknown key(s) {shown}{' ...' if len(unknown) > 5 else ''}; "
                f"allowed: {', '.join(sorted(allowed))}"
            )

    def get(self, key: str, default: Any = _MISSING) -> Any:
        """The raw value of ``key`` (``default`` if absent; required if no default)."""
        if key not in self.data:
            if default is _MISSING:
                raise self.fail(f"missing key '{self.path(key)}'")
            return default
        return self.data[key]

    def number(
        self,
        key: str,
        default: Any = _MISSING,
        *,
        minimum: float | None = None,
        maximum: float | None = None,
        positive: bool = False,
        unit: str = "",
    ) -> float:
        """A finite number within [minimum, maximum] (and > 0 if ``positive``)."""
        v = self.get(key, default)
        f = as_number(v)
        u = f" {unit}" if unit else ""
        if f is None:
            raise self.fail(f"'{self.path(key)}' must be a finite number{u}, got {show(v)}")
        if positive and not f > 0:
            raise self.fail(f"'{self.path(key)}' must be positive{u}, got {show(v)}")
        if minimum is not None and f < minimum:
            raise self.fail(f"'{self.path(key)}' must be >= {minimum:g}{u}, got {show(v)}")
        if maximum is not None and f > maximum:
            raise self.fail(f"'{self.path(key)}' must be <= {maximum:g}{u}, got {show(v)}")
        return f

    def integer(
        self, key: str, default: Any = _MISSING, *, minimum: int = 0, maximum: int | None = None
    ) -> int:
        """An integer within [minimum, maximum]."""
        v = self.get(key, default)
        rng = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        if (
            isinstance(v, bool)
            or not isinstance(v, int)
            or v < minimum
            or (maximum is not None and v > maximum)
        ):
            raise self.fail(f"'{self.path(key)}' must be an integer {rng}, got {show(v)}")
        return int(v)

    def choice(self, key: str, options: Sequence[str], default: Any = _MISSING) -> str:
        """One of the strings ``options``."""
        v = self.get(key, default)
        if not isinstance(v, str) or v not in options:
            raise self.fail(
                f"'{self.path(key)}' must be one of {', '.join(options)}, got {show(v)}"
            )
        return v

    def string(self, key: str, default: Any = _MISSING, *, max_length: int = 200) -> str:
        """A non-empty, single-line string of at most ``max_length`` characters, without
        control characters (which would garble a terminal)."""
        v = self.get(key, default)
        if (
            not isinstance(v, str)
            or not v.strip()
            or len(v) > max_length
            or any(ord(c) < 32 or 127 <= ord(c) < 160 for c in v)
        ):
            raise self.fail(
                f"'{self.path(key)}' must be a non-empty one-line string of at most "
                f"{max_length} characters without control characters, got {show(v)}"
            )
        return v

    def vector(
        self,
        key: str,
        n: int,
        value: Any = _MISSING,
        *,
        bound: float | None = None,
        what: str = "",
    ) -> tuple[float, ...]:
        """A list of ``n`` finite numbers (each |v| <= ``bound`` if given).

        ``value`` is used instead of looking ``key`` up (for list items); ``what``
        describes the entries, e.g. "[x, y, xdot, ydot]".
        """
        v = self.get(key) if value is _MISSING else value
        desc = f"a list of {n} numbers{' ' + what if what else ''}"
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise self.fail(f"'{self.path(key)}' must be {desc}, got {show(v)}")
        out = tuple(as_number(e) for e in v)
        if any(e is None for e in out):
            raise self.fail(f"'{self.path(key)}' must be {desc} (finite), got {show(v)}")
        vals = tuple(float(e) for e in out if e is not None)
        if bound is not None and any(abs(e) > bound for e in vals):
            raise self.fail(f"'{self.path(key)}' entries must be within ±{bound:g}, got {show(v)}")
        return vals

    def items(
        self, key: str, default: Any = _MISSING, *, min_len: int = 0, max_len: int, what: str
    ) -> list[Any]:
        """A list of ``min_len`` to ``max_len`` items, each described by ``what``."""
        v = self.get(key, default)
        if not isinstance(v, list) or len(v) < min_len:
            need = "a non-empty list" if min_len else "a list"
            raise self.fail(f"'{self.path(key)}' must be {need} of {what}, got {show(v)}")
        if len(v) > max_len:
            raise self.fail(
                f"'{self.path(key)}' has {len(v)} entries; at most {max_len} are allowed"
            )
        return v

    def sub(self, key: str, default: Any = _MISSING) -> Fields:
        """The mapping at ``key``."""
        return Fields(self.get(key, default), self.path(key), self.source, error=self.error)
