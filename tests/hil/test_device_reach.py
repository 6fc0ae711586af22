"""The device refuses a setpoint whose pose violates a joint cone or a leg clearance of the
scene's [joints] and [clearance] tables (the one feasibility engine, controller.capability):
one STATUSTEXT naming the limit and the leg or pair, nothing moves; the same pose is accepted
by the same scene without those tables. The violation is confirmed independently of the
engine (numpy: the angle between the leg and its joint's axis, the distance between two legs'
segments)."""
from __future__ import annotations

from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from tests.app.test_workspace import Reference, legs, segment_distance, tomllib_load  # noqa: E402  (numpy, independent)

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
CONE, RADIUS = 1.2, 0.009
YAWED = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]                # past a platform cone of 0.6 rad, leg 1
CROSSED = [0.02950108, 0.0251514, -0.01681271, 0.25153145, -0.32824542, 0.49505509]


def scene(tmp_path: Path, cone: float, radius: float):
    """The micro-manipulator with cones and a leg radius, and its numpy reference."""
    path = tmp_path / f"micro_{cone}_{radius}.toml"
    path.write_text(MICRO.read_text() + f"\n[joints]\nbase_cone = {cone!r}\nplatform_cone = "
                    f"{cone!r}\n\n[clearance]\nleg_radius = {radius!r}\n")
    return load_scene(path), Reference(tomllib_load(MICRO), cone, radius)


def arm():
    return ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                           0, 0, 0, 0, 0, 0)


def setpoint(lengths):
    return ms.MAVLink_leg_setpoint_message(1000, 1, list(map(float, lengths)), [0.0] * 6, 0,
                                           [0.0] * 6)


def texts(msgs):
    """The texts said: the chunks of one STATUSTEXT id (hil.statustext) joined."""
    said: dict[int, str] = {}
    for m in msgs:
        if m.get_type() == "STATUSTEXT":
            said[m.id] = said.get(m.id, "") + m.text
    return list(said.values())


def _refused(model, pose):
    dev = Device(model)
    dev.receive(arm())
    l0 = dev.plant.outputs.lengths.copy()
    lengths = inverse_kinematics(model, np.asarray(model.home) + pose).lengths
    assert np.all(lengths > dev.capability.leg_min) and np.all(lengths < dev.capability.leg_max)
    out = dev.receive(setpoint(lengths))
    for _ in range(50):
        dev.tick()
    return dev, texts(out), np.max(np.abs(dev.plant.outputs.lengths - l0))


def test_a_setpoint_past_a_joint_cone_is_refused_naming_it(tmp_path):
    model, ref = scene(tmp_path, 0.6, 0.004)
    m = ref.margins((np.asarray(model.home) + YAWED)[None])
    # numpy: the platform cone is the one violated, by more than 0.1 rad, the others hold
    assert m["platform_cone"][0] < -0.1 and min(m["base_cone"][0], m["leg_clearance"][0]) > 0
    dev, said, moved = _refused(model, YAWED)
    assert len(said) == 1 and said[0].startswith("refused: platform_cone at leg 1, margin -0.1"), said
    assert dev.counters.setpoints_refused == 1 and dev.counters.setpoints_accepted == 0
    assert moved < 1e-12
    # the same scene without [joints] follows it
    free = load_scene(MICRO)
    dev, said, moved = _refused(free, YAWED)
    assert said == [] and dev.counters.setpoints_accepted == 1 and moved > 1e-3


def test_a_setpoint_whose_legs_touch_is_refused_naming_the_pair(tmp_path):
    model, ref = scene(tmp_path, CONE, RADIUS)
    q = (np.asarray(model.home) + CROSSED)[None]
    m = ref.margins(q)
    assert m["leg_clearance"][0] < -1e-4 and min(m["base_cone"][0], m["platform_cone"][0]) > 0
    P, _, _ = legs(ref.base, ref.top, q)
    gaps = {(i, j): float(segment_distance(ref.base[None, i], P[:, i], ref.base[None, j],
                                           P[:, j])[0]) for i, j in combinations(range(6), 2)}
    i, j = min(gaps, key=gaps.get)                    # numpy: the pair whose capsules overlap
    dev, said, moved = _refused(model, CROSSED)
    assert len(said) == 1 and said[0].startswith(
        f"refused: leg_clearance at legs {i + 1}-{j + 1}, margin -"), (said, i, j)
    assert dev.counters.setpoints_refused == 1 and moved < 1e-12
