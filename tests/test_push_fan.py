"""Design push: the library keeps room, where it moves fast, for the catches of every
state a push of the design impulse leaves (gracenav.library.push_fans.PushFan)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gracenav import BallbotParams, ConfigError
from gracenav.execution.capture import capture_for
from gracenav.library import DEFAULT_DESIGN_PUSH, build_library, push_fan
from gracenav.library import push_fans as push_fans_module
from gracenav.library.push_fans import (
    FAN_DIRECTIONS,
    FAN_FLOOR,
    fastest_flat_speed,
    flat_speed_change,
)
from gracenav.policies import flat_position_state
from gracenav.primitives.references import flat_output_lengths
from gracenav.scenarios import parse_scenario
from gracenav.scenarios.run import library_key
from gracenav.sim import Model3DPlant, position_state, state_from_position
from gracenav.world import load_map

ROOT = Path(__file__).resolve().parent.parent
BOX = ROOT / "examples" / "maps" / "room_5m_box.yaml"
PARAMS = BallbotParams()


def _kick(x0: np.ndarray, impulse: float) -> float:
    """The flat output's velocity change along x of the 3D model pushed at ``x0``."""
    plant = Model3DPlant(PARAMS)
    plant.reset(x0)
    r = PARAMS.ball_radius

    def flat(x: np.ndarray) -> np.ndarray:
        return flat_position_state(position_state(x, r), x[2:4], x[6:8], PARAMS)

    before = flat(plant.state())
    plant.push(np.array([impulse, 0.0]))
    return float(flat(plant.state())[2] - before[2])


def test_flat_speed_change_is_the_models_kick() -> None:
    """Momentum gives the centre of mass J / M; the flat output gains a few % more (its
    L weighs the lean rate the push starts). Linear in J, the same at speed and at a
    maneuver's lean (within 1 %), so the fan's one figure holds along a reference."""
    mass = PARAMS.body_mass + PARAMS.ball_mass
    dv16 = flat_speed_change(PARAMS, 16.0)
    assert 1.0 < dv16 / (16.0 / mass) < 1.06
    assert flat_speed_change(PARAMS, 4.0) == pytest.approx(dv16 / 4.0, rel=1e-9)
    moving = state_from_position(np.array([0.0, 0.0, 1.0, 0.3]), PARAMS.ball_radius)
    assert _kick(moving, 16.0) == pytest.approx(dv16, rel=1e-9)
    leaning = moving.copy()
    leaning[2] = np.radians(5.0)
    leaning[6] = 0.1
    assert _kick(leaning, 16.0) == pytest.approx(dv16, rel=0.01)


def _flat(prim, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flat output's reference positions (from the start) and velocities."""
    pos = prim.position[:, :2] - prim.position[0, :2] + length * prim.states[:, 2:4]
    return pos, prim.position[:, 2:4] + length * prim.states[:, 6:8]


def test_no_design_push_and_the_shipped_palette_change_nothing(palette) -> None:
    """Without a design push there is no fan; the shipped palette's references (their
    flat output) stay at or below FAN_FLOOR, so even a design push (the default one
    too) checks no fan and leaves its libraries as they are."""
    assert push_fan(palette, 0.0, 0.05) is None
    length = flat_output_lengths(palette.params)
    top = max(float(np.max(np.hypot(*_flat(p.primitive, length)[1].T))) for p in palette.policies)
    assert top <= FAN_FLOOR
    assert fastest_flat_speed(palette) == pytest.approx(top, abs=1e-12)
    assert push_fan(palette, 16.0, 0.05) is None
    room = load_map(BOX)
    plain = build_library(palette, room, max_halvings=0, design_push=0.0)
    default = build_library(palette, room, max_halvings=0)
    pushed = build_library(palette, room, max_halvings=0, design_push=16.0)
    assert pushed.design_push == 16.0 and plain.design_push == 0.0
    assert default.design_push == DEFAULT_DESIGN_PUSH == 8.0
    for lib in (default, pushed):
        np.testing.assert_array_equal(plain.palette_index, lib.palette_index)
        np.testing.assert_array_equal(plain.start_xy, lib.start_xy)
        np.testing.assert_array_equal(plain.orientation, lib.orientation)


def _rows(lib) -> set[tuple[int, int, float, float]]:
    return {
        (int(p), int(o), round(float(x), 6), round(float(y), 6))
        for p, o, (x, y) in zip(lib.palette_index, lib.orientation, lib.start_xy, strict=True)
    }


def _without_catch(lib, fan, capture, rows) -> tuple[int, int]:
    """(pushed states without a clear catch, pushed states) at the flat output every
    1/16 s of the fast part of library ``rows`` (states the fan did not check itself
    as well), in each of the fan's directions, by the capture planner's own placement
    and clearance test."""
    missing = checked = 0
    for i in rows:
        inst = lib.policy(int(i))
        rot = inst.rotation
        fpos, fvel = _flat(inst.policy.primitive, fan.flat_length)
        for k in np.flatnonzero(np.hypot(*fvel.T) > fan.above)[::64]:
            p = inst.start_xy + rot @ fpos[k]
            v = rot @ fvel[k]
            for j in range(FAN_DIRECTIONS):
                a = 2.0 * np.pi * j / FAN_DIRECTIONS
                state = np.concatenate([p, v + fan.speed_change * np.array([np.cos(a), np.sin(a)])])
                clear = False
                for _, _, m, heading, start, _ in capture._candidates(state, ("pushed",), state):
                    c, s = np.cos(heading), np.sin(heading)
                    path = start + m.path @ np.array([[c, -s], [s, c]]).T
                    if np.all(capture.clear(path, m.reach)):
                        clear = True
                        break
                missing += not clear
                checked += 1
    return missing, checked


def test_fan_keeps_policies_where_the_catches_of_pushed_states_fit(palette, monkeypatch) -> None:
    """With the fan from 0.3 m/s (the shipped palette's cruise is 0.5 m/s) and a 7.5 N s
    design push, the library drops policies near the walls; along the policies it keeps,
    the capture planner (its own catch placement and clearance test, not the fan's
    discs) finds a clear pushed catch for every pushed flat-output state checked, where
    without the fan more than 5 % have none.

    All moving policies of this room: with the fan 0 of 149,088 states lack one,
    without it 108,812 of 1,556,480 (7.0 %).
    """
    monkeypatch.setattr(push_fans_module, "FAN_FLOOR", 0.3)
    room = load_map(BOX)
    plain = build_library(palette, room, max_halvings=0, design_push=0.0)
    lib = build_library(palette, room, max_halvings=0, design_push=7.5)
    kept, before = _rows(lib), _rows(plain)
    assert kept < before  # a strict subset: the fan removed policies
    fan = push_fan(palette, 7.5, float(room.resolution))
    assert fan is not None and fan.above == 0.3
    rng = np.random.default_rng(3)

    def moving(library) -> list[int]:
        return [
            i
            for i in range(len(library))
            if np.max(np.hypot(*_flat(library.policy(i).policy.primitive, fan.flat_length)[1].T))
            > 0.3
        ]

    rows = rng.choice(moving(lib), 40, replace=False)
    missing, checked = _without_catch(lib, fan, capture_for(lib), rows)
    assert checked > 200 and missing == 0
    rows = rng.choice(moving(plain), 40, replace=False)
    missing, checked = _without_catch(plain, fan, capture_for(plain), rows)
    assert checked > 200 and missing > 0.05 * checked


def test_pushed_speeds_beyond_every_catch_place_nothing(palette, monkeypatch) -> None:
    """A design push that takes the fan's states beyond the fastest pushed catch leaves
    out every policy with a fan tick: none whose flat output is faster than the floor
    remains."""
    monkeypatch.setattr(push_fans_module, "FAN_FLOOR", 0.3)
    fan = push_fan(palette, 60.0, 0.05)
    assert fan is not None and 0.3 + fan.speed_change > fan.speeds[-1] + fan.tolerance[-1]
    lib = build_library(palette, load_map(BOX), max_halvings=0, design_push=60.0)
    assert len(lib) > 0  # the rest trims and slow maneuvers stay
    for i in range(len(lib)):
        vel = _flat(lib.policy(i).policy.primitive, fan.flat_length)[1]
        assert np.max(np.hypot(*vel.T)) <= 0.3 + 1e-9


def test_design_push_scenario_key(palette) -> None:
    """``planner.design_push`` (N s) is read, checked, and keys the library."""
    doc = {
        "name": "design push",
        "map": {"bounds": [[0.0, 0.0], [5.0, 5.0]], "resolution": 0.05},
        "task": {"kind": "point_to_point", "goal": [4.0, 4.0, 0.0, 0.0], "starts": [[1, 1, 0, 0]]},
    }
    default = parse_scenario(doc, source="t")
    assert default.design_push == DEFAULT_DESIGN_PUSH
    plain = parse_scenario({**doc, "planner": {"design_push": 0}}, source="t")
    assert plain.design_push == 0.0
    pushed = parse_scenario({**doc, "planner": {"design_push": 16}}, source="t")
    assert pushed.design_push == 16.0
    assert library_key(plain, palette) != library_key(pushed, palette)
    with pytest.raises(ConfigError, match=r"'planner\.design_push' must be a number in"):
        parse_scenario({**doc, "planner": {"design_push": -1}}, source="t")
    with pytest.raises(ConfigError, match="design_push must be an impulse"):
        build_library(palette, load_map(BOX), design_push=-1.0)


def test_memory_estimate_counts_the_design_push(palette, monkeypatch) -> None:
    """The run's memory estimate sees the library the design push builds: fewer
    policies than without it, and the library built stays within the estimate."""
    from gracenav.scenarios import estimate_run_memory

    monkeypatch.setattr(push_fans_module, "FAN_FLOOR", 0.3)
    room = load_map(BOX)
    plain = estimate_run_memory(room, palette, 0, design_push=0.0)
    pushed = estimate_run_memory(room, palette, 0, design_push=7.5)
    assert pushed.policies is not None and plain.policies is not None
    assert pushed.policies < plain.policies
    assert len(build_library(palette, room, max_halvings=0, design_push=7.5)) <= pushed.policies


def _discs_of_one_state(fan, position: np.ndarray, velocity: np.ndarray):
    """The fan's discs at one state, written direction by direction (the reference
    :meth:`PushFan.samples_along` is checked against); None when a pushed state lies
    outside every pushed catch's S."""
    centres, radii = [], []
    for k in range(FAN_DIRECTIONS):
        a = 2.0 * math.pi * k / FAN_DIRECTIONS
        w = velocity + fan.speed_change * np.array([math.cos(a), math.sin(a)])
        speed = float(np.hypot(*w))
        j = int(np.argmin(np.abs(fan.speeds - speed)))
        if abs(float(fan.speeds[j]) - speed) > float(fan.tolerance[j]):
            return None
        h = math.atan2(w[1], w[0]) if speed > 1e-9 else 0.0
        c, s = math.cos(h), math.sin(h)
        centres.append(position + fan.paths[j] @ np.array([[c, s], [-s, c]]))
        radii.append(fan.reaches[j])
    return np.concatenate(centres), np.concatenate(radii)


def test_the_fans_walk_and_its_discs_match_a_state_by_state_reference() -> None:
    """The compiled walk (which states of a fast reference get their catches' discs)
    and the discs of all of them at once equal the walk written state by state with
    :meth:`PushFan.turn` and the discs formed state by state, on the shipped speed
    palette."""
    from gracenav.palette import load_palette

    pal = load_palette("speed")
    fan = push_fan(pal, DEFAULT_DESIGN_PUSH, 0.05)
    assert fan is not None
    checked = 0
    for name in ("rest_to_cruise2_x_3_0", "cruise3_xy", "cruise2_x_to_cruise2_y_3_3"):
        prim = pal[name].primitive
        ref = prim.position[:, :2] + fan.flat_length * prim.states[:, 2:4]
        vel = push_fans_module._flat_velocity(prim, fan.flat_length)
        fast = np.flatnonzero(np.hypot(vel[:, 0], vel[:, 1]) > fan.above + 1e-9)
        ticks = fast[:: push_fans_module._FAN_STRIDE]
        members = fan.members(vel[ticks])
        assert members is not None and ticks.size > 10
        expect = [0]
        for i in range(1, ticks.size):
            p = expect[-1]
            moved = float(np.hypot(*(ref[ticks[i]] - ref[ticks[p]])))
            dv = float(np.hypot(*(vel[ticks[i]] - vel[ticks[p]])))
            gap = moved + fan.turn(members[p], dv)
            if np.any(members[i] != members[p]) or gap > push_fans_module.FAN_GAP:
                expect.append(i)
        picked = push_fans_module._pick_fan_states(
            ref[ticks],
            vel[ticks],
            members.astype(np.int64),
            fan.radius,
            np.maximum(fan.speeds - fan.tolerance, 1e-9),
            push_fans_module.FAN_GAP,
        )
        np.testing.assert_array_equal(picked, expect)
        centres, radii = fan.samples_along(ref[ticks[picked]], vel[ticks[picked]], members[picked])
        one = [_discs_of_one_state(fan, ref[ticks[i]], vel[ticks[i]]) for i in picked]
        assert all(o is not None for o in one)
        np.testing.assert_allclose(centres, np.concatenate([o[0] for o in one]), atol=1e-12)
        np.testing.assert_array_equal(radii, np.concatenate([o[1] for o in one]))
        checked += len(picked)
    assert checked > 30
