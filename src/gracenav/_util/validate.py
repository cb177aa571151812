"""Validation of user documents (scenarios, parameter files, maps): one reader, one style.

A :class:`Fields` wraps one mapping of a parsed document at a key path (``task``,
``obstacles[2].circle``) and reads typed values from it. Every failure is a
:class:`gracenav.errors.ConfigError` (or the package error given as ``error``, e.g.
:class:`~gracenav.errors.MapError`) whose one-line message names the file, the full key
path and the offending value, shortened::

    lab.yaml: 'task.starts[1]' must be a list of 4 numbers [x, y, xdot, ydot], got [0, 'a']
    map.yaml: 'obstacles[2].circle.radius' must be a positive number (m), got -1

Numbers are real numbers only (not ``bool``), finite, and within the bounds the caller
states; ranges appear in the message with their unit (:func:`number_range`, shared with
the command line's argument types). :func:`check_number` checks one value outside a
document (a function argument) in the same words.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gracenav.errors import ConfigError, GracenavError

__all__ = [
    "Fields",
    "as_number",
    "check_number",
    "in_range",
    "number_range",
    "require_mapping",
    "show",
]

_MISSING: Any = ...


def show(value: Any, limit: int = 40) -> str:
    """A short, user-facing rendering of a parsed value for error messages.

    Numbers of any real type (numpy's included) are shown as plain numbers, never as
    ``np.float64(...)``.
    """
    if value is None:
        return "null (nothing)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Mapping):
        return "a mapping" if value else "an empty mapping"
    if isinstance(value, numbers.Integral):
        i = int(value)
        if abs(i) < 10**15:
            return str(i)
        sign = "-" if i < 0 else ""
        return f"{sign}~1e{int(abs(i).bit_length() * math.log10(2))}"  # any size
    if isinstance(value, numbers.Real):
        try:
            return repr(float(value))
        except OverflowError:
            return "a number too large for a float"
    if isinstance(value, (list, tuple)):
        items = ", ".join(show(v, limit) for v in value[:5])
        text = f"[{items}{', ...' if len(value) > 5 else ''}]"
    elif isinstance(value, str):
        text = repr(value)
    else:
        text = f"a {type(value).__name__}"
    return text if len(text) <= limit else text[: limit - 4] + " ..."


def _key_text(key: Any) -> str:
    """A mapping key as it appears in a key path: control characters escaped, long keys
    shortened, other types shown as values."""
    if not isinstance(key, str):
        return show(key, 20)
    if not key:
        return '""'
    text = repr(key)[1:-1]
    return text if len(text) <= 20 else text[:16] + " ..."


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
    if isinstance(value, numbers.Real):
        return "a number"
    return f"a {type(value).__name__}"


def as_number(value: Any) -> float | None:
    """``value`` as a finite float, or None if it is not a finite real number.

    Python and numpy reals are numbers; ``bool`` (and numpy's) and strings are not.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        f = float(value)
    except (OverflowError, TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def number_range(
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
    integer: bool = False,
    unit: str = "",
) -> str:
    """The numbers allowed, in words: "a positive number (m)", "a number in [0, 5] m",
    "an integer >= 1", "a number in (0, 600] s"."""
    kind = "integer" if integer else "number"
    noun = f"an {kind}" if integer else f"a {kind}"
    u = f" {unit}" if unit else ""  # after a limit: ">= 0 m"
    pu = f" ({unit})" if unit else ""  # after a word: "a positive number (m)"
    low = "(0" if positive and (minimum is None or minimum <= 0) else None
    if low is None and minimum is not None:
        low = f"[{_bound(minimum)}"
    if low is not None and maximum is not None:
        return f"{noun} in {low}, {_bound(maximum)}]{u}"
    if low == "(0":
        return f"a positive {kind}{pu}"
    if minimum is not None:
        return f"{noun} >= {_bound(minimum)}{u}"
    if maximum is not None:
        return f"{noun} <= {_bound(maximum)}{u}"
    return f"a finite {kind}{pu}"


def _bound(x: float) -> str:
    """A limit as written in messages: integers in full, other numbers with %g."""
    return str(x) if isinstance(x, int) and not isinstance(x, bool) else f"{x:g}"


def in_range(
    value: float,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
) -> bool:
    """Whether the finite ``value`` is within the limits :func:`number_range` describes."""
    return not (
        (positive and not value > 0)
        or (minimum is not None and value < minimum)
        or (maximum is not None and value > maximum)
    )


def check_number(
    value: Any,
    name: str,
    source: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
    unit: str = "",
    error: type[GracenavError] = ConfigError,
) -> float:
    """``value`` as a float, checked as :meth:`Fields.number` checks a document's value.

    For arguments of functions (``WorldMap(resolution=...)``): the message reads
    ``SOURCE: 'NAME' must be ..., got ...``.
    """
    f = as_number(value)
    if f is None:
        hint = ""
        if isinstance(value, str) and as_number(_float_or_none(value)) is not None:
            hint = " (a string: write numbers without quotes)"
        u = f" ({unit})" if unit else ""
        raise error(f"{source}: '{name}' must be a finite number{u}, got {show(value)}{hint}")
    if not in_range(f, minimum=minimum, maximum=maximum, positive=positive):
        desc = number_range(minimum=minimum, maximum=maximum, positive=positive, unit=unit)
        raise error(f"{source}: '{name}' must be {desc}, got {show(value)}")
    return f


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _is_file(path: Path) -> bool:
    try:  # a name too long for the file system raises OSError on some Python versions
        return path.is_file()
    except OSError:
        return False


def _is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except OSError:
        return False


def require_mapping(
    data: Any, source: str, what: str, keys: Sequence[str], error: type[GracenavError] = ConfigError
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
        The file (or "scenario", "parameters", "inline map") named in messages.
    error : type of GracenavError
        Exception raised on invalid input (``ConfigError``; ``MapError`` for maps).
    expect : str
        What ``data`` should be, for the message when it is not a mapping.
    """

    def __init__(
        self,
        data: Any,
        where: str,
        source: str,
        *,
        error: type[GracenavError] = ConfigError,
        expect: str = "a mapping",
    ) -> None:
        self.error = error
        self.where = where
        self.source = source
        if not isinstance(data, Mapping):
            raise self.fail(f"'{where}' must be {expect}, got {_kind(data)}")
        self.data = data

    def fail(self, message: str) -> GracenavError:
        """The exception to raise for ``message`` (prefixed with the source)."""
        return self.error(f"{self.source}: {message}")

    def path(self, key: str) -> str:
        """Full key path of ``key``."""
        return f"{self.where}.{key}" if self.where else key

    def check_keys(self, allowed: Sequence[str] | set[str]) -> None:
        """Refuse keys not in ``allowed``."""
        unknown = sorted(_key_text(k) for k in self.data if k not in allowed)
        if unknown:
            shown = ", ".join(f"'{self.path(k)}'" for k in unknown[:5])
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
        """A finite number within [minimum, maximum] (and > 0 if ``positive``).

        A number given as a quoted string is refused with a hint to drop the quotes.
        """
        return check_number(
            self.get(key, default),
            self.path(key),
            self.source,
            minimum=minimum,
            maximum=maximum,
            positive=positive,
            unit=unit,
            error=self.error,
        )

    def integer(
        self, key: str, default: Any = _MISSING, *, minimum: int = 0, maximum: int | None = None
    ) -> int:
        """An integer within [minimum, maximum] (``bool`` and floats such as 1.0 refused)."""
        v = self.get(key, default)
        if (
            isinstance(v, bool)
            or not isinstance(v, numbers.Integral)
            or not in_range(int(v), minimum=minimum, maximum=maximum)
        ):
            desc = number_range(minimum=minimum, maximum=maximum, integer=True)
            raise self.fail(f"'{self.path(key)}' must be {desc}, got {show(v)}")
        return int(v)

    def choice(self, key: str, options: Sequence[str], default: Any = _MISSING) -> str:
        """One of the strings ``options``."""
        v = self.get(key, default)
        if not isinstance(v, str) or v not in options:
            raise self.fail(
                f"'{self.path(key)}' must be one of {', '.join(options)}, got {show(v)}"
            )
        return v

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        """``true`` or ``false`` (YAML booleans, not 0/1 or strings)."""
        v = self.get(key, default)
        if not isinstance(v, bool):
            raise self.fail(f"'{self.path(key)}' must be true or false, got {show(v)}")
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

    def file(
        self, key: str, base: Path, default: Any = _MISSING, *, must_exist: bool = True
    ) -> Path:
        """A file named by a path string: absolute, or relative to the folder ``base`` of
        the document that names it (map_server's rule for a map's image).

        With ``must_exist`` it must be an existing regular file.
        """
        text = self.string(key, default, max_length=4096)
        path = base / text  # an absolute ``text`` replaces ``base``
        if must_exist and not _is_file(path):
            problem = "is a folder, not a file" if _is_dir(path) else "not found"
            raise self.fail(
                f"'{self.path(key)}': file {path} {problem}; a relative path is taken from "
                f"the folder of {Path(self.source).name}"
            )
        return path

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
        self,
        key: str,
        default: Any = _MISSING,
        *,
        min_len: int = 0,
        max_len: int | None = None,
        what: str,
        advice: str = "",
    ) -> list[Any]:
        """A list of ``min_len`` to ``max_len`` items, each described by ``what``.

        ``advice`` (what to do) ends the message of a list over ``max_len``.
        """
        v = self.get(key, default)
        if min_len == max_len:
            need = f"a list of {min_len} {what}"
        elif min_len > 1:
            need = f"a list of at least {min_len} {what}"
        else:
            need = f"a {'non-empty ' if min_len else ''}list of {what}"
        if not isinstance(v, list) or len(v) < min_len:
            raise self.fail(f"'{self.path(key)}' must be {need}, got {show(v)}")
        if max_len is not None and len(v) > max_len and min_len == max_len:
            raise self.fail(f"'{self.path(key)}' must be {need}, got {show(v)}")
        if max_len is not None and len(v) > max_len:
            raise self.fail(
                f"'{self.path(key)}' has {len(v)} entries; at most {max_len} are allowed"
                + (f"; {advice}" if advice else "")
            )
        return v

    def points(
        self,
        key: str,
        default: Any = _MISSING,
        *,
        dim: int = 2,
        min_len: int = 0,
        max_len: int | None = None,
        bound: float | None = None,
        what: str,
        item: str | None = None,
        advice: str = "",
    ) -> tuple[tuple[float, ...], ...]:
        """A list of points (or states), each a list of ``dim`` finite numbers.

        The list is checked as by :meth:`items` (described by ``what``), each entry as by
        :meth:`vector` (described by ``item``, default ``what``) under its own key path,
        ``key[i]``.
        """
        raw = self.items(key, default, min_len=min_len, max_len=max_len, what=what, advice=advice)
        desc = what if item is None else item
        return tuple(
            self.vector(f"{key}[{i}]", dim, p, bound=bound, what=desc) for i, p in enumerate(raw)
        )

    def variant(self, options: Sequence[str]) -> tuple[str, Fields]:
        """The one key of a mapping that must hold exactly one of ``options``, and the
        mapping under it (e.g. ``{circle: {center: ..., radius: ...}}``)."""
        keys = list(self.data)
        if len(keys) != 1 or keys[0] not in options:
            got = ", ".join(show(k, 20) for k in keys[:5]) if keys else "none"
            raise self.fail(
                f"'{self.where}' must hold exactly one of the keys {', '.join(options)}, got {got}"
            )
        kind = str(keys[0])
        return kind, self.sub(kind)

    def sub(self, key: str, default: Any = _MISSING) -> Fields:
        """The mapping at ``key``."""
        return Fields(self.get(key, default), self.path(key), self.source, error=self.error)
