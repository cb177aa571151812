"""Runs as MCAP files that Foxglove opens: the map, the robot, its funnels and its
time series.

Every channel is JSON-encoded with a JSON schema; the standard ones carry Foxglove's
schema names (``foxglove.Grid``, ``foxglove.FrameTransform``, ``foxglove.SceneUpdate``,
``foxglove.Log``), so Foxglove's 3D panel draws the map, the robot and the domains, and
its Plot panel plots any field of the two gracenav channels (``gracenav.State``,
``gracenav.Push``). Frames follow REP-105: ``map`` (the world, the scenario's frame)
and ``base_link`` (the ball's centre, tilted with the body). Times are log times in
nanoseconds; :class:`McapRunLog` is written incrementally (a ROS node records with it
live), :func:`write_scenario_log` writes a whole ``gracenav run``.

========================  ========================  ===========================================
topic                     schema                    content
========================  ========================  ===========================================
``/map``                  foxglove.Grid             occupancy (uint8 ``occupied``: 0 free, 100
                                                    obstacle), frame ``map``, once per run
``/tf``                   foxglove.FrameTransform   ``map`` → ``base_link``: ball centre and
                                                    body lean, every sample
``/gracenav/state``       gracenav.State            run, t, position state, lean, lean rate,
                                                    torque, reference, policy, every sample
``/gracenav/robot``       foxglove.SceneUpdate      the robot (ball, body, footprint) in
                                                    ``base_link``; the goals in ``map``
``/gracenav/domains``     foxglove.SceneUpdate      the running policy's S, G, D'(t) and
                                                    reference, at every switch
``/gracenav/path``        foxglove.SceneUpdate      the path travelled and the reference
``/gracenav/events``      foxglove.Log              switches, pushes, goals, run ends
``/gracenav/pushes``      gracenav.Push             every push: time, place, impulse (N s)
========================  ========================  ===========================================
"""

from __future__ import annotations

import base64
import json
import math
import os
import tempfile
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gracenav.errors import ConfigError, OutputError

__all__ = [
    "LOG_CHANNELS",
    "McapRunLog",
    "lean_from_quaternion",
    "lean_quaternion",
    "write_scenario_log",
]

FloatArray = NDArray[np.float64]

#: Topic → schema name of every channel a log holds.
LOG_CHANNELS: dict[str, str] = {
    "/map": "foxglove.Grid",
    "/tf": "foxglove.FrameTransform",
    "/gracenav/state": "gracenav.State",
    "/gracenav/robot": "foxglove.SceneUpdate",
    "/gracenav/domains": "foxglove.SceneUpdate",
    "/gracenav/path": "foxglove.SceneUpdate",
    "/gracenav/events": "foxglove.Log",
    "/gracenav/pushes": "gracenav.Push",
}

#: Body drawn above the ball (m): a cylinder of this height and diameter.
_BODY_HEIGHT = 1.5
_BODY_DIAMETER = 0.35
#: Seconds between runs in one log.
RUN_GAP = 1.0
#: foxglove.Log levels.
INFO, WARNING = 2, 3


# -- geometry -------------------------------------------------------------------------
def lean_quaternion(lean: ArrayLike) -> tuple[float, float, float, float]:
    """Body orientation (x, y, z, w) of the lean (φ_x, φ_y) (rad): R = R_y(φ_x) R_x(−φ_y),
    so the body axis leans toward +x by φ_x and toward +y by φ_y (REP-103 axes)."""
    ax, ay = (float(v) for v in np.asarray(lean, dtype=float)[:2])
    cy, sy = math.cos(0.5 * ax), math.sin(0.5 * ax)  # about y by φ_x
    cx, sx = math.cos(-0.5 * ay), math.sin(-0.5 * ay)  # about x by −φ_y
    # q_y ⊗ q_x with q_y = (0, sy, 0, cy), q_x = (sx, 0, 0, cx)
    return (cy * sx, sy * cx, -sy * sx, cy * cx)


def lean_from_quaternion(q: Sequence[float]) -> FloatArray:
    """The lean (φ_x, φ_y) (rad) of a body orientation (x, y, z, w): the inverse of
    :func:`lean_quaternion` (the yaw of ``q``, which the model does not have, is ignored)."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not n > 0.0:
        raise ConfigError("a body orientation quaternion must not be zero")
    x, y, z, w = x / n, y / n, z / n, w / n
    # body z axis in the world: (cos φ_y sin φ_x, sin φ_y, cos φ_y cos φ_x)
    bx = 2.0 * (x * z + w * y)
    by = 2.0 * (y * z - w * x)
    bz = 1.0 - 2.0 * (x * x + y * y)
    return np.array([math.atan2(bx, bz), math.asin(max(-1.0, min(1.0, by)))])


def ellipse_outline(shape_xy: FloatArray, center: ArrayLike, n: int = 49) -> FloatArray:
    """Points (n, 2) of {u : (u − c)ᵀ Q (u − c) = 1} (closed: first = last)."""
    ang = np.linspace(0.0, 2.0 * np.pi, n)
    ell = np.linalg.cholesky(np.linalg.inv(shape_xy))
    c = np.asarray(center, dtype=float)[:2]
    out: FloatArray = c + (ell @ np.vstack([np.cos(ang), np.sin(ang)])).T
    return out


# -- schemas --------------------------------------------------------------------------
def _obj(props: dict[str, Any], title: str | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"type": "object", "properties": props}
    if title is not None:
        out["title"] = title
    return out


_NUM = {"type": "number"}
_INT = {"type": "integer"}
_STR = {"type": "string"}
_BOOL = {"type": "boolean"}
_TIME = _obj({"sec": _INT, "nsec": _INT})
_VEC3 = _obj({"x": _NUM, "y": _NUM, "z": _NUM})
_VEC2 = _obj({"x": _NUM, "y": _NUM})
_QUAT = _obj({"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM})
_POSE = _obj({"position": _VEC3, "orientation": _QUAT})
_COLOR = _obj({"r": _NUM, "g": _NUM, "b": _NUM, "a": _NUM})


def _array(item: dict[str, Any]) -> dict[str, Any]:
    return {"type": "array", "items": item}


_LINE = _obj(
    {
        "type": _INT,
        "pose": _POSE,
        "thickness": _NUM,
        "scale_invariant": _BOOL,
        "points": _array(_VEC3),
        "color": _COLOR,
        "colors": _array(_COLOR),
        "indices": _array(_INT),
    }
)
_SHAPE = _obj({"pose": _POSE, "size": _VEC3, "color": _COLOR})
_CYLINDER = _obj(
    {"pose": _POSE, "size": _VEC3, "bottom_scale": _NUM, "top_scale": _NUM, "color": _COLOR}
)
_ARROW = _obj(
    {
        "pose": _POSE,
        "shaft_length": _NUM,
        "shaft_diameter": _NUM,
        "head_length": _NUM,
        "head_diameter": _NUM,
        "color": _COLOR,
    }
)
_TEXT = _obj(
    {
        "pose": _POSE,
        "billboard": _BOOL,
        "font_size": _NUM,
        "scale_invariant": _BOOL,
        "color": _COLOR,
        "text": _STR,
    }
)
_ENTITY = _obj(
    {
        "timestamp": _TIME,
        "frame_id": _STR,
        "id": _STR,
        "lifetime": _TIME,
        "frame_locked": _BOOL,
        "metadata": _array(_obj({"key": _STR, "value": _STR})),
        "arrows": _array(_ARROW),
        "cubes": _array(_SHAPE),
        "spheres": _array(_SHAPE),
        "cylinders": _array(_CYLINDER),
        "lines": _array(_LINE),
        "triangles": _array(_obj({})),
        "texts": _array(_TEXT),
        "models": _array(_obj({})),
    }
)

SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.Grid": _obj(
        {
            "timestamp": _TIME,
            "frame_id": _STR,
            "pose": _POSE,
            "column_count": _INT,
            "cell_size": _VEC2,
            "row_stride": _INT,
            "cell_stride": _INT,
            "fields": _array(_obj({"name": _STR, "offset": _INT, "type": _INT})),
            "data": {"type": "string", "contentEncoding": "base64"},
        },
        "foxglove.Grid",
    ),
    "foxglove.FrameTransform": _obj(
        {
            "timestamp": _TIME,
            "parent_frame_id": _STR,
            "child_frame_id": _STR,
            "translation": _VEC3,
            "rotation": _QUAT,
        },
        "foxglove.FrameTransform",
    ),
    "foxglove.SceneUpdate": _obj(
        {
            "deletions": _array(_obj({"timestamp": _TIME, "type": _INT, "id": _STR})),
            "entities": _array(_ENTITY),
        },
        "foxglove.SceneUpdate",
    ),
    "foxglove.Log": _obj(
        {
            "timestamp": _TIME,
            "level": _INT,
            "message": _STR,
            "name": _STR,
            "file": _STR,
            "line": _INT,
        },
        "foxglove.Log",
    ),
    "gracenav.State": _obj(
        {
            "timestamp": _TIME,
            "run": _INT,
            "t": {"type": "number", "description": "time since the run started (s)"},
            "x": _NUM,
            "y": _NUM,
            "xdot": _NUM,
            "ydot": _NUM,
            "lean_x": {"type": "number", "description": "body lean toward +x (rad)"},
            "lean_y": {"type": "number", "description": "body lean toward +y (rad)"},
            "lean_rate_x": _NUM,
            "lean_rate_y": _NUM,
            "tau_x": {"type": "number", "description": "generalised torque on θ_x (N m)"},
            "tau_y": {"type": "number", "description": "generalised torque on θ_y (N m)"},
            "ref_x": _NUM,
            "ref_y": _NUM,
            "ref_xdot": _NUM,
            "ref_ydot": _NUM,
            "policy": {"type": "integer", "description": "library row (<0: not a row)"},
        },
        "gracenav.State",
    ),
    "gracenav.Push": _obj(
        {
            "timestamp": _TIME,
            "run": _INT,
            "t": _NUM,
            "position": _VEC2,
            "impulse": {"type": "object", "properties": {"x": _NUM, "y": _NUM}},
        },
        "gracenav.Push",
    ),
}


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _ns(t: float) -> int:
    return round(t * 1e9)


def _vec3(x: float, y: float, z: float = 0.0) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0, q: Any = None) -> dict[str, Any]:
    qx, qy, qz, qw = q if q is not None else (0.0, 0.0, 0.0, 1.0)
    return {"position": _vec3(x, y, z), "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}


def _color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    return {"r": r, "g": g, "b": b, "a": a}


def _line(points: FloatArray, color: dict[str, float], thickness: float = 0.02) -> dict[str, Any]:
    return {
        "type": 0,
        "pose": _pose(),
        "thickness": thickness,
        "scale_invariant": False,
        "points": [_vec3(p[0], p[1], 0.01) for p in np.asarray(points, dtype=float)],
        "color": color,
        "colors": [],
        "indices": [],
    }


def _entity(ns: int, frame: str, eid: str, **parts: Any) -> dict[str, Any]:
    out: dict[str, Any] = {
        "timestamp": _stamp(ns),
        "frame_id": frame,
        "id": eid,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": frame != "map",
        "metadata": [],
    }
    for key in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"):
        out[key] = parts.get(key, [])
    if "metadata" in parts:
        out["metadata"] = [{"key": k, "value": str(v)} for k, v in parts["metadata"].items()]
    return out


_BLUE = _color(0.12, 0.47, 0.71)
_ORANGE = _color(1.0, 0.5, 0.05)
_GREEN = _color(0.17, 0.63, 0.17)
_GREY = _color(0.2, 0.2, 0.2)
_RED = _color(0.84, 0.15, 0.16)


class McapRunLog:
    """An MCAP file of one or more runs, written as the runs go.

    Parameters
    ----------
    path : str or Path
        The file (suffix ``.mcap``); written to a temporary file beside it and renamed
        by :meth:`close`, so a failed run leaves no partial file.
    library : PolicyLibrary, optional
        Its policies' domains are drawn at every switch (:meth:`policy`).

    Raises
    ------
    OutputError
        The path does not end in ``.mcap``, or its folder cannot be written.
    """

    def __init__(self, path: str | Path, *, library: Any = None) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        if self.path.suffix.lower() != ".mcap":
            raise OutputError(f"--log {self.path}: a log file name ends in .mcap")
        if self.path.is_dir():
            raise OutputError(
                f"--log {self.path} is a directory; give a file name such as run.mcap"
            )
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(
                prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent
            )
        except OSError as exc:
            raise OutputError(f"--log {self.path}: cannot write there ({exc.strerror})") from None
        self._tmp = Path(tmp)
        umask = os.umask(0)  # mkstemp makes the file 0600: give it what open() would
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        self._fh: IO[bytes] | None = os.fdopen(fd, "wb")
        self._writer = Writer(self._fh, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="gracenav")
        schema_ids = {
            name: self._writer.register_schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode()
            )
            for name, schema in SCHEMAS.items()
        }
        self._channels = {
            topic: self._writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_ids[name]
            )
            for topic, name in LOG_CHANNELS.items()
        }
        self._seq = 0
        self._lock = threading.Lock()
        self.library = library
        self._policies: dict[int, Any] = {}
        self.counts: dict[str, int] = dict.fromkeys(LOG_CHANNELS, 0)

    # -- low level --------------------------------------------------------------------
    def _write(self, topic: str, ns: int, message: dict[str, Any]) -> None:
        data = json.dumps(message, allow_nan=False, separators=(",", ":")).encode()
        with self._lock:  # a node writes from its control callback and its worker threads
            if self._fh is None:
                return
            self._seq += 1
            self._writer.add_message(
                self._channels[topic], log_time=ns, data=data, publish_time=ns, sequence=self._seq
            )
            self.counts[topic] += 1

    # -- content ----------------------------------------------------------------------
    def world_map(self, t: float, world_map: Any) -> None:
        """The occupancy grid at log time ``t`` (s): 0 free, 100 obstacle, as ``uint8``."""
        ns = _ns(t)
        occ = np.asarray(world_map.occupied, dtype=bool)
        _ny, nx = occ.shape
        data = np.where(occ, 100, 0).astype(np.uint8)
        ox, oy = (float(v) for v in world_map.origin)
        self._write(
            "/map",
            ns,
            {
                "timestamp": _stamp(ns),
                "frame_id": "map",
                "pose": _pose(ox, oy),
                "column_count": int(nx),
                "cell_size": {"x": float(world_map.resolution), "y": float(world_map.resolution)},
                "row_stride": int(nx),
                "cell_stride": 1,
                "fields": [{"name": "occupied", "offset": 0, "type": 1}],
                "data": base64.b64encode(data.tobytes()).decode("ascii"),
            },
        )

    def robot(
        self, t: float, radius: float, footprint: float, goals: Sequence[ArrayLike] = ()
    ) -> None:
        """The robot in ``base_link`` (ball of ``radius``, body, footprint of radius
        ``footprint``, m) and the goals in ``map``."""
        ns = _ns(t)
        body = _entity(
            ns,
            "base_link",
            "robot",
            spheres=[
                {"pose": _pose(), "size": _vec3(2 * radius, 2 * radius, 2 * radius), "color": _BLUE}
            ],
            cylinders=[
                {
                    "pose": _pose(0.0, 0.0, radius + 0.5 * _BODY_HEIGHT),
                    "size": _vec3(_BODY_DIAMETER, _BODY_DIAMETER, _BODY_HEIGHT),
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": _color(0.6, 0.6, 0.6, 0.9),
                }
            ],
        )
        ang = np.linspace(0.0, 2 * np.pi, 49)
        ring = np.column_stack([footprint * np.cos(ang), footprint * np.sin(ang)])
        foot = _line(ring, _GREY, 0.01)
        for p in foot["points"]:
            p["z"] = -radius
        body["lines"] = [foot]
        entities = [body]
        for k, g in enumerate(goals):
            gx, gy = (float(v) for v in np.asarray(g, dtype=float)[:2])
            entities.append(
                _entity(
                    ns,
                    "map",
                    f"goal {k}",
                    spheres=[
                        {"pose": _pose(gx, gy, 0.05), "size": _vec3(0.1, 0.1, 0.1), "color": _GREEN}
                    ],
                    texts=[
                        {
                            "pose": _pose(gx, gy, 0.3),
                            "billboard": True,
                            "font_size": 14.0,
                            "scale_invariant": True,
                            "color": _GREEN,
                            "text": f"goal {k + 1}",
                        }
                    ],
                )
            )
        self._write("/gracenav/robot", ns, {"deletions": [], "entities": entities})

    def sample(
        self,
        t: float,
        *,
        run: int,
        run_time: float,
        position_state: ArrayLike,
        lean: ArrayLike,
        lean_rate: ArrayLike,
        torque: ArrayLike,
        reference: ArrayLike,
        policy: int,
        radius: float,
    ) -> None:
        """One sample at log time ``t`` (s): the ``map`` → ``base_link`` transform and a
        ``gracenav.State`` (``run_time``: time since the run started, s)."""
        ns = _ns(t)
        p = np.asarray(position_state, dtype=float)
        a = np.asarray(lean, dtype=float)
        da = np.asarray(lean_rate, dtype=float)
        u = np.asarray(torque, dtype=float)
        r = np.asarray(reference, dtype=float)
        q = lean_quaternion(a)
        self._write(
            "/tf",
            ns,
            {
                "timestamp": _stamp(ns),
                "parent_frame_id": "map",
                "child_frame_id": "base_link",
                "translation": _vec3(p[0], p[1], radius),
                "rotation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]},
            },
        )
        self._write(
            "/gracenav/state",
            ns,
            {
                "timestamp": _stamp(ns),
                "run": int(run),
                "t": float(run_time),
                "x": float(p[0]),
                "y": float(p[1]),
                "xdot": float(p[2]),
                "ydot": float(p[3]),
                "lean_x": float(a[0]),
                "lean_y": float(a[1]),
                "lean_rate_x": float(da[0]),
                "lean_rate_y": float(da[1]),
                "tau_x": float(u[0]),
                "tau_y": float(u[1]),
                "ref_x": float(r[0]),
                "ref_y": float(r[1]),
                "ref_xdot": float(r[2]),
                "ref_ydot": float(r[3]),
                "policy": int(policy),
            },
        )

    def policy(self, t: float, row: int, *, name: str | None = None, samples: int = 8) -> None:
        """The domains of the policy starting at log time ``t`` (s): S (blue), G (green),
        D'(t) at ``samples`` times (orange) and the reference (black), XY projections, on
        entity ``policy``. A ``row`` < 0 (balancing mode, a terminal regulator, a placed
        catch) or a log without a library clears it."""
        ns = _ns(t)
        if row < 0 or self.library is None:
            what = {-1: "balancing mode", -2: "terminal regulator", -4: "placed catch"}
            label = name or what.get(row, "no library policy")
            self._write(
                "/gracenav/domains",
                ns,
                {
                    "deletions": [{"timestamp": _stamp(ns), "type": 0, "id": "policy"}],
                    "entities": [
                        _entity(ns, "map", "policy label", metadata={"policy": label, "row": row})
                    ],
                },
            )
            return
        pol = self._policies.get(row)
        if pol is None:
            pol = self._policies.setdefault(row, self.library.policy(row))
        lines = []
        for tau in np.linspace(0.0, float(pol.duration), samples):
            d = pol.outer_domain(float(tau))
            lines.append(_line(ellipse_outline(d.xy_projection(), d.center), _ORANGE, 0.008))
        for dom, color in ((pol.start_domain, _BLUE), (pol.goal_domain, _GREEN)):
            lines.append(_line(ellipse_outline(dom.xy_projection(), dom.center), color, 0.02))
        ref = np.asarray(pol.reference_positions)[:, :2]
        lines.append(_line(ref[:: max(1, ref.shape[0] // 64)], _GREY, 0.015))
        self._write(
            "/gracenav/domains",
            ns,
            {
                "deletions": [],
                "entities": [
                    _entity(
                        ns,
                        "map",
                        "policy",
                        lines=lines,
                        metadata={"policy": pol.name, "row": row},
                    ),
                    _entity(ns, "map", "policy label", metadata={"policy": pol.name, "row": row}),
                ],
            },
        )

    def trail(self, t: float, run: int, xy: ArrayLike, reference_xy: ArrayLike) -> None:
        """The path travelled (blue) and the reference (black) of run ``run`` (m)."""
        ns = _ns(t)
        self._write(
            "/gracenav/path",
            ns,
            {
                "deletions": [],
                "entities": [
                    _entity(ns, "map", f"path {run}", lines=[_line(np.asarray(xy), _BLUE, 0.02)]),
                    _entity(
                        ns,
                        "map",
                        f"reference {run}",
                        lines=[_line(np.asarray(reference_xy), _GREY, 0.01)],
                    ),
                ],
            },
        )

    def event(self, t: float, message: str, *, level: int = INFO) -> None:
        """A line on the event log (switches, goals, run ends)."""
        ns = _ns(t)
        self._write(
            "/gracenav/events",
            ns,
            {
                "timestamp": _stamp(ns),
                "level": level,
                "message": message,
                "name": "gracenav",
                "file": "",
                "line": 0,
            },
        )

    def push(
        self, t: float, *, run: int, run_time: float, at: ArrayLike, impulse: ArrayLike
    ) -> None:
        """A push of ``impulse`` (N s) on the robot at ``at`` (m), with an arrow on the
        path scene and a line on the event log."""
        ns = _ns(t)
        a = np.asarray(at, dtype=float)
        j = np.asarray(impulse, dtype=float)
        self._write(
            "/gracenav/pushes",
            ns,
            {
                "timestamp": _stamp(ns),
                "run": int(run),
                "t": float(run_time),
                "position": {"x": float(a[0]), "y": float(a[1])},
                "impulse": {"x": float(j[0]), "y": float(j[1])},
            },
        )
        yaw = math.atan2(float(j[1]), float(j[0]))
        q = (0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw))
        length = 0.05 * float(np.hypot(*j))  # 20 N s drawn as 1 m
        self._write(
            "/gracenav/path",
            ns,
            {
                "deletions": [],
                "entities": [
                    _entity(
                        ns,
                        "map",
                        f"push {run} {run_time:.3f}",
                        arrows=[
                            {
                                "pose": _pose(
                                    a[0] - length * math.cos(yaw),
                                    a[1] - length * math.sin(yaw),
                                    0.5,
                                    q,
                                ),
                                "shaft_length": 0.8 * length,
                                "shaft_diameter": 0.03,
                                "head_length": 0.2 * length,
                                "head_diameter": 0.08,
                                "color": _RED,
                            }
                        ],
                    )
                ],
            },
        )
        self.event(
            t,
            f"run {run}: push of ({j[0]:.3g}, {j[1]:.3g}) N s at t = {run_time:.3f} s",
            level=WARNING,
        )

    # -- end --------------------------------------------------------------------------
    def close(self) -> Path:
        """Finish the file and move it into place; returns its path."""
        with self._lock:
            if self._fh is None:
                return self.path
            self._writer.finish()
            fh, self._fh = self._fh, None
        fh.flush()
        os.fsync(fh.fileno())
        fh.close()
        os.replace(self._tmp, self.path)
        return self.path

    def discard(self) -> None:
        """Drop the file being written (a failed or interrupted run)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None
        if self._tmp.exists():
            self._tmp.unlink()

    def __enter__(self) -> McapRunLog:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.discard()


def write_scenario_log(result: Any, path: str | Path, *, stride: int = 8) -> Path:
    """Write a scenario's runs (:func:`gracenav.scenarios.run_scenario`) to an MCAP file.

    Runs follow one another in log time, :data:`RUN_GAP` s apart; each starts with the
    map, the robot and the goals. Every ``stride``-th control tick is a sample (with the
    default, 128 Hz), and so is each run's last tick; each switch draws the starting
    policy's domains; pushes, switches and the run's end are on the event log.

    Parameters
    ----------
    result : ScenarioResult
    path : str or Path
        The ``.mcap`` file.
    stride : int
        Control ticks per sample (≥ 1).

    Returns
    -------
    Path
    """
    from gracenav.sim import Push

    if not (isinstance(stride, int) and stride >= 1):
        raise ConfigError(f"stride must be a positive integer, got {stride!r}")
    sc = result.scenario
    lib = result.library
    footprint = float(sc.footprint_radius)
    with McapRunLog(path, library=lib) as log:
        offset = 0.0
        for k, ep in enumerate(result.episodes):
            radius = float(ep.radius)
            log.world_map(offset, result.world_map)
            log.robot(offset, radius, footprint, sc.goals)
            p = ep.position_state
            log.event(offset, f"run {k}: start at ({p[0, 0]:.3g}, {p[0, 1]:.3g}) m")
            ticks = list(range(0, ep.time.size, stride))
            if ticks[-1] != ep.time.size - 1:
                ticks.append(ep.time.size - 1)
            events = sorted(ep.events, key=lambda e: e.time)
            pushes = sorted(
                (d for d in sc.disturbances if isinstance(d, Push)), key=lambda d: d.time
            )
            ei = pi = 0
            for i in ticks:
                ti = float(ep.time[i])
                while ei < len(events) and events[ei].time <= ti:
                    e = events[ei]
                    name = (
                        lib.policy(e.to_policy).name
                        if (lib is not None and e.to_policy >= 0)
                        else ""
                    )
                    log.policy(offset + e.time, e.to_policy, name=name or None)
                    log.event(
                        offset + e.time,
                        f"run {k}: {e.reason.value} switch {e.from_policy} → {e.to_policy}"
                        + (f" ({name})" if name else ""),
                        level=INFO if e.reason.graceful or e.reason.value == "start" else WARNING,
                    )
                    ei += 1
                while pi < len(pushes) and pushes[pi].time <= ti:
                    j = int(np.clip(np.searchsorted(ep.time, pushes[pi].time), 0, ep.time.size - 1))
                    log.push(
                        offset + pushes[pi].time,
                        run=k,
                        run_time=pushes[pi].time,
                        at=p[j, :2],
                        impulse=pushes[pi].impulse,
                    )
                    pi += 1
                log.sample(
                    offset + ti,
                    run=k,
                    run_time=ti,
                    position_state=p[i],
                    lean=ep.states[i, 2:4],
                    lean_rate=ep.states[i, 6:8],
                    torque=ep.inputs[i],
                    reference=ep.reference[i],
                    policy=int(ep.policy[i]),
                    radius=radius,
                )
            end = offset + float(ep.time[-1])
            log.trail(end, k, p[:, :2], ep.reference[:, :2])
            for when, goal in ep.goals_reached:
                log.event(offset + when, f"run {k}: goal {goal + 1} reached at t = {when:.3f} s")
            log.event(end, f"run {k}: ended ({ep.status.value}) at t = {ep.time[-1]:.3f} s")
            offset = end + RUN_GAP
    return Path(path)
