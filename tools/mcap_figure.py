"""Draw what a gracenav MCAP log holds, as Foxglove's 3D and Plot panels show it.

Reads only the MCAP file: the map (``/map``), the path and the push arrows
(``/gracenav/path``, ``/gracenav/pushes``), the robot's pose (``/tf``) and the running
policy's domains (``/gracenav/domains``) at one moment, and the lean and torque series
of ``/gracenav/state``. Without ``--log`` it first runs the paper's Fig. 5 task from
(0, 0) with a push of (0, 9) N s at 3 s into a temporary MCAP file.

    python tools/mcap_figure.py --out docs/figures/ros_mcap.png [--log run.mcap] [--at 4.0]
"""

from __future__ import annotations

import argparse
import base64
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np


def _scenario(tmp: Path) -> Path:
    import yaml

    spec = {
        "name": "Fig. 5 with a push",
        "map": {
            "bounds": [[-1.0, -1.0], [3.5, 3.0]],
            "resolution": 0.05,
            "obstacles": [
                {"rectangle": {"min": [0.75, 1.0], "max": [1.25, 1.5]}},
                {"rectangle": {"min": [1.75, 0.25], "max": [2.25, 0.75]}},
            ],
        },
        "robot": {"footprint_radius": 0.2},
        "planner": {"cost": "time", "max_halvings": 1},
        "task": {"kind": "point_to_point", "goal": [2.0, 2.0, 0.0, 0.0], "starts": [[0, 0, 0, 0]]},
        "disturbances": [{"kind": "push", "time": 3.0, "impulse": [0.0, 9.0]}],
        "simulation": {"plant": "model3d", "seed": 0, "max_time": 40},
    }
    path = tmp / "fig5_push.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def _read(log: Path) -> dict[str, list[tuple[float, dict[str, Any]]]]:
    from mcap.reader import make_reader

    out: dict[str, list[tuple[float, dict[str, Any]]]] = {}
    with log.open("rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(log_time_order=True):
            out.setdefault(channel.topic, []).append(
                (message.log_time * 1e-9, json.loads(message.data))
            )
    return out


def _xy(points: list[dict[str, float]]) -> np.ndarray:
    return np.array([[p["x"], p["y"]] for p in points])


def draw(log: Path, out: Path, at: float) -> Path:
    """Render ``log`` to ``out`` with the 3D view at log time ``at`` (s)."""
    from matplotlib.figure import Figure

    topics = _read(log)
    fig = Figure(figsize=(11, 5.2), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=[1.15, 1])
    ax = fig.add_subplot(grid[:, 0])
    ax.set_facecolor("#15171c")
    g = topics["/map"][0][1]
    nx = g["column_count"]
    data = np.frombuffer(base64.b64decode(g["data"]), dtype=np.uint8).reshape(-1, nx)
    ox, oy = g["pose"]["position"]["x"], g["pose"]["position"]["y"]
    res = g["cell_size"]["x"]
    extent = (ox, ox + nx * res, oy, oy + data.shape[0] * res)
    ax.imshow(data, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=130, alpha=0.9)
    for _, m in topics.get("/gracenav/path", []):
        for e in m["entities"]:
            for line in e["lines"]:
                c = line["color"]
                pts = _xy(line["points"])
                ax.plot(pts[:, 0], pts[:, 1], color=(c["r"], c["g"], c["b"]), lw=1.6)
            for a in e["arrows"]:
                p, q = a["pose"]["position"], a["pose"]["orientation"]
                yaw = 2 * np.arctan2(q["z"], q["w"])
                n = a["shaft_length"] + a["head_length"]
                ax.annotate(
                    "",
                    xy=(p["x"] + n * np.cos(yaw), p["y"] + n * np.sin(yaw)),
                    xytext=(p["x"], p["y"]),
                    arrowprops={"arrowstyle": "-|>", "color": "tab:red", "lw": 2},
                )
    domains = [m for t, m in topics["/gracenav/domains"] if t <= at]
    if domains:
        for e in domains[-1]["entities"]:
            for line in e["lines"]:
                c = line["color"]
                pts = _xy(line["points"])
                ax.plot(
                    pts[:, 0],
                    pts[:, 1],
                    color=(c["r"], c["g"], c["b"]),
                    lw=0.6 + 40 * line["thickness"],
                )
        label = next(e for e in domains[-1]["entities"] if e["id"] == "policy label")
        name = {d["key"]: d["value"] for d in label["metadata"]}["policy"]
    else:
        name = ""
    tf = [m for t, m in topics["/tf"] if t <= at][-1]
    x, y = tf["translation"]["x"], tf["translation"]["y"]
    q = tf["rotation"]
    tip = (2 * (q["x"] * q["z"] + q["w"] * q["y"]), 2 * (q["y"] * q["z"] - q["w"] * q["x"]))
    ax.plot([x, x + 8 * tip[0]], [y, y + 8 * tip[1]], color="#bbbbbb", lw=5, solid_capstyle="round")
    ax.plot(x, y, "o", color="tab:blue", ms=9, mec="white")
    for _, m in topics["/gracenav/robot"][:1]:
        for e in m["entities"]:
            if e["id"].startswith("goal"):
                p = e["spheres"][0]["pose"]["position"]
                ax.plot(p["x"], p["y"], "*", color="tab:green", ms=14, mec="white")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_title(f"3D panel (top view), t = {at:.2f} s: {name}", fontsize=9)
    ax.set_xlabel("map x (m)")
    ax.set_ylabel("map y (m)")
    states = [m for _, m in topics["/gracenav/state"]]
    t = np.array([m["t"] for m in states])
    for row, (keys, unit, title) in enumerate(
        (
            (("lean_x", "lean_y"), "deg", "/gracenav/state.lean_x, .lean_y"),
            (("tau_x", "tau_y"), "N m", "/gracenav/state.tau_x, .tau_y"),
        )
    ):
        a = fig.add_subplot(grid[row, 1])
        for k in keys:
            v = np.array([m[k] for m in states])
            a.plot(t, np.degrees(v) if unit == "deg" else v, lw=1, label=k)
        for _, p in topics.get("/gracenav/pushes", []):
            a.axvline(p["t"], color="tab:red", lw=0.8, ls="--")
        a.axvline(at, color="k", lw=0.6)
        a.set_ylabel(unit)
        a.set_title(f"Plot panel: {title}", fontsize=9)
        a.legend(fontsize=8, loc="upper right")
        a.grid(True, alpha=0.3)
    a.set_xlabel("t (s)")
    fig.suptitle(f"{log.name}: what Foxglove shows of a gracenav run", fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--log", type=Path, default=None)
    parser.add_argument("--at", type=float, default=10.8, help="log time of the 3D view (s)")
    args = parser.parse_args()
    if args.log is not None:
        print(f"wrote {draw(args.log, args.out, args.at)}")
        return
    from gracenav.cli import main as gracenav

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "fig5_push.mcap"
        status = gracenav(
            [
                "run",
                str(_scenario(Path(tmp))),
                "--out",
                f"{tmp}/out",
                "--log",
                str(log),
                "--no-animation",
            ]
        )
        if status != 0:
            raise SystemExit(status)
        print(f"wrote {draw(log, args.out, args.at)}")


if __name__ == "__main__":
    main()
