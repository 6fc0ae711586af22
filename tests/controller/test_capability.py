"""controller.capability's views against the scene file's own numbers: the device's setpoint
bounds (inset by the servo's overshoot room, its headroom over the drives) and the live
envelope's (less its Margins), computed here from the micro-manipulator's [geometry], [drive]
and [controller.motor] tables, not from controller.drive."""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controller.capability import (DEVICE_FORCE, DEVICE_FORCE_RATE, DEVICE_RATE, Margins,
                                   capability, overshoot_room)
from stewart_fmu.reach import LIMITS
from stewart_fmu.reach_params import COND_LIMIT
from stewart_fmu.scene import load_scene
from stewart_sim.scene.load import scene_of

MICRO = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"


@pytest.fixture(scope="module")
def scene():
    model = load_scene(MICRO)
    return model, scene_of(model).controller, tomllib.loads(MICRO.read_text())


def _drive(table: dict) -> tuple[float, float, float]:
    """(no-load speed m/s, peak force N, Kf V_max / L N/s) from the scene file."""
    d, m = table["drive"], table["controller"]["motor"]
    zeta_r = d["gear_ratio"] / d["pinion_radius"]
    kf, ke = m["torque_constant"] * zeta_r, m["back_emf"] * zeta_r
    return (m["voltage_limit"] / ke, kf * m["current_limit"],
            kf * m["voltage_limit"] / m["inductance"])


def test_the_device_view_is_the_stroke_inset_and_the_drives_times_their_headroom(scene):
    model, controller, table = scene
    speed, force, force_rate = _drive(table)
    g = table["geometry"]
    room = 0.0047
    cap = capability(model, controller).inset(room)
    assert cap.stroke == (g["leg_min"] + room, g["leg_max"] - room)
    assert (cap.leg_min, cap.leg_max) == cap.stroke
    assert cap.speed == pytest.approx(speed, rel=1e-15)
    assert cap.force == pytest.approx(force, rel=1e-15)
    assert cap.setpoint_rate == pytest.approx(DEVICE_RATE * speed, rel=1e-15)
    assert cap.setpoint_force == pytest.approx(DEVICE_FORCE * force, rel=1e-15)
    assert cap.setpoint_force_rate == pytest.approx(DEVICE_FORCE_RATE * force_rate, rel=1e-15)
    # the figures of hil.input_bounds' table: 3 m/s, 8 kN, 3.84e7 N/s
    assert (cap.setpoint_rate, cap.setpoint_force) == pytest.approx((3.0, 8000.0), rel=1e-15)
    assert cap.setpoint_force_rate == pytest.approx(3.84e7, rel=1e-15)


def test_the_envelope_view_takes_each_margin_off(scene):
    model, controller, table = scene
    speed, force, _ = _drive(table)
    g = table["geometry"]
    room, m = 0.0047, Margins(stroke=0.1, speed=0.3, acceleration=0.4, force=0.5, cond=0.25)
    full = capability(model, controller)
    cap = full.inset(room).less(m)
    keep = 0.1 * (g["leg_max"] - g["leg_min"])
    assert cap.leg_min == pytest.approx(g["leg_min"] + room + keep, rel=1e-15)
    assert cap.leg_max == pytest.approx(g["leg_max"] - room - keep, rel=1e-15)
    assert cap.speed == pytest.approx(0.7 * speed, rel=1e-15)
    assert cap.acceleration == pytest.approx(0.6 * full.acceleration, rel=1e-15)
    assert cap.force == pytest.approx(0.5 * force, rel=1e-15)
    assert cap.cond == pytest.approx(0.75 * COND_LIMIT, rel=1e-15)
    # no cones or clearance in the scene: nothing geometric to keep free of, none to check
    assert not np.any(cap.keep) and cap.geometric is None


def test_the_geometric_margins_kept_are_fractions_of_the_cone_and_the_leg_radius(tmp_path):
    path = tmp_path / "micro_cones.toml"
    path.write_text(MICRO.read_text() + "\n[joints]\nbase_cone = 0.6\nplatform_cone = 0.5\n\n"
                    "[clearance]\nleg_radius = 0.004\n")
    model = load_scene(path)
    cap = capability(model, scene_of(model).controller).less(Margins(cone=0.1, clearance=0.5))
    keep = dict(zip((lim.name for lim in LIMITS), cap.keep))
    assert keep["base_cone"] == pytest.approx(0.06, rel=1e-15)
    assert keep["platform_cone"] == pytest.approx(0.05, rel=1e-15)
    assert keep["leg_clearance"] == keep["obstacle"] == pytest.approx(0.002, rel=1e-15)
    assert cap.geometric is not None
    assert {lim.name for lim in cap.geometric.present()} >= {"base_cone", "platform_cone",
                                                             "leg_clearance"}


def test_a_scene_without_stroke_or_drive(scene):
    model, _, _ = scene
    free = replace(model, leg_min=None, leg_max=None)
    cap = capability(free, None)
    assert cap.drive is None and cap.speed is None and cap.force is None and cap.voltage is None
    inset = cap.inset(0.001)
    assert inset.stroke == (0.001, math.inf)
    less = inset.less(Margins())
    assert less.stroke == (0.001, math.inf) and less.drive is None


def test_a_bad_margin_is_named(scene):
    model, controller, _ = scene
    with pytest.raises(ValueError, match="envelope margin 'speed' must be in"):
        capability(model, controller).less(Margins(speed=1.0))


def test_the_overshoot_room_stops_the_moving_mass_from_the_no_load_speed(scene):
    """room = m v0^2 / (2 (F - F_hold)): the distance a constant net force F - F_hold takes to
    stop m from v0; inf when the drive cannot out-push what it holds."""
    model, controller, table = scene
    cap = capability(model, controller)
    speed, force, _ = _drive(table)
    d = table["drive"]
    m = cap.axis.load_mass + d["gear_ratio"] ** 2 * d["rotor_inertia"] / d["pinion_radius"] ** 2
    held = 12.5
    room = overshoot_room(cap.axis, held)
    assert room == pytest.approx(m * speed ** 2 / (2 * (force - held)), rel=1e-14)
    assert cap.room(-held) == room
    # braking at the net force from v0 over `room` ends at rest: v0^2 - 2 a room = 0
    assert speed ** 2 - 2 * (force - held) / m * room == pytest.approx(0.0, abs=1e-12)
    assert overshoot_room(cap.axis, force) == math.inf
