"""The motion policy palette Π(Σ): verified policies stored as a versioned data file.

A palette file is a single ``.npz`` archive (no pickle) holding a JSON header
and the sampled primitives of every policy. The header carries a key, a hash
of everything the palette depends on (robot parameters, controller gains,
verification options, distance parameter d, file format and code version).
Loading checks the archive's integrity and the key; a stale, corrupt or
mismatched file raises :class:`gracenav.errors.CacheError` and is never used.
Files are written atomically.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from gracenav._io import atomic_write_bytes
from gracenav.control import ControllerGains, design_gains
from gracenav.errors import CacheError, ConfigError
from gracenav.params import BallbotParams
from gracenav.policies import (
    DomainRadii,
    DomainShape,
    MotionPolicy,
    PrimitiveKind,
    SampledPrimitive,
    VerificationOptions,
    VerificationReport,
)

__all__ = [
    "PALETTE_FORMAT",
    "Palette",
    "build_palette",
    "load_palette",
    "palette_key",
    "shipped_palette_path",
]

PALETTE_FORMAT = 1
#: Primitives are stored at every COARSE_STRIDE-th control tick (1/128 s) and
#: rebuilt exactly enough (see SampledPrimitive.from_coarse) when loaded.
COARSE_STRIDE = 8
#: Bumped whenever the planner, controller or verification code changes results.
ALGORITHM_VERSION = "1"


def palette_key(
    params: BallbotParams, gains: ControllerGains, options: VerificationOptions, d: float
) -> str:
    """Hash (hex SHA-256) of everything a palette's content depends on."""
    blob = json.dumps(
        {
            "format": PALETTE_FORMAT,
            "algorithm": ALGORITHM_VERSION,
            "params": params.to_dict(),
            "gains": {
                "lqr": np.round(gains.lqr, 12).tolist(),
                "params": gains.params.to_dict(),
                "max_lean_compensation": gains.max_lean_compensation,
                "friction_compensation": gains.friction_compensation,
            },
            "options": dataclasses.asdict(options),
            "d": d,
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
        The verified policies (first-quadrant primitives; instantiation rotates them).
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
    """

    policies: tuple[MotionPolicy, ...]
    rejected: tuple[tuple[str, VerificationReport], ...]
    duplicates: tuple[tuple[str, str], ...]
    d: float
    params: BallbotParams
    options: VerificationOptions
    key: str

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
            "gains": {
                "lqr": self.gains.lqr.tolist(),
                "params": self.gains.params.to_dict(),
                "max_lean_compensation": self.gains.max_lean_compensation,
                "friction_compensation": self.gains.friction_compensation,
            },
            "policies": [],
            "rejected": [[n, dataclasses.asdict(r)] for n, r in self.rejected],
            "duplicates": [list(x) for x in self.duplicates],
        }
        arrays: dict[str, np.ndarray] = {}
        for i, pol in enumerate(self.policies):
            prim = pol.primitive
            header["policies"].append(
                {
                    "name": prim.name,
                    "kind": prim.kind.value,
                    "duration": prim.duration,
                    "dt": prim.dt,
                    "displacement": prim.displacement.tolist(),
                    "start_velocity": prim.start_velocity.tolist(),
                    "end_velocity": prim.end_velocity.tolist(),
                    "start_radii": dataclasses.asdict(pol.start_radii),
                    "goal_radii": dataclasses.asdict(pol.goal_radii),
                    "outer_factors": list(pol.outer_factors),
                    "correlation": pol.correlation,
                    "report": None if pol.report is None else dataclasses.asdict(pol.report),
                }
            )
            stride = COARSE_STRIDE if prim.num_ticks % COARSE_STRIDE == 0 else 1
            header["policies"][-1]["stride"] = stride
            arrays[f"p{i}_states"], arrays[f"p{i}_accelerations"] = prim.coarse(stride)
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
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            header = json.loads(arrays.pop("header").tobytes().decode())
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
            )
            options = VerificationOptions(**header["options"])
            policies = []
            for i, meta in enumerate(header["policies"]):
                prim = SampledPrimitive.from_coarse(
                    arrays[f"p{i}_states"],
                    arrays[f"p{i}_accelerations"],
                    int(meta["stride"]),
                    name=meta["name"],
                    kind=PrimitiveKind(meta["kind"]),
                    dt=float(meta["dt"]),
                    displacement=np.asarray(meta["displacement"], dtype=float),
                    start_velocity=np.asarray(meta["start_velocity"], dtype=float),
                    end_velocity=np.asarray(meta["end_velocity"], dtype=float),
                    params=params,
                )
                if abs(prim.duration - float(meta["duration"])) > 1e-9:
                    raise ValueError(f"policy {meta['name']}: samples do not span its duration")
                rep = meta["report"]
                policies.append(
                    MotionPolicy(
                        primitive=prim,
                        gains=gains,
                        start_radii=DomainRadii(**meta["start_radii"]),
                        goal_radii=DomainRadii(**meta["goal_radii"]),
                        outer_factors=(
                            float(meta["outer_factors"][0]),
                            float(meta["outer_factors"][1]),
                        ),
                        correlation=float(meta["correlation"]),
                        report=None if rep is None else VerificationReport(**rep),
                    )
                )
            rejected = tuple((str(n), VerificationReport(**r)) for n, r in header["rejected"])
            return cls(
                policies=tuple(policies),
                rejected=rejected,
                duplicates=tuple((str(a), str(b)) for a, b in header["duplicates"]),
                d=float(header["d"]),
                params=params,
                options=options,
                key=str(header["key"]),
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
        """The key this palette's own content should carry."""
        return palette_key(self.params, self.gains, self.options, self.d)


def load_palette(
    path: str | Path | None = None,
    *,
    params: BallbotParams | None = None,
    gains: ControllerGains | None = None,
    options: VerificationOptions | None = None,
    d: float | None = None,
) -> Palette:
    """Load a palette file (default: the one shipped with gracenav) and check its key.

    Parameters
    ----------
    path : str or Path, optional
        Palette file; default :func:`shipped_palette_path`.
    params, gains, options, d : optional
        What the caller expects the palette to have been built for (default: the
        defaults of this version of gracenav). A palette built for anything else is
        refused.

    Raises
    ------
    CacheError
        Missing, corrupt, stale (built by another algorithm version) or mismatched file.
    """
    path = Path(path) if path is not None else shipped_palette_path()
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
            f"{path}: palette key does not match its content (stale or edited file); "
            "rebuild it with `gracenav palette build`"
        )
    params = params if params is not None else BallbotParams()
    gains = gains if gains is not None else design_gains(params)
    options = options if options is not None else VerificationOptions()
    d = d if d is not None else pal.d
    want = palette_key(params, gains, options, d)
    if pal.key != want:
        raise CacheError(
            f"{path}: palette was built for other robot parameters, gains, verification options "
            f"or d than requested (key {pal.key[:12]} != {want[:12]}); rebuild it with "
            "`gracenav palette build`"
        )
    return pal


def _size_one(
    args: tuple[SampledPrimitive, ControllerGains, VerificationOptions, DomainShape],
) -> MotionPolicy:
    from gracenav.policies import size_policy

    prim, gains, options, shape = args
    return size_policy(prim, gains, options, shape=shape)


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
    """Size and verify one policy per primitive; keep those that pass.

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
    from gracenav._progress import Progress
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
    results: list[MotionPolicy] = []
    with Progress(len(jobs), "verifying policies", enabled=progress) as bar:
        if processes <= 1:
            for job in jobs:
                results.append(_size_one(job))
                bar.update()
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
            with ProcessPoolExecutor(max_workers=processes, mp_context=ctx) as pool:
                for pol in pool.map(_size_one, jobs):
                    results.append(pol)
                    bar.update()
    passed = tuple(p for p in results if p.report is not None and p.report.passed)
    rejected = tuple(
        (p.name, p.report) for p in results if p.report is not None and not p.report.passed
    )
    return Palette(
        policies=passed,
        rejected=rejected,
        duplicates=tuple(duplicates),
        d=d,
        params=params,
        options=options,
        key=palette_key(params, gains, options, d),
    )
