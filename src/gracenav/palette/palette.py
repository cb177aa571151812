"""The palette Π: the verified motion policies of one robot and controller (lattice
maneuvers and trims, capture regulators, catches and shifts) and how they are stored."""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import zipfile
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

from gracenav._util.io import atomic_write_bytes
from gracenav.control import ControllerGains, LQRWeights, design_gains
from gracenav.errors import CacheError, ConfigError
from gracenav.params import BallbotParams
from gracenav.policies import (
    BrakingOptions,
    CatchOptions,
    DomainRadii,
    MotionPolicy,
    PrimitiveKind,
    RegulatorOptions,
    SampledPrimitive,
    VerificationOptions,
    VerificationReport,
)
from gracenav.primitives import PrimitiveSetOptions

__all__ = ["PALETTE_FORMAT", "Palette", "palette_key"]

PALETTE_FORMAT = 5

#: Primitive name of the capture regulators (a rest trim held
#: ``RegulatorOptions.duration``).
REGULATOR_NAME = "regulate"

#: Primitives are stored at every COARSE_STRIDE-th control tick (1/128 s) and
#: rebuilt exactly enough (see SampledPrimitive.from_coarse) when loaded.
COARSE_STRIDE = 8

#: Bumped whenever the planner, controller or verification code changes results.
ALGORITHM_VERSION = "10"


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
            "options": _options_key(options),
            "primitives": primitive_options.to_dict(),
            "d": float(d),
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


def _options_key(options: VerificationOptions) -> dict[str, Any]:
    """The verification options as hashed: a catch option added later
    (:attr:`CatchOptions.ADDED_LATER`) is left out at the value that reproduces the
    palettes built before it, so their keys stay valid."""
    data = dataclasses.asdict(options)
    catch = data.get("catch")
    if catch is not None:
        for name, before in CatchOptions.ADDED_LATER.items():
            if catch.get(name, before) == before:
                catch.pop(name, None)
    return data


@dataclass(frozen=True)
class Palette:
    """A motion policy palette Π(Σ): unique verified policies of the primitive set Σ(d).

    Attributes
    ----------
    policies : tuple of MotionPolicy
        The verified policies (first-quadrant primitives; instantiation rotates them):
        for each primitive the policy sized by bisection, followed by its larger-domain
        variants (scaled domains, named ``<primitive>[S=<s>G]``) and its fine copies
        (every domain scaled down, named ``<primitive>[x<λ>]``), which share its
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
                "friction_midpoint": self.gains.friction_midpoint,
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
                    "still_report": (
                        None if pol.still_report is None else dataclasses.asdict(pol.still_report)
                    ),
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
                # Palettes written before the midpoint feed-forward existed have none.
                friction_midpoint=bool(gp.get("friction_midpoint", False)),
            )
            opts = dict(header["options"])
            opts["scale_ladder"] = tuple(opts["scale_ladder"])
            # Palettes written before fine copies existed have none.
            opts.setdefault("fine_scales", ())
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
                still_report=(
                    None
                    if meta.get("still_report") is None
                    else VerificationReport(**meta["still_report"])
                ),
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
