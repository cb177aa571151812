"""Palette files: what a palette is keyed by, the shipped file and the user cache, and
loading one (built once when none matches what is asked)."""

from __future__ import annotations

import dataclasses
import os
from importlib import resources
from pathlib import Path
from typing import Any

from gracenav._util.cache import cache_dir
from gracenav.control import ControllerGains, design_gains
from gracenav.errors import CacheError
from gracenav.palette.build import build_palette
from gracenav.palette.limits import PaletteLimits
from gracenav.palette.palette import Palette, palette_key
from gracenav.params import BallbotParams
from gracenav.policies import SampledPrimitive, VerificationOptions
from gracenav.primitives import PrimitiveSetOptions

__all__ = [
    "GAINS_RTOL",
    "PALETTE_ENV",
    "SHIPPED_PALETTES",
    "build_palette_for",
    "cached_palette_path",
    "forget_read_palettes",
    "load_palette",
    "palette_file",
    "shipped_palette_path",
]

#: Largest relative difference (see ControllerGains.relative_difference) between a
#: palette's stored gains and the gains requested of it that still counts as the
#: same design. Rebuilding the gains on another numpy/scipy build changes them by
#: about 1e-14; any real change of a design input changes them by far more.
GAINS_RTOL = 1e-8

#: Environment variable naming a palette file to use instead of the default.
PALETTE_ENV = "GRACENAV_PALETTE"


#: The palettes shipped inside the package, by name: ``default`` (one cruise speed,
#: 0.5 m/s; limited references whose ball jerk stays within 3 m/s³, shifts too: what
#: ``gracenav palette build`` builds by default, :class:`PaletteLimits`), used when no
#: palette is asked for, and ``gentle``, the same file by the name it was first shipped
#: under; ``nonic`` (the same speed with the nonic references of fixed form, shifts
#: within 12 m/s³: the default before; built with ``gracenav palette build --reference
#: nonic --max-ball-jerk 6 --shift-max-ball-jerk 12``); ``speed`` (cruise levels 0.5,
#: 1.0 and 1.2 m/s, limited references within 6 m/s³; built with ``gracenav palette
#: build --cruise-speeds 1.0 1.2 --max-ball-jerk 6 --shift-max-ball-jerk 12``); and
#: ``smooth`` (limited references and shifts within 2 m/s³; built with ``gracenav
#: palette build --max-ball-jerk 2 --shift-max-ball-jerk 2``); and ``calm`` (cruise at
#: 0.4 m/s, limited references and shifts within 1.15 m/s³, the controller feeding
#: friction forward at the mid-period rate; built with ``gracenav palette build
#: --cruise-speed 0.4 --max-ball-jerk 1.15 --shift-max-ball-jerk 1.15
#: --friction-midpoint``). ``--palette NAME`` and
#: ``$GRACENAV_PALETTE=NAME`` select one (:func:`palette_file`); a file of that name is
#: ``./NAME``.
SHIPPED_PALETTES: dict[str, str] = {
    "default": "palette.npz",
    "gentle": "palette.npz",
    "nonic": "palette-nonic.npz",
    "speed": "palette-speed.npz",
    "smooth": "palette-smooth.npz",
    "calm": "palette-calm.npz",
}


def shipped_palette_path(name: str = "default") -> Path:
    """Path of the palette file shipped inside the package under ``name`` (one of
    :data:`SHIPPED_PALETTES`).

    Raises
    ------
    CacheError
        ``name`` is not a shipped palette.
    """
    if name not in SHIPPED_PALETTES:
        raise CacheError(
            f"no palette named {name!r} is shipped (shipped: {', '.join(SHIPPED_PALETTES)})"
        )
    return Path(str(resources.files("gracenav") / "data" / SHIPPED_PALETTES[name]))


def palette_file(path: str | Path) -> Path:
    """The file ``path`` names: a shipped palette's when ``path`` is a string equal to
    one of the names of :data:`SHIPPED_PALETTES`, else ``path`` itself (a
    :class:`~pathlib.Path` or ``"./speed"`` is always a file)."""
    if isinstance(path, str) and path in SHIPPED_PALETTES:
        return shipped_palette_path(path)
    return Path(path)


def _requested_differences(
    pal: Palette,
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
    primitive_options: PrimitiveSetOptions,
) -> list[str]:
    """What the inputs stored in ``pal`` and the requested ones differ in, in words."""

    def show(d: dict[str, Any], k: str) -> str:
        # Options at their defaults are left out of the stored dictionaries.
        return repr(d[k]) if k in d else "the default"

    def fields(kind: str, have: dict[str, Any], want: dict[str, Any]) -> list[str]:
        return [
            f"{kind} {k}: {show(have, k)} in the file, {show(want, k)} requested"
            for k in sorted(set(have) | set(want))
            if have.get(k) != want.get(k)
        ]

    out = fields("robot parameter", pal.params.to_dict(), params.to_dict())
    out += fields("controller design", pal.gains.design_inputs(), gains.design_inputs())
    out += fields(
        "verification option", dataclasses.asdict(pal.options), dataclasses.asdict(options)
    )
    if pal.d != float(d):
        out.append(f"d: {pal.d!r} m in the file, {float(d)!r} m requested")
    out += fields(
        "primitive set option", pal.primitive_options.to_dict(), primitive_options.to_dict()
    )
    if pal.key != palette_key(params, gains, options, d, primitive_options) and not out:
        out.append("format or algorithm version")
    return out


def _mismatch(
    pal: Palette,
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
    primitive_options: PrimitiveSetOptions,
) -> str | None:
    """Why ``pal`` cannot serve the request, or None if it can."""
    if pal.key != palette_key(params, gains, options, d, primitive_options):
        return "it was built for " + "; ".join(
            _requested_differences(pal, params, gains, options, d, primitive_options)
        )
    diff = pal.gains.relative_difference(gains)
    if not diff <= GAINS_RTOL:
        return (
            f"its controller gains differ from the requested ones by a relative {diff:.1e} "
            f"(tolerance {GAINS_RTOL:.0e}): the same design inputs gave other gains"
        )
    return None


#: Palettes read in this process, by file (resolved path, modification time in ns and
#: size), the most recently read last: a process that runs many scenarios reads its
#: palette once, and instantiation's tables, kept per palette object, are computed once.
_READ: dict[tuple[str, int, int], Palette] = {}

#: Most palettes :data:`_READ` holds.
_READ_KEEP = 4


def _file_key(path: Path) -> tuple[str, int, int] | None:
    """(resolved path, mtime in ns, size) of ``path``, or None when it cannot be read."""
    try:
        st = path.stat()
        return (str(path.resolve()), st.st_mtime_ns, st.st_size)
    except OSError:
        return None


def _read_palette(path: Path) -> Palette:
    """Read ``path`` and check its key against the inputs stored in it; a file read
    before and not changed since is not read again."""
    before = _file_key(path)
    if before is not None and before in _READ:
        return _READ[before]
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CacheError(
            f"cannot read palette file {path}: {exc.strerror}; build one with "
            "`gracenav palette build`, or name a shipped palette: " + ", ".join(SHIPPED_PALETTES)
        ) from None
    pal = Palette.from_bytes(data, source=str(path))
    if pal.key != pal.expected_key():
        raise CacheError(
            f"{path}: palette key does not match the inputs stored in it (stale or edited "
            "file); rebuild it with `gracenav palette build`"
        )
    if before is not None and _file_key(path) == before:  # not replaced while read
        _READ[before] = pal
        while len(_READ) > _READ_KEEP:
            del _READ[next(iter(_READ))]
    return pal


def forget_read_palettes() -> None:
    """Forget the palettes this process has read.

    :func:`load_palette` keeps the palettes it reads (:data:`_READ`) and returns the same
    object again while a file is unchanged; after this the next load reads and checks the
    file anew, and returns a new object (for timing a real load, or to drop the
    memory).

    See Also
    --------
    load_palette
    """
    _READ.clear()


def _redesign(gains: ControllerGains) -> ControllerGains:
    """The gains designed anew from ``gains``' design inputs (hand-given gains as given)."""
    if gains.weights is None:
        return gains
    return design_gains(
        gains.params,
        gains.weights,
        max_lean_compensation=gains.max_lean_compensation,
        friction_compensation=gains.friction_compensation,
        friction_midpoint=gains.friction_midpoint,
    )


def cached_palette_path(key: str) -> Path:
    """Where the palette with ``key`` (see :func:`palette_key`) is cached."""
    return cache_dir() / f"palette-{key[:24]}.npz"


def load_palette(
    path: str | Path | None = None,
    *,
    params: BallbotParams | None = None,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    d: float | None = None,
    limits: PaletteLimits | None = None,
    build: bool = True,
    processes: int | None = None,
    progress: bool = True,
) -> Palette:
    """The palette for the requested robot, controller, verification options, d and
    limits.

    Without ``path`` (and without ``$GRACENAV_PALETTE``), a palette shipped with
    gracenav is returned when it was built from the requested inputs; otherwise a
    matching palette from the user cache (:func:`cached_palette_path`), and when
    there is none (or it is corrupt) one is built once, with a progress bar, and
    cached atomically. A palette "matches" when its key (a hash of the inputs,
    :func:`palette_key`) is the requested one and its stored gains equal the
    requested gains within a relative :data:`GAINS_RTOL`.

    Parameters
    ----------
    path : str or Path, optional
        Force this palette file, or a shipped palette by name (:data:`SHIPPED_PALETTES`,
        e.g. ``"speed"``; default ``$GRACENAV_PALETTE`` if set). A forced file
        that does not match the request is an error, never rebuilt; its primitive set
        options (references, speed levels: ``gracenav palette build --reference
        --cruise-speeds``) are taken as they are.
    params, gains, options, d : optional
        What the palette must have been built for. Defaults: for a forced file, what
        it was built for (its gains designed anew from its design inputs and
        compared); otherwise the CMU ballbot, :func:`gracenav.control.design_gains`
        on ``params``, the verification options of the default :class:`PaletteLimits`
        and d = 0.5 m.
    limits : PaletteLimits, optional
        The limits the palette must have been built to: its primitive set (references,
        speeds) and, when ``options`` is not given, its verification options. Default:
        for a forced file, what it was built to; otherwise ``PaletteLimits()``, the
        default palette's.
    build : bool
        Build a missing palette (False: raise CacheError instead).
    processes : int, optional
        Worker processes of a build (default: the number of CPUs, at most 4).
    progress : bool
        Show the build's progress bar on a terminal.

    Raises
    ------
    CacheError
        A forced file is missing, corrupt, stale or does not match; or no matching
        palette exists and ``build`` is False.
    """
    forced = path if path is not None else (os.environ.get(PALETTE_ENV) or None)
    if forced is not None:
        pal = _read_palette(palette_file(forced))
        # What is not asked for is what the file was built for; its gains are then
        # designed anew from the file's design inputs and compared, as for any request.
        params = params if params is not None else pal.params
        if gains is None:
            gains = _redesign(pal.gains) if params == pal.params else design_gains(params)
        if limits is not None and options is None:
            options = limits.verification_options()
        options = options if options is not None else pal.options
        prim = limits.primitive_options() if limits is not None else pal.primitive_options
        why = _mismatch(pal, params, gains, options, d if d is not None else pal.d, prim)
        if why is not None:
            raise CacheError(
                f"{forced}: this palette cannot be used: {why}. Leave out --palette / "
                f"${PALETTE_ENV} to use (or build once) a matching palette, or rebuild this "
                "file with `gracenav palette build --out FILE`"
            )
        return pal
    limits = limits if limits is not None else PaletteLimits()
    params = params if params is not None else BallbotParams()
    gains = gains if gains is not None else design_gains(params)
    options = options if options is not None else limits.verification_options()
    d = float(d) if d is not None else 0.5
    prim = limits.primitive_options()
    key = palette_key(params, gains, options, d, prim)
    # The default palette first, then the other shipped ones, then the user cache.
    shipped = dict.fromkeys(shipped_palette_path(name) for name in SHIPPED_PALETTES)
    for candidate in (*shipped, cached_palette_path(key)):
        if not candidate.is_file():
            continue
        try:
            pal = _read_palette(candidate)
        except CacheError:
            continue  # a corrupt or stale cache file is rebuilt below
        if _mismatch(pal, params, gains, options, d, prim) is None:
            return pal
    if not build:
        raise CacheError(
            "no palette matches the requested robot parameters, controller, verification "
            f"options and d = {d} m; build one with `gracenav palette build`"
        )
    pal = build_palette_for(
        params=params,
        gains=gains,
        options=options,
        d=d,
        processes=processes,
        progress=progress,
        primitive_options=prim,
    )
    try:
        pal.save(cached_palette_path(key))
    except OSError:
        pass  # an unwritable cache only costs the rebuild next time
    return pal


def build_palette_for(
    *,
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
    processes: int | None = None,
    progress: bool = True,
    primitive_options: PrimitiveSetOptions | None = None,
) -> Palette:
    """Plan the primitive set Σ(d) (with ``primitive_options``, default the defaults)
    and build its palette (see :func:`build_palette`)."""
    from gracenav.primitives import primitive_set

    pset = primitive_set(d=d, params=params, options=primitive_options)
    prims = [SampledPrimitive.from_primitive(p) for p in pset]
    if processes is None:
        processes = max(1, min(4, os.cpu_count() or 1))
    return build_palette(
        prims,
        d=d,
        params=params,
        gains=gains,
        options=options,
        processes=processes,
        progress=progress,
        primitive_options=primitive_options,
    )
