"""The rules between a scene's keys are written once (native/src/rules.c): the scene reader
(scene_from_dict) and the exported FMU (exitInitializationMode) refuse the same broken scenes
for the same rule, naming the same key (the FMU's parameter, or one of its elements) and giving
the same reason; a key that breaks its own rule is named before any rule between keys; the
Plant and the FMU refuse the same initial pose q0. One FMU is exported (FMI 2.0), its
instances run in a child process (a crash fails the test, not the session)."""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import SceneError, SingularityError, StrokeLimitError, scene_from_dict
from stewart_fmu import table
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.plant import Plant
from tests.helpers import SCENE_FILES, host_binary_only, scene_dict

HERE = Path(__file__).resolve().parent
ERROR = 3
CALL = "exitInitializationMode"


def _micro(key: str):
    *tables, name = key.split(".")
    node = scene_dict("micro")
    for t in tables:
        node = node[t]
    return node[name]


def _joint_copy(key: str, src: int, dst: int) -> list:
    pts = [list(p) for p in _micro(key)]
    pts[dst] = list(pts[src])
    return pts


# (id, {dotted key: its new value}, the key the refusal names, a fragment of the reason)
BROKEN = [
    ("coincident base joints", {"geometry.base_joints": _joint_copy("geometry.base_joints", 0, 3)},
     "geometry.base_joints", "joints 1 and 4 coincide"),
    ("coincident platform joints",
     {"geometry.platform_joints": _joint_copy("geometry.platform_joints", 2, 5)},
     "geometry.platform_joints", "joints 3 and 6 coincide"),
    ("leg_min = leg_max", {"geometry.leg_min": 0.19}, "geometry.leg_max", "must exceed leg_min"),
    ("leg_max < leg_min", {"geometry.leg_max": 0.05}, "geometry.leg_max", "must exceed leg_min"),
    ("zero platform moment", {"platform.inertia": [6e-4, 0.0, 1.1e-3]}, "platform.inertia",
     "not positive definite"),
    ("triangle-violating inertia", {"platform.inertia": [6e-4, 6e-4, 1.3e-3]}, "platform.inertia",
     "triangle inequality"),
    ("lower leg axial > 2 transverse", {"legs.lower_inertia": [3e-5, 7e-5]}, "legs.lower_inertia",
     "exceeds twice the transverse"),
    ("upper leg axial > 2 transverse", {"legs.upper_inertia": [1e-6, 2.5e-6]}, "legs.upper_inertia",
     "exceeds twice the transverse"),
    ("home above the stroke", {"geometry.home": [0.0, 0.0, 0.3, 0.0, 0.0, 0.0]}, "geometry.home",
     "outside the stroke"),
    ("home singular", {"geometry.home": [0.0, 0.0, 0.12, 0.0, 0.0, math.pi / 2]}, "geometry.home",
     "near-singular"),
    # a key's own rule first: platform.mass is named, not the broken triangle
    ("negative mass and triangle", {"platform.mass": -0.5, "platform.inertia": [6e-4, 6e-4, 1.3e-3]},
     "platform.mass", "must be > 0"),
]
# The initial pose q0, for the FMU and the Plant: (id, q0, error class, fragment).
POSES = [("q0 above the stroke", [0.0, 0.0, 0.3, 0.0, 0.0, 0.0], StrokeLimitError, "outside the stroke"),
         ("q0 singular", [0.0, 0.0, 0.12, 0.0, 0.0, math.pi / 2], SingularityError, "near-singular")]

_CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from native_fmu_child import initialization_refusals
cases = json.loads(sys.stdin.read())
print("RESULT " + json.dumps(initialization_refusals(sys.argv[2], 2, cases)), flush=True)
"""


def _values(changes: dict) -> dict[int, float]:
    """The FMU parameter values of the changed scene keys: value reference -> value (a matrix
    row-major from its group's first value reference, as the table lays it out)."""
    out = {}
    for key, value in changes.items():
        group = next(g for g in table.VARIABLES if g.name == key)
        for i, x in enumerate(np.ravel(value)):
            out[group.vr + i] = float(x)
    return out


@pytest.fixture(scope="module")
def refusals(tmp_path_factory) -> dict:
    """Each broken scene and each bad q0 through one exported FMU, in a child process."""
    folder = tmp_path_factory.mktemp("rules_fmu")
    with host_binary_only():   # run here: the Windows DLL is tested in test_windows_fmu.py
        fmu = export_fmu(SCENE_FILES["micro"], folder / "micro.fmu", fmi_version=2)
    from fmpy import extract
    unzipdir = extract(str(fmu), str(folder / "micro"))
    cases = {name: _values(changes) for name, changes, _, _ in BROKEN}
    cases.update({name: _values({"q0": q0}) for name, q0, _, _ in POSES})
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(HERE), unzipdir], capture_output=True,
                          text=True, timeout=120, input=json.dumps(cases))
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    return json.loads(lines[-1][7:])


def _fmu_refusal(run: dict) -> str:
    assert run["set"] == 0 and run["exit"] == ERROR, run
    found = [m for m in run["messages"] if m.startswith(f"{CALL}: parameter ")]
    assert len(found) == 1, run["messages"]
    return found[0]


def _reader_refusal(changes: dict) -> SceneError:
    """The scene reader's SceneError for the micro-manipulator's scene with `changes` (dotted
    key: value) applied."""
    data = scene_dict("micro")
    for dotted, value in changes.items():
        *tables, name = dotted.split(".")
        node = data
        for t in tables:
            node = node[t]
        node[name] = value
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    return info.value


@pytest.mark.parametrize("changes,key,why", [c[1:] for c in BROKEN], ids=[c[0] for c in BROKEN])
def test_scene_reader_and_fmu_refuse_for_the_same_rule(refusals, request, changes, key, why):
    """The scene reader's SceneError names the key; the FMU logs 'parameter <key> <reason>' (or
    an element of the key, '<key>[i]' / '<key>[row,col]') with the very same reason."""
    err = _reader_refusal(changes)
    assert err.key == key and why in err.reason, (err.key, err.reason)
    message = _fmu_refusal(refusals[request.node.callspec.id])
    named = re.match(rf"{CALL}: parameter ({re.escape(key)}(?:\[\d+(?:,\d+)?\])?) ", message)
    assert named, message
    assert why in message
    if why != "must be > 0":   # a rule between keys: one reason text, the core's
        assert message == f"{named.group(0)}{err.reason}", (message, err.reason)


@pytest.mark.parametrize("q0,error,why", [p[1:] for p in POSES], ids=[p[0] for p in POSES])
def test_plant_and_fmu_refuse_the_same_initial_pose(refusals, request, q0, error, why):
    """The same q0: Plant.exit_initialization_mode raises the typed error, the FMU logs
    'parameter q0 <reason>' with the same reason."""
    plant = Plant(scene_from_dict(scene_dict("micro")))
    plant.enter_initialization_mode()
    plant.set_initial(q=np.array(q0))
    with pytest.raises(error) as info:
        plant.exit_initialization_mode()
    reason = str(info.value).removeprefix("the initial pose ")
    assert why in reason
    assert _fmu_refusal(refusals[request.node.callspec.id]) == f"{CALL}: parameter q0 {reason}"


# --- the physical bounds of the one table: the scene reader and both FMUs -----------------------

# (id, {dotted key: value}, the key named, the reason as both give it)
BEYOND = [
    ("gear ratio 1e308", {"drive.gear_ratio": 1e308}, "drive.gear_ratio", "must be <= 100000, got 1e+308"),
    ("pinion radius 1e-300", {"drive.pinion_radius": 1e-300}, "drive.pinion_radius",
     "must be >= 1e-06 m, got 1e-300"),
    ("lower mass 1e308", {"legs.lower_mass": 1e308}, "legs.lower_mass", "must be <= 100000 kg, got 1e+308"),
    ("platform mass 1e7", {"platform.mass": 1e7}, "platform.mass", "must be <= 1e+06 kg, got 10000000.0"),
    ("gravity -1e4", {"gravity": [0.0, 0.0, -1e4]}, "gravity", "must be >= -1000 m/s2, got "),
    ("m_d beyond its bound", {"drive.gear_ratio": 1e5, "drive.rotor_inertia": 1.0}, "drive.gear_ratio",
     "gives the reflected drive mass m_d = zeta^2 I / r^2 = 400000000000000.0 kg (leg 1: drive.gear_ratio 100000.0, "
     "drive.rotor_inertia 1.0, drive.pinion_radius 0.005): must be >= 0 and <= 1e+08 kg"),
]


@pytest.fixture(scope="module", params=[2, 3], ids=["fmi2", "fmi3"])
def bound_refusals(request, tmp_path_factory) -> dict:
    """Each BEYOND case through an exported FMU of the micro scene (FMI 2.0 and 3.0), in a child
    process: its exitInitializationMode status and log."""
    version = request.param
    folder = tmp_path_factory.mktemp(f"bounds_fmu{version}")
    with host_binary_only():   # run here: the Windows DLL is tested in test_windows_fmu.py
        fmu = export_fmu(SCENE_FILES["micro"], folder / "micro.fmu", fmi_version=version)
    from fmpy import extract
    unzipdir = extract(str(fmu), str(folder / "micro"))
    cases = {name: _values(changes) for name, changes, _, _ in BEYOND}
    child = _CHILD.replace("initialization_refusals(sys.argv[2], 2, cases)",
                           f"initialization_refusals(sys.argv[2], {version}, cases)")
    proc = subprocess.run([sys.executable, "-c", child, str(HERE), unzipdir], capture_output=True,
                          text=True, timeout=120, input=json.dumps(cases))
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    return json.loads(lines[-1][7:])


@pytest.mark.parametrize("changes,key,why", [c[1:] for c in BEYOND], ids=[c[0] for c in BEYOND])
def test_scene_reader_and_fmu_refuse_values_beyond_the_bounds(bound_refusals, request, changes,
                                                              key, why):
    """A value beyond its key's physical bounds (the one table, native/include/stewart_table.h),
    or a derived quantity beyond its own: the scene reader names the key; exitInitializationMode
    of FMI 2.0 and 3.0 returns Error, logging 'parameter <key> <the same reason>' (no NaN
    answered with OK later: drive.gear_ratio = 1e308 gave one)."""
    err = _reader_refusal(changes)
    assert err.key == key and why in err.reason, (err.key, err.reason)
    name = request.node.callspec.id.split("-", 1)[1]   # "fmi2-<case>"
    message = _fmu_refusal(bound_refusals[name])
    named = re.match(rf"{CALL}: parameter {re.escape(key)}(\[\d+\])? ", message)
    assert named and why in message, message
    if not named.group(1):   # a scalar: the very same reason (an element's names its value)
        assert message == f"{named.group(0)}{err.reason}", (message, err.reason)
