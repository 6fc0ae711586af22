"""Scene rejection rules: every malformed or non-physical scene raises SceneError whose `.key`
names the dotted key and whose message says why; absent tables build no terms at all."""
from __future__ import annotations

import math

import numpy as np
import pytest

from stewart_fmu import SceneError, inverse_dynamics_parts, load_scene, scene_from_dict
from stewart_fmu.model import (
    P_DRIVE_MASS,
    P_HAS_DRIVE,
    P_HAS_FRICTION,
    P_HAS_LEGS,
    P_LOWER,
    P_UPPER,
    P_VISCOUS,
)
from tests.helpers import SCENE_FILES, deleting, scene_dict, setting


def element(path: str, index, value):
    """A mutation that sets one element (index tuple) of the array at `path`."""
    def apply(d):
        *tables, key = path.split(".")
        node = d
        for t in tables:
            node = node[t]
        arr = node[key]
        for i in index[:-1]:
            arr = arr[i]
        arr[index[-1]] = value
    return apply


def copy_joint(path: str, src: int, dst: int):
    """A mutation making joint dst coincide with joint src."""
    def apply(d):
        pts = d["geometry"][path]
        pts[dst] = list(pts[src])
    return apply


NAN, INF = float("nan"), float("inf")

# (id, mutation, expected .key, fragment of the reason)
CASES = [
    # unknown keys
    ("unknown top-level key", setting("colour", "red"), "colour", "unknown key"),
    *[(f"unknown key in [{t}]", setting(f"{t}.bogus", 1.0), f"{t}.bogus", "unknown key")
      for t in ("geometry", "platform", "legs", "drive", "friction")],
    # missing tables and keys
    ("missing [geometry]", deleting("geometry"), "geometry", "required table is missing"),
    ("missing [platform]", deleting("platform"), "platform", "required table is missing"),
    *[(f"missing {k}", deleting(k), k, "required key is missing") for k in (
        "geometry.base_joints", "geometry.platform_joints", "geometry.home", "platform.mass",
        "platform.inertia", "legs.lower_mass", "legs.lower_com", "legs.lower_inertia",
        "legs.upper_mass", "legs.upper_com", "legs.upper_inertia", "drive.gear_ratio",
        "drive.rotor_inertia", "drive.pinion_radius", "friction.viscous", "friction.coulomb")],
    ("table given as a number", setting("legs", 5), "legs", "must be a table"),
    ("name not a string", setting("name", 3), "name", "must be a string"),
    # wrong shapes
    ("5 base joints", lambda d: d["geometry"]["base_joints"].pop(), "geometry.base_joints",
     "wrong shape"),
    ("5 platform joints", lambda d: d["geometry"]["platform_joints"].pop(),
     "geometry.platform_joints", "wrong shape"),
    ("joint with 2 coordinates", element("geometry.base_joints", (2,), [0.1, 0.1]),
     "geometry.base_joints", "shape (6, 3)"),
    ("2-vector home", setting("geometry.home", [0.0, 0.12]), "geometry.home", "wrong shape"),
    ("home as a scalar", setting("geometry.home", 0.12), "geometry.home", "wrong shape"),
    ("2-vector gravity", setting("gravity", [0.0, -9.81]), "gravity", "wrong shape"),
    ("inertia of 2", setting("platform.inertia", [6e-4, 6e-4]), "platform.inertia", "wrong shape"),
    ("leg inertia of 3", setting("legs.upper_inertia", [3e-5, 1e-6, 0.0]), "legs.upper_inertia",
     "wrong shape"),
    ("mass as a list", setting("platform.mass", [0.5]), "platform.mass", "must be a number"),
    ("mass as a string", setting("platform.mass", "0.5"), "platform.mass", "must be a number"),
    # non-finite
    ("nan mass", setting("platform.mass", NAN), "platform.mass", "must be finite"),
    ("inf viscous", setting("friction.viscous", INF), "friction.viscous", "must be finite"),
    ("nan in home", element("geometry.home", (2,), NAN), "geometry.home", "must be finite"),
    ("inf in base joint", element("geometry.base_joints", (1, 0), INF), "geometry.base_joints",
     "must be finite"),
    ("-inf in platform joint", element("geometry.platform_joints", (3, 2), -INF),
     "geometry.platform_joints", "must be finite"),
    ("nan gravity", element("gravity", (2,), NAN), "gravity", "must be finite"),
    ("inf inertia", element("platform.inertia", (0,), INF), "platform.inertia", "must be finite"),
    ("nan leg_max", setting("geometry.leg_max", NAN), "geometry.leg_max", "must be finite"),
    # non-physical masses and inertias
    ("zero platform mass", setting("platform.mass", 0.0), "platform.mass", "must be > 0"),
    ("negative platform mass", setting("platform.mass", -0.5), "platform.mass", "must be > 0"),
    ("negative lower mass", setting("legs.lower_mass", -0.065), "legs.lower_mass", "must be >= 0"),
    ("negative upper mass", setting("legs.upper_mass", -0.065), "legs.upper_mass", "must be >= 0"),
    ("negative platform moment", setting("platform.inertia", [-6e-4, 6e-4, 1.1e-3]),
     "platform.inertia", "must be >= 0"),
    ("zero platform moment", setting("platform.inertia", [6e-4, 0.0, 1.1e-3]), "platform.inertia",
     "not positive definite"),
    ("triangle-violating inertia", setting("platform.inertia", [6e-4, 6e-4, 1.3e-3]),
     "platform.inertia", "triangle inequality"),
    ("leg axial > 2 transverse (lower)", setting("legs.lower_inertia", [3e-5, 7e-5]),
     "legs.lower_inertia", "exceeds twice the transverse"),
    ("leg axial > 2 transverse (upper)", setting("legs.upper_inertia", [1e-6, 2.5e-6]),
     "legs.upper_inertia", "exceeds twice the transverse"),
    ("negative leg moment", setting("legs.lower_inertia", [-3e-5, 0.0]), "legs.lower_inertia",
     "must be >= 0"),
    ("negative lower com", setting("legs.lower_com", -0.04), "legs.lower_com", "must be >= 0"),
    ("negative upper com", setting("legs.upper_com", -0.04), "legs.upper_com", "must be >= 0"),
    # drive and friction
    *[(f"{how} {k}", setting(f"drive.{k}", v), f"drive.{k}", "must be > 0")
      for k in ("gear_ratio", "rotor_inertia")
      for how, v in (("zero", 0.0), ("negative", -1.0))],
    *[(f"{how} pinion_radius", setting("drive.pinion_radius", v), "drive.pinion_radius",
       "must be >= 1e-06 m") for how, v in (("zero", 0.0), ("negative", -1.0))],
    ("negative viscous", setting("friction.viscous", -5.0), "friction.viscous", "must be >= 0"),
    ("negative coulomb", setting("friction.coulomb", -0.1), "friction.coulomb", "must be >= 0"),
    # stroke and home
    ("leg_min = leg_max", setting("geometry.leg_min", 0.19), "geometry.leg_max",
     "must exceed leg_min"),
    ("leg_min > leg_max", setting("geometry.leg_min", 0.25), "geometry.leg_max",
     "must exceed leg_min"),
    ("negative leg_min", setting("geometry.leg_min", -0.07), "geometry.leg_min", "must be > 0"),
    ("home above the stroke", setting("geometry.home", [0.0, 0.0, 0.3, 0.0, 0.0, 0.0]),
     "geometry.home", "outside the stroke"),
    ("home below the stroke", setting("geometry.home", [0.0, 0.0, 0.02, 0.0, 0.0, 0.0]),
     "geometry.home", "outside the stroke"),
    ("home singular", setting("geometry.home", [0.0, 0.0, 0.12, 0.0, 0.0, math.pi / 2]),
     "geometry.home", "singular"),
    # coincident joints
    ("coincident base joints", copy_joint("base_joints", 0, 3), "geometry.base_joints",
     "joints 1 and 4 coincide"),
    ("coincident platform joints", copy_joint("platform_joints", 2, 5),
     "geometry.platform_joints", "joints 3 and 6 coincide"),
    # booleans instead of numbers
    ("boolean mass", setting("platform.mass", True), "platform.mass", "must be a number"),
    ("boolean leg_max", setting("geometry.leg_max", False), "geometry.leg_max", "must be a number"),
    ("boolean in home", element("geometry.home", (5,), False), "geometry.home", "not booleans"),
    ("boolean in inertia", element("platform.inertia", (0,), True), "platform.inertia",
     "not booleans"),
    ("boolean in joints", element("geometry.platform_joints", (0, 0), True),
     "geometry.platform_joints", "not booleans"),
    ("boolean gear ratio", setting("drive.gear_ratio", True), "drive.gear_ratio",
     "must be a number"),
]


@pytest.mark.parametrize("mutate,key,why", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_scene_rejection(micro_dict, mutate, key, why):
    """Each rule: SceneError (a ValueError) with .key the dotted key and the reason in the
    message ("scene key '<key>': <reason>")."""
    mutate(micro_dict)
    with pytest.raises(SceneError) as info:
        scene_from_dict(micro_dict)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.key == key, (err.key, str(err))
    assert why in err.reason, err.reason
    assert f"scene key '{key}'" in str(err) and why in str(err)


@pytest.mark.parametrize("path,value", [
    ("geometry.home", ["0", "0", "0.12", "0", "0", "0"]),
    ("platform.inertia", ["6e-4", "6e-4", "1.1e-3"]),
])
def test_strings_in_arrays_are_rejected(micro_dict, path, value):
    """Strings where numbers belong are rejected in arrays as they are in scalars."""
    setting(path, value)(micro_dict)
    with pytest.raises(SceneError) as info:
        scene_from_dict(micro_dict)
    assert info.value.key == path


# --- files -------------------------------------------------------------------------------------

def _file_text(name: str = "micro") -> str:
    return SCENE_FILES[name].read_text()


@pytest.mark.parametrize("old,new,key", [
    ("mass = 0.5", "mass = nan", "platform.mass"),
    ("mass = 0.5", "mass = inf", "platform.mass"),
    ("viscous = 5.0", "viscous = -inf", "friction.viscous"),
    ("home = [0.0, 0.0, 0.12, 0.0, 0.0, 0.0]", "home = [0.0, 0.0, nan, 0.0, 0.0, 0.0]",
     "geometry.home"),
    ("inertia = [6e-4, 6e-4, 1.1e-3]", "inertia = [6e-4, inf, 1.1e-3]", "platform.inertia"),
    ("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, nan, -9.81]", "gravity"),
])
def test_non_finite_toml_values_are_rejected(tmp_path, old, new, key):
    """TOML's nan / inf / -inf literals: SceneError naming the key, 'must be finite', and the
    file in the message."""
    text = _file_text()
    assert text.count(old) == 1
    path = tmp_path / "scene.toml"
    path.write_text(text.replace(old, new))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == key and "must be finite" in str(info.value)
    assert str(path) in str(info.value) and info.value.source == str(path)


def test_invalid_toml_file(tmp_path):
    """A file that is not TOML: SceneError with key '<file>', 'not valid TOML' and the file."""
    path = tmp_path / "broken.toml"
    path.write_text(_file_text().replace("[platform]", "[platform", 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == "<file>" and "not valid TOML" in str(info.value)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    """A path that does not exist: SceneError with key '<file>' saying there is no such file."""
    path = tmp_path / "nowhere.toml"
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.key == "<file>" and "no such scene file" in str(info.value)
    assert str(path) in str(info.value)


def test_file_errors_name_the_file(tmp_path):
    """A rule broken in a file: the message starts with the file's path."""
    path = tmp_path / "neg.toml"
    path.write_text(_file_text().replace("mass = 0.5", "mass = -0.5"))
    with pytest.raises(SceneError, match="must be > 0") as info:
        load_scene(path)
    assert info.value.key == "platform.mass" and str(info.value).startswith(f"{path}: ")


# --- what the scene declares is what the model holds -----------------------------------------

def test_both_scene_files_load():
    """The shipped scenes load with all optional effects and the contract's m_d values."""
    micro, sim = load_scene(SCENE_FILES["micro"]), load_scene(SCENE_FILES["sim"])
    assert micro.effects == sim.effects == ("legs", "drive", "friction")
    assert micro.drive.reflected_mass == pytest.approx(16.0, rel=1e-15)
    assert sim.drive.reflected_mass == pytest.approx(125.0, rel=1e-15)


@pytest.mark.parametrize("table", ["legs", "drive", "friction"])
def test_absent_table_builds_no_terms(micro_dict, table):
    """A scene without [legs] / [drive] / [friction]: the Model's attribute is None, its params
    flag is 0 and its parameters are not packed (0); the other effects stay; the matching parts
    of inverse_dynamics_parts are exactly zero (not computed)."""
    model = scene_from_dict({k: v for k, v in micro_dict.items() if k != table})
    assert getattr(model, table) is None
    assert table not in model.effects and len(model.effects) == 2
    flag = {"legs": P_HAS_LEGS, "drive": P_HAS_DRIVE, "friction": P_HAS_FRICTION}[table]
    assert model.params[flag] == 0.0
    others = {"legs": P_HAS_LEGS, "drive": P_HAS_DRIVE, "friction": P_HAS_FRICTION}
    assert all(model.params[f] == 1.0 for t, f in others.items() if t != table)
    packed = {"legs": slice(P_LOWER, P_UPPER + 4), "drive": slice(P_DRIVE_MASS, P_DRIVE_MASS + 1),
              "friction": slice(P_VISCOUS, P_VISCOUS + 2)}[table]
    assert np.all(model.params[packed] == 0.0)
    q = model.home + np.r_[0.002, -0.001, 0.003, 0.1, -0.2, 0.15]
    qd = np.r_[0.05, -0.02, 0.03, 0.5, 1.0, -0.7]
    qdd = np.r_[1.0, 2.0, -1.5, 10.0, -5.0, 8.0]
    parts = inverse_dynamics_parts(model, q, qd, qdd)
    zero_parts = {"legs": ("lower_legs", "upper_legs"), "drive": ("drives",),
                  "friction": ("friction",)}[table]
    for name, value in parts.items():
        if name in zero_parts:
            assert np.all(value == 0.0), name
        else:
            assert np.abs(value).max() > 0.0, name


def test_legs_with_zero_mass_differ_from_absent_legs(micro_dict):
    """[legs] with zero masses and inertias is declared (flag 1, legs computed as zeros), unlike
    an absent [legs] (flag 0): the contract distinguishes them."""
    micro_dict["legs"] = {"lower_mass": 0.0, "lower_com": 0.0, "lower_inertia": [0.0, 0.0],
                          "upper_mass": 0.0, "upper_com": 0.0, "upper_inertia": [0.0, 0.0]}
    model = scene_from_dict(micro_dict)
    assert model.legs is not None and model.params[P_HAS_LEGS] == 1.0


def test_optional_keys_and_project_tables(micro_dict):
    """gravity defaults to [0, 0, -9.81]; leg_min / leg_max are optional; the project's own
    tables (controller, cueing, case, solver) are accepted and kept in Model.extra."""
    del micro_dict["gravity"], micro_dict["geometry"]["leg_min"], micro_dict["geometry"]["leg_max"]
    micro_dict["controller"] = {"kp": 1.0}
    model = scene_from_dict(micro_dict)
    assert np.array_equal(model.gravity, [0.0, 0.0, -9.81])
    assert model.leg_min is None and model.leg_max is None
    assert dict(model.extra) == {"controller": {"kp": 1.0}}


def test_sim_scene_rejections_name_keys_too(sim_dict):
    """The same rules on the simulator scene (spot check): a coincident base joint and a
    triangle-violating inertia."""
    copy_joint("base_joints", 1, 2)(sim_dict)
    with pytest.raises(SceneError) as info:
        scene_from_dict(sim_dict)
    assert info.value.key == "geometry.base_joints" and "coincide" in str(info.value)
    d = scene_dict("sim")
    d["platform"]["inertia"] = [100.0, 100.0, 2600.0]
    with pytest.raises(SceneError, match="triangle") as info:
        scene_from_dict(d)
    assert info.value.key == "platform.inertia"
