"""Disturbance recovery (paper Fig. 7): the path of one run, the push or drag as an
arrow where it acted, the start domains of the policies executed around it, and the
hybrid controller's switches.

:func:`recovery_data` computes what is drawn (positions in m, times in s);
:func:`plot_recovery` draws it and returns the same data, so that what a figure shows
can be checked without reading pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from gracenav.plotting._figure import agg_figure
from gracenav.plotting.navigation import draw_map
from gracenav.policies.domains import EllipsoidalDomain
from gracenav.sim import Drag, Push

__all__ = [
    "DisturbanceArrow",
    "ExitDomain",
    "RecoveryData",
    "SwitchMarker",
    "plot_recovery",
    "recovery_data",
]

FloatArray = NDArray[np.float64]

_NOT_GRACEFUL_EXITS = ("domain_exit", "not_in_goal", "balancing", "capture")
#: D'(t) of a catch or shift is drawn every this many seconds (and at its end).
CATCH_OUTER_EVERY = 0.25


@dataclass(frozen=True)
class DisturbanceArrow:
    """A push or drag as drawn.

    Attributes
    ----------
    kind : {"push", "drag"}
    time : float
        Time of the push, or start of the drag (s).
    tail : ndarray, shape (2,)
        Where the arrow starts: the robot's (ball's) position at ``time`` (m).
    vector : ndarray, shape (2,)
        The arrow (m): a push's impulse times :attr:`RecoveryData.impulse_scale`, a
        drag's velocity times the time it held the robot (the hand's displacement).
    magnitude : float
        |impulse| (N s) of a push, |velocity| (m/s) of a drag.
    label : str
        The text beside the arrow ("push 8 N s", "drag 0.35 m/s, 2 s").
    """

    kind: Literal["push", "drag"]
    time: float
    tail: FloatArray
    vector: FloatArray
    magnitude: float
    label: str


@dataclass(frozen=True)
class SwitchMarker:
    """A switch of the hybrid controller, drawn where the robot was.

    Attributes
    ----------
    time : float
        (s)
    xy : ndarray, shape (2,)
        The robot's position at the switch (m).
    reason : str
        :class:`~gracenav.execution.EventReason` value.
    graceful : bool
    to_policy : int
        Library row started (−1: balancing mode).
    """

    time: float
    xy: FloatArray
    reason: str
    graceful: bool
    to_policy: int


@dataclass(frozen=True)
class ExitDomain:
    """The outer domain D'(t) of a policy at the tick its state left it.

    Attributes
    ----------
    policy : int
        Library row.
    time : float
        Time of the exit (s).
    outline : ndarray, shape (n, 2)
        XY outline of D'(t) (m).
    """

    policy: int
    time: float
    outline: FloatArray


@dataclass(frozen=True)
class RecoveryData:
    """What :func:`plot_recovery` draws for one run.

    Attributes
    ----------
    run : int
        Index of the episode in the scenario result.
    window : tuple of float
        (t0, t1) (s): from the first disturbance to the first graceful switch after the
        last disturbance and the last non-graceful switch (or the end of the run).
    policies : tuple of int
        Library rows executed in ``window`` (the one running at t0 first); their start
        domains are drawn.
    start_domains : tuple of ndarray, shape (n, 2)
        XY outlines of their start domains S (m), in the order of ``policies``.
    exits : tuple of ExitDomain
        D'(t) at every domain exit in ``window``.
    arrows : tuple of DisturbanceArrow
        Every disturbance that acted during the run.
    switches : tuple of SwitchMarker
        Every switch of the run (the first start excluded).
    impulse_scale : float
        Length of a push arrow per unit impulse (m / (N s)).
    path : ndarray, shape (N, 2)
        The ball's XY path (m), where the plant truly is.
    catch_start_domains : tuple of ndarray, shape (n, 2)
        XY outlines of the start domains S of the catches and shifts placed at the
        robot's state (:mod:`gracenav.execution.capture`) and started in ``window`` (m).
    catch_outer_domains : tuple of ndarray, shape (n, 2)
        XY outlines of their outer domains D'(t) every :data:`CATCH_OUTER_EVERY` s and
        at their last tick (m): together they draw the swept D' that was checked
        against the map.
    """

    run: int
    window: tuple[float, float]
    policies: tuple[int, ...]
    start_domains: tuple[FloatArray, ...]
    exits: tuple[ExitDomain, ...]
    arrows: tuple[DisturbanceArrow, ...]
    switches: tuple[SwitchMarker, ...]
    impulse_scale: float
    path: FloatArray
    catch_start_domains: tuple[FloatArray, ...] = ()
    catch_outer_domains: tuple[FloatArray, ...] = ()


def _catch_outlines(ep: Any, t0: float, t1: float) -> tuple[list[FloatArray], list[FloatArray]]:
    """Outlines of S and of D'(t) (every CATCH_OUTER_EVERY s) of the placed catches and
    shifts of the captures started in [t0, t1]."""
    starts: list[FloatArray] = []
    outers: list[FloatArray] = []
    for when, plan in ep.captures:
        if not t0 - 1e-9 <= when <= t1 + 1e-9:
            continue
        for placed in plan.policies:
            s = placed.start_domain
            starts.append(_ellipse_xy(s.xy_projection(), np.asarray(s.center, dtype=float)))
            centres, shapes = placed.outer_monitor()
            step = max(1, round(CATCH_OUTER_EVERY / placed.primitive.dt))
            ticks = sorted({*range(0, centres.shape[0], step), centres.shape[0] - 1})
            for k in ticks:
                d = EllipsoidalDomain(centres[k], 0.5 * (shapes[k] + shapes[k].T))
                outers.append(_ellipse_xy(d.xy_projection(), centres[k], n=61))
    return starts, outers


def _ellipse_xy(shape_xy: FloatArray, center: FloatArray, n: int = 121) -> FloatArray:
    """Points (n, 2) of {u : (u − c)ᵀ Q (u − c) = 1}."""
    ang = np.linspace(0.0, 2.0 * np.pi, n)
    ell = np.linalg.cholesky(np.linalg.inv(shape_xy))
    return np.asarray(center[:2] + (ell @ np.vstack([np.cos(ang), np.sin(ang)])).T)


def _at(ep: Any, t: float) -> FloatArray:
    """The ball's XY position at time ``t`` (s), interpolated between ticks."""
    p = ep.position_state
    return np.array([np.interp(t, ep.time, p[:, 0]), np.interp(t, ep.time, p[:, 1])])


def _window(ep: Any, disturbances: list[Any]) -> tuple[float, float]:
    t0 = min(d.time if isinstance(d, Push) else d.start_time for d in disturbances)
    released = max(d.time if isinstance(d, Push) else d.end_time for d in disturbances)
    last_forced = max(
        (e.time for e in ep.events if e.time >= t0 and not e.reason.graceful), default=t0
    )
    after = max(released, last_forced)
    t1 = next(
        (e.time for e in ep.events if e.time > after and e.reason.graceful),
        float(ep.time[-1]),
    )
    return float(t0), float(t1)


def recovery_data(result: Any, run: int = 0, *, arrow_length: float | None = None) -> RecoveryData:
    """The data of the recovery figure of run ``run`` of a scenario result.

    Parameters
    ----------
    result : ScenarioResult
        As returned by :func:`gracenav.scenarios.run_scenario`; its scenario must have a
        push or drag that acted during the run.
    run : int
        Index of the episode in ``result.episodes``.
    arrow_length : float, optional
        Length (m) of the arrow of the largest push; default 15 % of the map's smaller
        side.

    Raises
    ------
    ValueError
        If ``run`` is out of range or no push or drag acted during the run.
    """
    if not 0 <= run < len(result.episodes):
        raise ValueError(f"run {run} is out of range: {len(result.episodes)} run(s)")
    ep = result.episodes[run]
    lib = result.library
    t_end = float(ep.time[-1])
    acted = [
        d
        for d in result.scenario.disturbances
        if (isinstance(d, Push) and d.time <= t_end)
        or (isinstance(d, Drag) and d.start_time <= t_end)
    ]
    if not acted:
        raise ValueError(f"no push or drag acted during run {run} (it ended at {t_end:g} s)")
    (x0, y0), (x1, y1) = result.world_map.bounds
    length = arrow_length if arrow_length is not None else 0.15 * min(x1 - x0, y1 - y0)
    largest = max((float(np.hypot(*d.impulse)) for d in acted if isinstance(d, Push)), default=0)
    scale = length / largest if largest > 0 else 0.0
    arrows = []
    for d in acted:
        if isinstance(d, Push):
            imp = np.asarray(d.impulse, dtype=float)
            mag = float(np.hypot(*imp))
            arrows.append(
                DisturbanceArrow(
                    "push", d.time, _at(ep, d.time), scale * imp, mag, f"push {mag:.3g} N s"
                )
            )
        else:
            held = min(d.end_time, t_end) - d.start_time
            vel = np.asarray(d.velocity, dtype=float)
            mag = float(np.hypot(*vel))
            label = f"drag {mag:.3g} m/s, {held:.3g} s"
            arrows.append(
                DisturbanceArrow(
                    "drag", d.start_time, _at(ep, d.start_time), held * vel, mag, label
                )
            )
    t0, t1 = _window(ep, acted)
    p = ep.position_state
    i0 = int(np.searchsorted(ep.time, t0 - 1e-9))
    i1 = int(np.searchsorted(ep.time, t1 + 1e-9))
    rows = [int(i) for i in ep.policy[min(i0, ep.time.size - 1) : max(i1, i0 + 1)] if i >= 0]
    policies = tuple(dict.fromkeys(rows))
    domains = []
    for pid in policies:
        s = lib.policy(pid).start_domain
        domains.append(_ellipse_xy(s.xy_projection(), np.asarray(s.center, dtype=float)))
    exits = []
    for e in ep.events:
        if (
            t0 <= e.time <= t1
            and e.reason.value in _NOT_GRACEFUL_EXITS
            and e.from_policy >= 0
            and e.tick > 0
        ):
            pol = lib.policy(e.from_policy)
            started = next(
                (
                    s.time
                    for s in reversed(ep.events)
                    if s.to_policy == e.from_policy and s.time < e.time
                ),
                0.0,
            )
            d = pol.outer_domain(float(e.time - started))
            exits.append(
                ExitDomain(
                    e.from_policy,
                    float(e.time),
                    _ellipse_xy(d.xy_projection(), np.asarray(d.center, dtype=float)),
                )
            )
    switches = tuple(
        SwitchMarker(
            float(e.time), p[e.tick, :2].copy(), e.reason.value, e.reason.graceful, e.to_policy
        )
        for e in ep.events
        if e.reason.value != "start"
    )
    catch_starts, catch_outers = _catch_outlines(ep, t0, t1)
    return RecoveryData(
        run=run,
        window=(t0, t1),
        policies=policies,
        start_domains=tuple(domains),
        exits=tuple(exits),
        arrows=tuple(arrows),
        switches=switches,
        impulse_scale=scale,
        path=p[:, :2].copy(),
        catch_start_domains=tuple(catch_starts),
        catch_outer_domains=tuple(catch_outers),
    )


def plot_recovery(
    result: Any,
    path: str | Path,
    *,
    run: int = 0,
    arrow_length: float | None = None,
    size: tuple[float, float] = (6.5, 6.5),
    dpi: int = 120,
) -> RecoveryData:
    """Save the recovery figure of run ``run`` (paper Fig. 7 style) and return its data.

    Draws the map, the reference (dashed) and simulated paths, the stretch where the
    robot was held (red), each push as an arrow from where it acted (length
    proportional to the impulse, labelled in N s) and each drag as the hand's
    displacement, the start domains S of the policies executed from the disturbance
    until the motion is graceful again, D'(t) where the state left it (dotted), and the
    switches: graceful (dots) and forced (red crosses). A catch or shift placed at the
    robot's state is drawn with its S (green) and its D'(t) every 0.25 s (light
    green). Paths and markers are where the plant truly is; domains are in the
    controller's coordinates (the two differ by the ratio of the ball radii when the
    plant's is not the palette's).

    Parameters
    ----------
    result : ScenarioResult
    path : str or Path
        Output file; the format follows its suffix.
    run : int
        Index of the episode in ``result.episodes``.
    arrow_length : float, optional
        See :func:`recovery_data`.
    size : tuple of float
        Figure size (inches); the image is ``size × dpi`` pixels.
    dpi : int

    Returns
    -------
    RecoveryData
    """
    data = recovery_data(result, run, arrow_length=arrow_length)
    ep = result.episodes[run]
    fig = agg_figure(figsize=size, constrained_layout=True)
    ax = fig.subplots()
    draw_map(ax, result.world_map)
    # Outlines: label, colour, line style, width, opacity, fill opacity, z-order.
    for outlines, label, color, ls, lw, alpha, fill, z in (
        (data.start_domains, "start domains S", "tab:blue", "-", 0.9, 0.6, 0.08, 2),
        (data.catch_outer_domains, "D'(t) of a catch or shift", "tab:green", "-", 0.6, 0.35, 0, 2),
        (data.catch_start_domains, "S of a catch or shift", "tab:green", "-", 1.2, 1.0, 0.25, 3),
        (
            [ex.outline for ex in data.exits],
            "D'(t) at a domain exit",
            "tab:orange",
            ":",
            1.2,
            1.0,
            0,
            3,
        ),
    ):
        for k, outline in enumerate(outlines):
            if fill:
                ax.fill(outline[:, 0], outline[:, 1], color=color, alpha=fill, lw=0, zorder=z)
            ax.plot(
                outline[:, 0],
                outline[:, 1],
                ls,
                color=color,
                lw=lw,
                alpha=alpha,
                zorder=z,
                label=label if k == 0 else None,
            )
    ref = ep.reference
    ax.plot(ref[:, 0], ref[:, 1], "--", color="0.35", lw=1, zorder=3, label="reference")
    ax.plot(data.path[:, 0], data.path[:, 1], "-", color="tab:blue", lw=2, zorder=4, label="path")
    ax.plot(data.path[0, 0], data.path[0, 1], "o", color="tab:blue", zorder=5)
    for d in result.scenario.disturbances:
        if isinstance(d, Drag):
            sel = (ep.time >= d.start_time) & (ep.time <= d.end_time)
            ax.plot(
                data.path[sel, 0], data.path[sel, 1], "-", color="red", lw=3.5, alpha=0.5, zorder=4
            )
    for a in data.arrows:
        ax.annotate(
            "",
            xy=(a.tail[0] + a.vector[0], a.tail[1] + a.vector[1]),
            xytext=(a.tail[0], a.tail[1]),
            arrowprops={"arrowstyle": "-|>", "color": "red", "lw": 2, "shrinkA": 0, "shrinkB": 0},
            zorder=6,
        )
        tip = a.tail + a.vector
        unit = a.vector / max(float(np.hypot(*a.vector)), 1e-12)
        ax.annotate(
            a.label,
            xy=(tip[0], tip[1]),
            xytext=(8.0 * unit[0], 8.0 * unit[1]),
            textcoords="offset points",
            ha="left" if unit[0] >= -0.3 else "right",
            va="bottom" if unit[1] >= -0.3 else "top",
            color="red",
            fontsize=9,
            zorder=7,
        )
    graceful = np.array([s.xy for s in data.switches if s.graceful]).reshape(-1, 2)
    forced = np.array([s.xy for s in data.switches if not s.graceful]).reshape(-1, 2)
    if graceful.size:
        ax.plot(
            graceful[:, 0],
            graceful[:, 1],
            "o",
            color="k",
            ms=3.5,
            zorder=6,
            label="graceful switch",
        )
    if forced.size:
        ax.plot(
            forced[:, 0],
            forced[:, 1],
            "x",
            color="red",
            ms=8,
            mew=2,
            zorder=6,
            label="forced switch",
        )
    for g in result.scenario.goals:
        ax.plot(g[0], g[1], "*", color="green", ms=16, mec="k", zorder=7)
    ax.legend(loc="lower right", fontsize=8)
    t0, t1 = data.window
    ax.set_title(
        f"{result.scenario.name}: run {run + 1}, recovery {t0:.1f}–{t1:.1f} s", fontsize=10
    )
    out = Path(path)
    fig.savefig(out, dpi=dpi)
    return data
