"""The primitive set Σ(d), built once per lattice spacing, parameters and options and
kept in the user cache (keyed by the inputs, never by computed floats)."""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gracenav._util.cache import cache_dir
from gracenav._util.io import atomic_write_bytes
from gracenav.errors import CacheError, ConfigError
from gracenav.params import BallbotParams
from gracenav.primitives.design import _build
from gracenav.primitives.motion import (
    FloatArray,
    Maneuver,
    MotionPrimitive,
    PrimitiveReport,
    PrimitiveSet,
    PrimitiveSetOptions,
    TrimPrimitive,
    _frozen,
)
from gracenav.primitives.shape_planner import ShapeTrajectory

__all__ = ["CODE_VERSION", "primitive_set"]

CODE_VERSION = "primitives-1"
"""Version of the primitive-set construction; part of the cache key."""


# --------------------------------------------------------------------------------------
# Cache
# --------------------------------------------------------------------------------------
def _cache_key(d: float, params: BallbotParams, options: PrimitiveSetOptions) -> str:
    payload = json.dumps(
        {
            "version": CODE_VERSION,
            "d": float(d),
            "params": params.to_dict(),
            "options": options.to_dict(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()


def _digest(arrays: Mapping[str, FloatArray]) -> str:
    h = hashlib.blake2b(digest_size=32)
    for key in sorted(arrays):
        a = np.ascontiguousarray(arrays[key])
        h.update(key.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


_TRAJ_FIELDS = ("knots", "coefficients", "theta", "theta_dot", "theta_ddot")


def _encode(pset: PrimitiveSet, key: str) -> bytes:
    arrays: dict[str, FloatArray] = {}
    records: list[dict[str, Any]] = []
    for i, p in enumerate(pset.primitives):
        rec: dict[str, Any] = {
            "name": p.name,
            "type": "trim" if isinstance(p, TrimPrimitive) else "maneuver",
            "duration": p.duration,
            "displacement": p.displacement.tolist(),
            "start_velocity": p.start_velocity.tolist(),
            "end_velocity": p.end_velocity.tolist(),
        }
        if isinstance(p, Maneuver):
            rec["start_trim"] = p.start_trim
            rec["end_trim"] = p.end_trim
            rec["reports"] = [dataclasses.asdict(r) for r in p.reports or ()]
            for o, traj in enumerate(p._plans()):
                for f in _TRAJ_FIELDS:
                    arrays[f"p{i}_o{o}_{f}"] = getattr(traj, f)
        records.append(rec)
    meta = {
        "key": key,
        "version": CODE_VERSION,
        "step": pset.options.planner.step,
        "primitives": records,
        "omitted": list(pset.omitted),
        "digest": _digest(arrays),
    }
    buf = io.BytesIO()
    members: dict[str, Any] = dict(arrays)
    members["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(buf, **members)
    return buf.getvalue()


def _decode(
    data: bytes, key: str, d: float, params: BallbotParams, options: PrimitiveSetOptions
) -> PrimitiveSet:
    """Rebuild a set from cache bytes; raises CacheError if anything does not match."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays.pop("__meta__").tobytes().decode())
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        raise CacheError(f"unreadable primitive cache: {exc}") from None
    if not isinstance(meta, dict):
        raise CacheError("primitive cache metadata is not a mapping")
    if meta.get("key") != key or meta.get("version") != CODE_VERSION:
        raise CacheError("primitive cache key does not match")
    if meta.get("digest") != _digest(arrays):
        raise CacheError("primitive cache arrays do not match their digest")
    try:
        prims: list[MotionPrimitive] = []
        for i, rec in enumerate(meta["primitives"]):
            common = {
                "name": rec["name"],
                "duration": float(rec["duration"]),
                "displacement": _frozen(rec["displacement"]),
                "start_velocity": _frozen(rec["start_velocity"]),
                "end_velocity": _frozen(rec["end_velocity"]),
                "params": params,
            }
            if rec["type"] == "trim":
                prims.append(TrimPrimitive(**common))
                continue
            plans = tuple(
                ShapeTrajectory(
                    params,
                    "3d",
                    float(rec["duration"]),
                    float(meta["step"]),
                    *(arrays[f"p{i}_o{o}_{f}"] for f in _TRAJ_FIELDS),
                )
                for o in range(2)
            )
            reports = tuple(PrimitiveReport(**r) for r in rec["reports"])
            prims.append(
                Maneuver(
                    **common,
                    start_trim=rec["start_trim"],
                    end_trim=rec["end_trim"],
                    plans=plans,  # type: ignore[arg-type]
                    reports=reports,  # type: ignore[arg-type]
                )
            )
        return PrimitiveSet(d, params, options, tuple(prims), tuple(meta["omitted"]))
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise CacheError(f"malformed primitive cache: {exc}") from None


def _cache_path(key: str) -> Path:
    return cache_dir() / f"primitives-{key[:24]}.npz"


def primitive_set(
    d: float = 0.5,
    params: BallbotParams | None = None,
    *,
    options: PrimitiveSetOptions | None = None,
    cache: bool = True,
) -> PrimitiveSet:
    """The motion primitive set Σ(d) (about 40 primitives).

    Trims: ``rest``, ``capture`` (a longer rest trim for catching a moving robot),
    ``cruise_x``, ``cruise_y``, ``cruise_xy``. Maneuvers,
    named ``<start>_to_<end>_<i>_<j>`` with displacement (i d, j d): rest to
    rest; start and stop along an axis and the diagonal; 45° and 90° turns in
    both directions; lane changes; U-turns. Each maneuver has the shortest
    duration on the ``options.duration_step`` grid (at most
    ``options.max_duration``) for which its 3D plans in both frames (0° and
    90°) keep the tilt within ``options.max_lean`` and the torque within
    ``params.torque_limit``, with friction.

    Parameters
    ----------
    d : float
        Distance parameter (m).
    params : BallbotParams, optional
        Model parameters (default: the CMU ballbot).
    options : PrimitiveSetOptions, optional
    cache : bool
        Read and write the on-disk cache (see :func:`cache_dir`). A cache file
        that is unreadable, corrupt or for another key is ignored, recomputed
        and overwritten.

    Returns
    -------
    PrimitiveSet
    """
    if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0):
        raise ConfigError(f"distance parameter d must be positive, got {d!r}")
    params = params if params is not None else BallbotParams()
    options = options if options is not None else PrimitiveSetOptions()
    d = float(d)
    key = _cache_key(d, params, options)
    path = _cache_path(key)
    if cache and path.is_file():
        try:
            return _decode(path.read_bytes(), key, d, params, options)
        except (CacheError, OSError):
            pass  # recompute and overwrite below
    pset = _build(d, params, options)
    if cache:
        try:
            atomic_write_bytes(path, _encode(pset, key))
        except OSError:
            pass  # a read-only cache directory only costs the recomputation
    return pset
