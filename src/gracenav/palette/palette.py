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
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import zipfile
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from gracenav._util.cache import cache_dir
from gracenav._util.io import atomic_write_bytes
from gracenav.control import ControllerGains, LQRWeights, design_gains
from gracenav.errors import CacheError, ConfigError
from gracenav.params import BallbotParams
from gracenav.policies import (
    BrakingOptions,
    CatchOptions,
    DomainRadii,
    DomainShape,
    MotionPolicy,
    PrimitiveKind,
    RegulatorOptions,
    SampledPrimitive,
    VerificationOptions,
    VerificationReport,
)
from gracenav.policies.catches import (
    PUSHED,
    SETTLED,
    STILL,
    catch_policies,
    shift_cells,
    shift_policies,
)
from gracenav.primitives import PrimitiveSetOptions

__all__ = [
    "GAINS_RTOL",
    "PALETTE_ENV",
    "PALETTE_FORMAT",
    "Palette",
    "build_palette",
    "build_palette_for",
    "cached_palette_path",
    "load_palette",
    "palette_key",
    "shipped_palette_path",
]

PALETTE_FORMAT = 5
#: Primitive name of the capture regulators (a rest trim held
#: ``RegulatorOptions.duration``).
REGULATOR_NAME = "regulate"
#: Primitives are stored at every COARSE_STRIDE-th control tick (1/128 s) and
#: rebuilt exactly enough (see SampledPrimitive.from_coarse) when loaded.
COARSE_STRIDE = 8
#: Bumped whenever the planner, controller or verification code changes results.
ALGORITHM_VERSION = "9"
#: Largest relative difference (see ControllerGains.relative_difference) between a
#: palette's stored gains and the gains requested of it that still counts as the
#: same design. Rebuilding the gains on another numpy/scipy build changes them by
#: about 1e-14; any real change of a design input changes them by far more.
GAINS_RTOL = 1e-8
#: Environment variable naming a palette file to use instead of the default.
PALETTE_ENV = "GRACENAV_PALETTE"


def palette_key(
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
    primitive_options: PrimitiveSetOptions | None = None,
) -> str:
    """Hash (hex SHA-256) of everything a palette is *built from*.

    The inputs only: robot parameters, the controller's design inputs
    (:meth:`ControllerGains.design_inputs`: nominal parameters, LQR weights,
    saturation, friction compensation), verification options, d, the primitive
    set's options, file format and algorithm version. Never a computed float:
    the designed gains themselves are stored in the file and compared within
    :data:`GAINS_RTOL` when the palette is loaded.
    """
    primitive_options = (
        primitive_options if primitive_options is not None else (PrimitiveSetOptions())
    )
    blob = json.dumps(
        {
            "format": PALETTE_FORMAT,
            "algorithm": ALGORITHM_VERSION,
            "params": params.to_dict(),
            "controller": gains.design_inputs(),
            "options": dataclasses.asdict(options),
            "primitives": primitive_options.to_dict(),
            "d": float(d),
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


def shipped_palette_path() -> Path:
    """Path of the palette file shipped inside the package."""
    return Path(str(resources.files("gracenav") / "data" / "palette.npz"))


@dataclass(frozen=True)
class Palette:
    """A motion policy palette Π(Σ): unique verified policies of the primitive set Σ(d).

    Attributes
    ----------
    policies : tuple of MotionPolicy
        The verified policies (first-quadrant primitives; instantiation rotates them):
        for each primitive the policy sized by bisection, followed by its larger-domain
        variants (scaled domains, named ``<primitive>[S=<s>G]``), which share its
        primitive.
    rejected : tuple of (str, VerificationReport)
        Primitives whose policy failed verification, with the failing report.
    duplicates : tuple of (str, str)
        Primitives left out because they are a rotation of another one (instantiation
        rotates policies anyway), with what they duplicate.
    d : float
        Distance parameter of the primitive set (m).
    params : BallbotParams
        Parameters of the plant the policies were verified on.
    options : VerificationOptions
    key : str
        See :func:`palette_key`.
    primitive_options : PrimitiveSetOptions
        Options the primitive set Σ(d) was planned with.
    catches, shifts : tuple of MotionPolicy
        The verified catches and shifts (:mod:`gracenav.policies.catches`): placed at the
        robot's state (:mod:`gracenav.execution.capture`), never on the lattice, so not among
        ``policies``.
    """

    policies: tuple[MotionPolicy, ...]
    rejected: tuple[tuple[str, VerificationReport], ...]
    duplicates: tuple[tuple[str, str], ...]
    d: float
    params: BallbotParams
    options: VerificationOptions
    key: str
    primitive_options: PrimitiveSetOptions = field(default_factory=PrimitiveSetOptions)
    catches: Sequence[MotionPolicy] = ()
    shifts: Sequence[MotionPolicy] = ()

    def __len__(self) -> int:
        return len(self.policies)

    def __iter__(self) -> Iterator[MotionPolicy]:
        return iter(self.policies)

    def __getitem__(self, name: str) -> MotionPolicy:
        for p in self.policies:
            if p.name == name:
                return p
        raise ConfigError(
            f"no policy named {name!r} in the palette; known: {', '.join(self.names)}"
        )

    @property
    def names(self) -> tuple[str, ...]:
        """Policy names, in palette order."""
        return tuple(p.name for p in self.policies)

    @property
    def base_policies(self) -> tuple[MotionPolicy, ...]:
        """One policy per primitive: the one sized by bisection (no scaled variants)."""
        return tuple(p for p in self.policies if not p.label)

    @property
    def gains(self) -> ControllerGains:
        """The control law shared by every policy."""
        return self.policies[0].gains if self.policies else design_gains(self.params)

    # -- file format ---------------------------------------------------------------
    def to_bytes(self) -> bytes:
        """Serialise to an ``.npz`` archive (no pickle)."""
        header: dict[str, Any] = {
            "format": PALETTE_FORMAT,
            "algorithm": ALGORITHM_VERSION,
            "key": self.key,
            "d": self.d,
            "params": self.params.to_dict(),
            "options": dataclasses.asdict(self.options),
            "primitive_options": self.primitive_options.to_dict(),
            "gains": {
                "lqr": self.gains.lqr.tolist(),
                "params": self.gains.params.to_dict(),
                "weights": (
                    None if self.gains.weights is None else dataclasses.asdict(self.gains.weights)
                ),
                "max_lean_compensation": self.gains.max_lean_compensation,
                "friction_compensation": self.gains.friction_compensation,
            },
            "policies": [],
            "rejected": [[n, dataclasses.asdict(r)] for n, r in self.rejected],
            "duplicates": [list(x) for x in self.duplicates],
        }
        arrays: dict[str, np.ndarray] = {}
        header["primitives"] = []
        prim_ids: dict[int, int] = {}
        header["catches"] = []
        header["shifts"] = []
        groups = (
            ("policies", self.policies),
            ("catches", self.catches),
            ("shifts", self.shifts),
        )
        for group, pol in ((g, p) for g, pols in groups for p in pols):
            prim = pol.primitive
            if id(prim) not in prim_ids:
                i = prim_ids[id(prim)] = len(header["primitives"])
                stride = COARSE_STRIDE if prim.num_ticks % COARSE_STRIDE == 0 else 1
                header["primitives"].append(
                    {
                        "name": prim.name,
                        "kind": prim.kind.value,
                        "duration": prim.duration,
                        "dt": prim.dt,
                        "displacement": prim.displacement.tolist(),
                        "start_velocity": prim.start_velocity.tolist(),
                        "end_velocity": prim.end_velocity.tolist(),
                        "stride": stride,
                    }
                )
                arrays[f"p{i}_states"], arrays[f"p{i}_accelerations"] = prim.coarse(stride)
            header[group].append(
                {
                    "primitive": prim_ids[id(prim)],
                    "label": pol.label,
                    "start_radii": dataclasses.asdict(pol.start_radii),
                    "goal_radii": dataclasses.asdict(pol.goal_radii),
                    "outer_factors": list(pol.outer_factors),
                    "correlation": pol.correlation,
                    "report": None if pol.report is None else dataclasses.asdict(pol.report),
                    "capture": pol.capture,
                    "start_correlation": pol.start_correlation,
                    "outer_cross": pol.outer_cross,
                    "flat_start": pol.flat_start,
                }
            )
        arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
        buf = io.BytesIO()
        np.savez(buf, **arrays)  # type: ignore[arg-type]
        return buf.getvalue()

    def save(self, path: str | Path) -> Path:
        """Write the palette atomically to ``path`` (``.npz``)."""
        path = Path(path)
        atomic_write_bytes(path, self.to_bytes())
        return path

    @classmethod
    def from_bytes(cls, data: bytes, *, source: str = "palette") -> Palette:
        """Parse an archive written by :meth:`to_bytes`; raises CacheError if corrupt."""
        try:
            # Every member's CRC now, so that a corrupt file is refused here, not when
            # its catches are first read.
            members = _stored_members(data)

            def array(name: str) -> NDArray[Any]:
                return np.lib.format.read_array(io.BytesIO(members[f"{name}.npy"]))

            header = json.loads(array("header").tobytes().decode())
            if header.get("format") == PALETTE_FORMAT:
                # The navigation policies' primitives now; catches and shifts when
                # first used (PlacedPolicies reads them from ``data``).
                used = {int(m["primitive"]) for m in header["policies"]}
                arrays = {
                    i: (array(f"p{i}_states"), array(f"p{i}_accelerations")) for i in sorted(used)
                }
            if header.get("format") != PALETTE_FORMAT:
                raise CacheError(
                    f"{source}: palette format {header.get('format')!r}, this gracenav reads "
                    f"format {PALETTE_FORMAT}; rebuild it with `gracenav palette build`"
                )
            params = BallbotParams.from_dict(header["params"], source=source)
            gp = header["gains"]
            gains = ControllerGains(
                lqr=np.asarray(gp["lqr"], dtype=float),
                params=BallbotParams.from_dict(gp["params"], source=source),
                max_lean_compensation=float(gp["max_lean_compensation"]),
                friction_compensation=bool(gp["friction_compensation"]),
                weights=None if gp["weights"] is None else LQRWeights(**gp["weights"]),
            )
            opts = dict(header["options"])
            opts["scale_ladder"] = tuple(opts["scale_ladder"])
            if opts.get("regulator") is not None:
                opts["regulator"] = RegulatorOptions.from_dict(opts["regulator"])
            if opts.get("braking") is not None:
                opts["braking"] = BrakingOptions.from_dict(opts["braking"])
            if opts.get("catch") is not None:
                opts["catch"] = CatchOptions.from_dict(opts["catch"])
            options = VerificationOptions(**opts)
            primitive_options = PrimitiveSetOptions.from_dict(header["primitive_options"])
            items = {
                i: _coarse_item(st, acc, header["primitives"][i]) for i, (st, acc) in arrays.items()
            }
            policies = _policies_from(
                header["policies"], items, header["primitives"], params, gains
            )
            # Catches and shifts are read and rebuilt on first use (captures only).
            placed = {
                g: PlacedPolicies(header.get(g, []), data, header["primitives"], params, gains)
                for g in ("catches", "shifts")
            }
            rejected = tuple((str(n), VerificationReport(**r)) for n, r in header["rejected"])
            return cls(
                policies=policies,
                catches=placed["catches"],
                shifts=placed["shifts"],
                rejected=rejected,
                duplicates=tuple((str(a), str(b)) for a, b in header["duplicates"]),
                d=float(header["d"]),
                params=params,
                options=options,
                key=str(header["key"]),
                primitive_options=primitive_options,
            )
        except CacheError:
            raise
        except (
            zipfile.BadZipFile,
            ValueError,
            KeyError,
            TypeError,
            OSError,
            EOFError,
            json.JSONDecodeError,
            ConfigError,
        ) as exc:
            raise CacheError(
                f"{source}: corrupt or unreadable palette file ({type(exc).__name__}: {exc}); "
                "rebuild it with `gracenav palette build`"
            ) from None

    def expected_key(self) -> str:
        """The key recomputed from the inputs stored in this palette."""
        return palette_key(self.params, self.gains, self.options, self.d, self.primitive_options)


def _requested_differences(
    pal: Palette,
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
) -> list[str]:
    """What the inputs stored in ``pal`` and the requested ones differ in, in words."""

    def fields(kind: str, have: dict[str, Any], want: dict[str, Any]) -> list[str]:
        return [
            f"{kind} {k}: {have.get(k)!r} in the file, {want.get(k)!r} requested"
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
    if pal.primitive_options != PrimitiveSetOptions():
        out.append("primitive set options other than this version's defaults")
    if pal.key != palette_key(params, gains, options, d) and not out:
        out.append("format or algorithm version")
    return out


def _mismatch(
    pal: Palette,
    params: BallbotParams,
    gains: ControllerGains,
    options: VerificationOptions,
    d: float,
) -> str | None:
    """Why ``pal`` cannot serve the request, or None if it can."""
    if pal.key != palette_key(params, gains, options, d):
        return "it was built for " + "; ".join(
            _requested_differences(pal, params, gains, options, d)
        )
    diff = pal.gains.relative_difference(gains)
    if not diff <= GAINS_RTOL:
        return (
            f"its controller gains differ from the requested ones by a relative {diff:.1e} "
            f"(tolerance {GAINS_RTOL:.0e}): the same design inputs gave other gains"
        )
    return None


def _coarse_item(
    states: NDArray[Any], accelerations: NDArray[Any], meta: dict[str, Any]
) -> tuple[NDArray[Any], NDArray[Any], int, dict[str, Any]]:
    """A stored primitive as :meth:`SampledPrimitive.from_coarse_many` takes it."""
    return (
        states,
        accelerations,
        int(meta["stride"]),
        {
            "name": meta["name"],
            "kind": PrimitiveKind(meta["kind"]),
            "dt": float(meta["dt"]),
            "displacement": np.asarray(meta["displacement"], dtype=float),
            "start_velocity": np.asarray(meta["start_velocity"], dtype=float),
            "end_velocity": np.asarray(meta["end_velocity"], dtype=float),
        },
    )


def _policies_from(
    entries: Sequence[dict[str, Any]],
    items: dict[int, tuple[NDArray[Any], NDArray[Any], int, dict[str, Any]]],
    primitive_meta: Sequence[dict[str, Any]],
    params: BallbotParams,
    gains: ControllerGains,
) -> tuple[MotionPolicy, ...]:
    """The policies of the header ``entries``, with their primitives rebuilt from the
    coarse ``items`` (by primitive index; one interpolation and one evaluation of the
    equations of motion for all of them)."""
    used = sorted({int(meta["primitive"]) for meta in entries})
    rebuilt = SampledPrimitive.from_coarse_many([items[i] for i in used], params)
    primitives = dict(zip(used, rebuilt, strict=True))
    for i, prim in primitives.items():
        if abs(prim.duration - float(primitive_meta[i]["duration"])) > 1e-9:
            raise ValueError(
                f"primitive {primitive_meta[i]['name']}: samples do not span its duration"
            )
    out = []
    for meta in entries:
        rep = meta["report"]
        out.append(
            MotionPolicy(
                primitive=primitives[int(meta["primitive"])],
                gains=gains,
                start_radii=DomainRadii(**meta["start_radii"]),
                goal_radii=DomainRadii(**meta["goal_radii"]),
                outer_factors=(float(meta["outer_factors"][0]), float(meta["outer_factors"][1])),
                correlation=float(meta["correlation"]),
                report=None if rep is None else VerificationReport(**rep),
                label=str(meta["label"]),
                capture=bool(meta["capture"]),
                start_correlation=(
                    None if meta["start_correlation"] is None else float(meta["start_correlation"])
                ),
                outer_cross=None if meta.get("outer_cross") is None else float(meta["outer_cross"]),
                flat_start=bool(meta.get("flat_start", False)),
            )
        )
    return tuple(out)


def _stored_members(data: bytes) -> dict[str, memoryview]:
    """Every member of an archive written by ``np.savez`` (stored, not compressed), by
    name, its CRC-32 checked: one pass over the bytes, without a read per member."""
    view = memoryview(data)
    out: dict[str, memoryview] = {}
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        for info in archive.infolist():
            if info.compress_type != zipfile.ZIP_STORED:
                raise ValueError(f"member {info.filename} is compressed")
            at = info.header_offset
            local = view[at : at + 30]
            if len(local) < 30 or bytes(local[:4]) != b"PK\x03\x04":
                raise ValueError(f"member {info.filename} has no local header")
            start = at + 30 + int.from_bytes(local[26:28], "little")
            start += int.from_bytes(local[28:30], "little")
            body = view[start : start + info.compress_size]
            if len(body) != info.compress_size or zlib.crc32(body) != info.CRC:
                raise ValueError(f"member {info.filename} fails its CRC check")
            out[info.filename] = body
    return out


class PlacedPolicies(Sequence[MotionPolicy]):
    """A palette's catches or shifts, read from the file and rebuilt on first use.

    They serve captures only (:mod:`gracenav.execution.capture`), so loading a palette does not
    pay for them; the file's bytes stay with the object (it pickles to worker
    processes). A file that turns out corrupt then raises :class:`CacheError`.
    """

    def __init__(
        self,
        entries: Sequence[dict[str, Any]],
        data: bytes,
        primitive_meta: Sequence[dict[str, Any]],
        params: BallbotParams,
        gains: ControllerGains,
    ) -> None:
        self._entries = list(entries)
        self._data = data if self._entries else b""
        self._meta = list(primitive_meta) if self._entries else []
        self._params = params
        self._gains = gains
        self._policies: tuple[MotionPolicy, ...] | None = None

    def _get(self) -> tuple[MotionPolicy, ...]:
        if self._policies is None:
            if not self._entries:
                self._policies = ()
                return self._policies
            used = sorted({int(m["primitive"]) for m in self._entries})
            try:
                with np.load(io.BytesIO(self._data), allow_pickle=False) as z:
                    items = {
                        i: _coarse_item(z[f"p{i}_states"], z[f"p{i}_accelerations"], self._meta[i])
                        for i in used
                    }
                self._policies = _policies_from(
                    self._entries, items, self._meta, self._params, self._gains
                )
            except (zipfile.BadZipFile, ValueError, KeyError, TypeError, OSError) as exc:
                raise CacheError(
                    f"palette: corrupt catches or shifts ({type(exc).__name__}: {exc}); "
                    "rebuild it with `gracenav palette build`"
                ) from None
        return self._policies

    def __len__(self) -> int:
        return len(self._entries)

    @overload
    def __getitem__(self, i: int) -> MotionPolicy: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[MotionPolicy]: ...
    def __getitem__(self, i: int | slice) -> MotionPolicy | Sequence[MotionPolicy]:
        return self._get()[i]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Sequence):
            return tuple(self._get()) == tuple(other)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"PlacedPolicies({len(self)} policies)"


def _read_palette(path: Path) -> Palette:
    """Read ``path`` and check its key against the inputs stored in it."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CacheError(
            f"cannot read palette file {path}: {exc.strerror}; build one with "
            "`gracenav palette build`"
        ) from None
    pal = Palette.from_bytes(data, source=str(path))
    if pal.key != pal.expected_key():
        raise CacheError(
            f"{path}: palette key does not match the inputs stored in it (stale or edited "
            "file); rebuild it with `gracenav palette build`"
        )
    return pal


def _redesign(gains: ControllerGains) -> ControllerGains:
    """The gains designed anew from ``gains``' design inputs (hand-given gains as given)."""
    if gains.weights is None:
        return gains
    return design_gains(
        gains.params,
        gains.weights,
        max_lean_compensation=gains.max_lean_compensation,
        friction_compensation=gains.friction_compensation,
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
    build: bool = True,
    processes: int | None = None,
    progress: bool = True,
) -> Palette:
    """The palette for the requested robot, controller, verification options and d.

    Without ``path`` (and without ``$GRACENAV_PALETTE``), the palette shipped with
    gracenav is returned when it was built from the requested inputs; otherwise a
    matching palette from the user cache (:func:`cached_palette_path`), and when
    there is none (or it is corrupt) one is built once, with a progress bar, and
    cached atomically. A palette "matches" when its key (a hash of the inputs,
    :func:`palette_key`) is the requested one and its stored gains equal the
    requested gains within a relative :data:`GAINS_RTOL`.

    Parameters
    ----------
    path : str or Path, optional
        Force this palette file (default ``$GRACENAV_PALETTE`` if set). A forced file
        that does not match the request is an error, never rebuilt.
    params, gains, options, d : optional
        What the palette must have been built for. Defaults: for a forced file, what
        it was built for (its gains designed anew from its design inputs and
        compared); otherwise the CMU ballbot, :func:`gracenav.control.design_gains`
        on ``params``, default :class:`VerificationOptions` and d = 0.5 m.
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
        pal = _read_palette(Path(forced))
        # What is not asked for is what the file was built for; its gains are then
        # designed anew from the file's design inputs and compared, as for any request.
        params = params if params is not None else pal.params
        if gains is None:
            gains = _redesign(pal.gains) if params == pal.params else design_gains(params)
        options = options if options is not None else pal.options
        why = _mismatch(pal, params, gains, options, d if d is not None else pal.d)
        if why is not None:
            raise CacheError(
                f"{forced}: this palette cannot be used: {why}. Leave out --palette / "
                f"${PALETTE_ENV} to use (or build once) a matching palette, or rebuild this "
                "file with `gracenav palette build --out FILE`"
            )
        return pal
    params = params if params is not None else BallbotParams()
    gains = gains if gains is not None else design_gains(params)
    options = options if options is not None else VerificationOptions()
    d = float(d) if d is not None else 0.5
    key = palette_key(params, gains, options, d)
    for candidate in (shipped_palette_path(), cached_palette_path(key)):
        if not candidate.is_file():
            continue
        try:
            pal = _read_palette(candidate)
        except CacheError:
            continue  # a corrupt or stale cache file is rebuilt below
        if _mismatch(pal, params, gains, options, d) is None:
            return pal
    if not build:
        raise CacheError(
            "no palette matches the requested robot parameters, controller, verification "
            f"options and d = {d} m; build one with `gracenav palette build`"
        )
    pal = build_palette_for(
        params=params, gains=gains, options=options, d=d, processes=processes, progress=progress
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
) -> Palette:
    """Plan the primitive set Σ(d) and build its palette (see :func:`build_palette`)."""
    from gracenav.policies import SampledPrimitive
    from gracenav.primitives import primitive_set

    prims = [SampledPrimitive.from_primitive(p) for p in primitive_set(d=d, params=params)]
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
    )


def _size_one(
    args: tuple[SampledPrimitive, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The policy of one primitive sized by bisection, then its verified larger variants."""
    from gracenav.policies import scaled_variants, size_policy

    prim, gains, options, shape = args
    base = size_policy(prim, gains, options, shape=shape)
    if base.report is None or not base.report.passed:
        return (base,)
    return (base, *scaled_variants(base, options))


def _regulators(
    args: tuple[ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The capture regulators of ``options.regulator`` (see
    :func:`gracenav.policies.regulator_policies`), verified."""
    from gracenav.policies import regulator_policies
    from gracenav.primitives import TrimPrimitive

    gains, options, shape = args
    reg = options.regulator
    if reg is None:
        return ()
    zero = np.zeros(2)
    prim = SampledPrimitive.from_primitive(
        TrimPrimitive(REGULATOR_NAME, reg.duration, zero, zero, zero, gains.params)
    )
    goal = shape.radii(options.goal_position_extent)
    return regulator_policies(prim, gains, options, goal, shape.correlation)


def _braking_one(
    args: tuple[float, tuple[int, int], float, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """One braking maneuver (see :mod:`gracenav.primitives.braking`), planned and verified at every
    size; empty if no stopping distance is feasible."""
    from gracenav.primitives.braking import braking_policies, braking_primitive

    speed, direction, step, gains, options, shape = args
    assert options.braking is not None
    prim = braking_primitive(speed, direction, step, options.braking, gains)
    if prim is None:
        return ()
    return braking_policies(prim, gains, options, shape)


def _catch_classes(speed: float, options: CatchOptions) -> tuple[str, ...]:
    """The lean classes of the catches from ``speed`` (m/s) the options ask for."""
    return (
        *((PUSHED,) if speed in options.speeds else ()),
        *((SETTLED,) if speed in options.speeds or speed in options.settled_speeds else ()),
        *((STILL,) if speed in options.still_speeds else ()),
    )


def _catch_one(
    args: tuple[float, tuple[str, ...], ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """The catches of some lean classes from one speed (see
    :func:`gracenav.policies.catches.catch_policies`)."""
    from gracenav.policies import RegulatorOptions, push_lean_table

    speed, classes, gains, options, shape = args
    pushes = options.regulator or RegulatorOptions()  # the regulators' push table
    push_leans = push_lean_table(gains, pushes.push_impulses, pushes.push_times)
    return catch_policies(speed, gains, options, shape, push_leans, classes=classes)


def _shift_one(
    args: tuple[tuple[int, int], float, ControllerGains, VerificationOptions, DomainShape],
) -> tuple[MotionPolicy, ...]:
    """One shift (see :func:`gracenav.policies.catches.shift_policies`)."""
    cell, d, gains, options, shape = args
    return shift_policies(cell, d, gains, options, shape)


def _rotation_duplicate(prim: SampledPrimitive, earlier: Sequence[SampledPrimitive]) -> str | None:
    """Name of an earlier primitive of which ``prim`` is a 90°, 180° or 270° rotation."""
    for other in earlier:
        if other.kind is not prim.kind or other.num_ticks != prim.num_ticks:
            continue
        for k in (1, 2, 3):
            c, s = ((0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[k - 1]
            rot = np.array([[c, -s], [s, c]])
            pos = other.position.reshape(-1, 3, 2) @ rot.T
            if np.allclose(pos.reshape(-1, 6), prim.position, rtol=0.0, atol=1e-9):
                return f"{other.name} rotated by {90 * k}°"
    return None


def build_palette(
    primitives: Sequence[SampledPrimitive],
    *,
    d: float,
    params: BallbotParams | None = None,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    processes: int = 2,
    progress: bool = True,
) -> Palette:
    """Size and verify one policy per primitive, then its larger-domain variants; keep
    those that pass.

    Each primitive's policy is sized by bisection on S/G up to ``options.max_scale``;
    then the sizes of ``options.scale_ladder`` are verified in turn
    (:func:`gracenav.policies.scaled_variants`) and every one that passes is kept as a
    labelled variant sharing the primitive (instantiation places the largest that fits).

    Parameters
    ----------
    primitives : sequence of SampledPrimitive
        The primitive set Σ(d), sampled at the control rate.
    d : float
        Distance parameter (m).
    params : BallbotParams, optional
        Plant and nominal controller parameters.
    gains : ControllerGains, optional
        Control law (default: :func:`gracenav.control.design_gains` on ``params``).
    options : VerificationOptions, optional
    processes : int
        Worker processes (1 runs in this process).
    progress : bool
        Show a progress bar on a terminal.

    Returns
    -------
    Palette
    """
    from gracenav._util.progress import Progress
    from gracenav.policies import domain_shape

    params = params if params is not None else BallbotParams()
    gains = gains if gains is not None else design_gains(params)
    options = options if options is not None else VerificationOptions()
    shape = domain_shape(gains, horizon=options.shape_horizon)
    unique: list[SampledPrimitive] = []
    duplicates: list[tuple[str, str]] = []
    for prim in primitives:
        dup = _rotation_duplicate(prim, unique)
        if dup is None:
            unique.append(prim)
        else:
            duplicates.append((prim.name, dup))
    jobs = [(p, gains, options, shape) for p in unique]
    brk = options.braking
    brake_jobs = (
        []
        if brk is None
        else [
            (v, dirn, d / brk.lattice_divisions, gains, options, shape)
            for v in brk.speeds
            for dirn in brk.directions
        ]
    )
    cat = options.catch
    catch_jobs = (
        []
        if cat is None
        else [
            (v, _catch_classes(v, cat), gains, options, shape)
            for v in sorted({*cat.speeds, *cat.settled_speeds, *cat.still_speeds})
        ]
    )
    shift_jobs = [] if cat is None else [(c, d, gains, options, shape) for c in shift_cells(cat, d)]
    results: list[MotionPolicy] = []
    catches: list[MotionPolicy] = []
    shifts: list[MotionPolicy] = []
    total = (
        len(jobs)
        + len(brake_jobs)
        + len(catch_jobs)
        + len(shift_jobs)
        + (options.regulator is not None)
    )
    with Progress(total, "verifying policies", enabled=progress) as bar:
        if processes <= 1:
            for job in jobs:
                results.extend(_size_one(job))
                bar.update()
            if options.regulator is not None:
                results.extend(_regulators((gains, options, shape)))
                bar.update()
            for bjob in brake_jobs:
                results.extend(_braking_one(bjob))
                bar.update()
            for cjob in catch_jobs:
                catches.extend(_catch_one(cjob))
                bar.update()
            for sjob in shift_jobs:
                shifts.extend(_shift_one(sjob))
                bar.update()
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
            with ProcessPoolExecutor(max_workers=processes, mp_context=ctx) as pool:
                # The regulators (the longest job) first, so that they overlap the rest.
                regs = (
                    pool.submit(_regulators, (gains, options, shape))
                    if options.regulator is not None
                    else None
                )
                brakes = [pool.submit(_braking_one, bjob) for bjob in brake_jobs]
                catch_futs = [pool.submit(_catch_one, cjob) for cjob in catch_jobs]
                shift_futs = [pool.submit(_shift_one, sjob) for sjob in shift_jobs]
                for sized in pool.map(_size_one, jobs):
                    results.extend(sized)
                    bar.update()
                for fut in brakes:
                    results.extend(fut.result())
                    bar.update()
                for fut in catch_futs:
                    catches.extend(fut.result())
                    bar.update()
                for fut in shift_futs:
                    shifts.extend(fut.result())
                    bar.update()
                if regs is not None:
                    results.extend(regs.result())
                    bar.update()

    def verified(pols: list[MotionPolicy]) -> tuple[MotionPolicy, ...]:
        return tuple(p for p in pols if p.report is not None and p.report.passed)

    passed = verified(results)
    rejected = tuple(
        (p.name, p.report)
        for p in (*results, *catches, *shifts)
        if p.report is not None and not p.report.passed
    )
    return Palette(
        policies=passed,
        rejected=rejected,
        duplicates=tuple(duplicates),
        d=d,
        params=params,
        options=options,
        key=palette_key(params, gains, options, d),
        catches=verified(catches),
        shifts=verified(shifts),
    )
