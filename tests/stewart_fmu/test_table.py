"""The one table (native/include/stewart_table.h) is the only spelling of the packed layout and
of the FMU's variables: every layer, C and Python, takes names, offsets and value references
from it, and this test fails when one spells a name, offset or value reference the table does
not hold."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import model as M
from stewart_fmu import scene, table
from stewart_fmu.dynamics import PARTS
from stewart_fmu.fmu import variables as V
from stewart_fmu.io import POSE
from stewart_fmu.native.core import lib
from stewart_fmu.scene import load_scene

from tests.helpers import shipped_scenes

ROOT = Path(__file__).resolve().parents[2]
NATIVE = ROOT / "stewart_fmu" / "native"
C_FILES = sorted([*NATIVE.glob("include/*.h"), *NATIVE.glob("src/*.[ch]"), *NATIVE.glob("fmi/*.[ch]")])
PY_DIRS = ("stewart_fmu", "controller", "hil", "stewart_sim")
SCENES = sorted((ROOT / "scenes").glob("*.toml"))
# Names the expansions define beside the entries (stewart.h, fmi/model.h, fmi/model.c).
P_EXTRA = {"N_PARAMS"}
VR_EXTRA = {"TIME", "N_PAR", "METHOD", "END", "COMPUTED", "PARAMETER", "INPUT", "OUTPUT"}


def _c_text(path: Path) -> str:
    """A C file without its comments."""
    return re.sub(r"/\*.*?\*/", " ", path.read_text(), flags=re.S)


def test_layout_is_contiguous_and_model_offsets_are_the_tables():
    """Entries follow one another from 0 to N_PARAMS; the P_ offsets of stewart_fmu.model are the table's."""
    at = 0
    for p in table.PARAMS.values():
        assert p.offset == at, p.name
        assert getattr(M, f"P_{p.name}") == p.offset == getattr(lib, f"STEWART_P_{p.name}")
        at += p.count
    assert at == table.N_PARAMS == M.N_PARAMS == lib.STEWART_N_PARAMS
    layout = {n[2:] for n in dir(M) if re.fullmatch(r"P_[A-Z_]+", n)}
    assert layout == set(table.PARAMS), "model.py names a layout entry the table lacks"


def test_packed_sources_are_scene_variables_with_the_same_unit_and_count():
    scene_ids = {g.id: g for g in table.VARIABLES if g.scene}
    for p in table.PARAMS.values():
        if p.source == "COMPUTED":
            continue
        g = scene_ids[p.source]
        assert p.unit in ("", g.unit), p.name
        if p.count <= g.count:   # a per-leg key or a vector, packed as it is
            assert p.count == g.count, p.name
        else:                    # LOWER / UPPER: consecutive groups
            groups = [x for x in table.VARIABLES if g.vr <= x.vr < g.vr + p.count]
            assert sum(x.count for x in groups) == p.count and all(x.scene for x in groups), p.name


def test_value_references_are_ordered_and_disjoint():
    taken: set[int] = set()
    for g in table.VARIABLES:
        vrs = set(range(g.vr, g.vr + g.count))
        assert not vrs & taken, g.name
        taken |= vrs
    assert table.VR_TIME not in taken
    assert table.VR_METHOD == table.VR_N_PAR == max(
        g.vr + g.count for g in table.VARIABLES if g.causality == "parameter" and g.shape != table.STRING)


@pytest.mark.parametrize("path", C_FILES, ids=lambda p: p.name)
def test_c_sources_name_only_table_entries(path):
    """Every STEWART_P_* and VR_* a C file uses is an entry of the table (or a name the
    expansions define), and no C file gives one a number."""
    text = _c_text(path)
    for name in set(re.findall(r"\bSTEWART_P_(\w+)", text)):
        assert name in table.PARAMS or name in P_EXTRA or name.startswith("##"), f"{path.name}: STEWART_P_{name}"
    for name in set(re.findall(r"\bVR_(\w+)", text)):
        assert name in table.GROUPS or name in VR_EXTRA, f"{path.name}: VR_{name}"
    literal = re.findall(r"#define\s+(?:STEWART_P_|VR_)\w+\s+\d", text)
    assert not literal, f"{path.name} defines layout numbers: {literal}"
    # no group name is spelled in the FMI layer: GROUPS and the bounds come from the table
    if path.parent.name == "fmi":
        spelled = {g.name for g in table.VARIABLES if "." in g.name} & set(re.findall(r'"([\w.]+)"', text))
        assert not spelled, f"{path.name} spells {spelled}"


def test_python_spells_no_layout_number():
    """No Python module assigns a number to a P_* or VR_* name, nor indexes params by a
    literal offset."""
    pattern = re.compile(r"^\s*(?:P_|VR_)[\w, ]*=\s*\(?\s*\d", re.M)
    found = []
    for folder in PY_DIRS:
        for path in (ROOT / folder).rglob("*.py"):
            text = path.read_text()
            found += [f"{path.relative_to(ROOT)}: {m.group(0).strip()}" for m in pattern.finditer(text)]
            found += [f"{path.relative_to(ROOT)}: {m}" for m in re.findall(r"params\[\d+\]", text)]
    assert not found


def test_python_tables_are_the_tables():
    """SCENE_KEYS and the scene's number keys are the table's scene variables; the pose
    outputs are io.POSE; force.<part> follow dynamics.PARTS and the core's STEWART_PART_*."""
    assert set(V.SCENE_KEYS) == set(table.scene_groups())
    for key, (vr, shape, _, _) in V.SCENE_KEYS.items():
        g = table.scene_groups()[key]
        assert vr == g.vr and int(np.prod(shape)) == g.count
    plant_numbers = {k for k in scene.NUMBER_KEYS if k.split(".")[0] in
                     {"geometry", "platform", "legs", "drive", "friction", "transmission"}}
    assert plant_numbers == {k for k, g in table.scene_groups().items()
                             if g.count == 1 or g.shape == table.PER_LEG}
    assert [table.GROUPS[f"Q_{c.upper()}"].name for c in POSE] == list(POSE)
    assert [table.GROUPS[f"QD_{c.upper()}"].name for c in POSE] == [f"d{c}" for c in POSE]
    forces = [g for g in table.VARIABLES if g.name.startswith("force.")]
    assert [g.name for g in forces] == [f"force.{p}" for p in PARTS]
    for g in forces:
        part = getattr(lib, f"STEWART_PART_{g.name.split('.')[1].upper()}")
        assert g.vr == table.vr("FORCE_PLATFORM") + 6 * part


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
@pytest.mark.parametrize("version", [2, 3])
def test_fmu_variables_are_table_groups(path, version):
    """Every variable of a scene's FMU lies in the group its name names, at the group's value
    reference plus its element index (row-major)."""
    model = load_scene(path)
    groups = {g.name: g for g in table.VARIABLES}
    for var in V.variables(model, version):
        if var.name == "time":
            assert var.vr == table.VR_TIME
            continue
        base, _, index = var.name.partition("[")
        g = groups[base]
        assert var.causality == g.causality and var.description
        assert version == 3 or not g.fmi3_only, var.name
        k = 0
        if index:
            assert version == 2, f"FMI 3.0 declares arrays, not elements: {var.name}"
            idx = [int(i) - 1 for i in index.rstrip("]").split(",")]
            k = idx[0] * g.shape + idx[1] if len(idx) == 2 else idx[0]
        assert var.vr == g.vr + k, var.name
        assert var.unit == (g.unit or None) or g.unit in ("pose", "rate"), var.name
        if var.shape:   # an FMI 3.0 array: the whole group at its first value reference
            assert version == 3 and var.size == g.count, var.name
            assert var.shape == ((g.count // g.shape, g.shape) if g.shape > 0 else (g.count,)), var.name
            assert var.unit is None if g.unit in ("pose", "rate") else var.unit == (g.unit or None)
            assert var.start is None or len(var.start) == g.count, var.name
        else:           # a scalar: a group of one, an element, or a per-leg key given once
            assert version == 2 or g.count == 1 or g.shape == table.PER_LEG or g.shape == table.STRING, var.name


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_fmi3_arrays_hold_the_fmi2_scalars(path):
    """The FMI 3.0 FMU declares each group of several values as one array, and its values are
    the FMI 2.0 scalars': the same start at the same stored value reference (array's + element,
    row-major), the same value references declared (elements aside), and q, qd, the pose
    arrays, in FMI 3.0 only, holding what x .. dthz hold. The scene's C file tells the binary
    how many values each declared value reference holds (STEWART_VALUES)."""
    model = load_scene(path)
    two, three = V.variables(model, 2), V.variables(model, 3)
    assert V.element_starts(two) == {vr: x for vr, x in V.element_starts(three).items() if vr != table.VR_TIME}
    stored = lambda vs: {v.vr + k for v in vs for k in range(v.size)}  # noqa: E731
    only3 = {g.name for g in table.VARIABLES if g.fmi3_only}
    assert only3 == {"q", "qd"}
    assert max(g.count for g in table.VARIABLES) <= 255   # STEWART_VALUES (fmi/model.h) is unsigned char
    assert stored(two) == stored([v for v in three if v.name not in only3 | {"time"}])
    assert all(v.size == 1 for v in two) and any(v.size > 1 for v in three)
    assert len(three) < len(two)
    q, qd = table.GROUPS["Q"], table.GROUPS["QD"]
    assert (q.count, qd.count, qd.vr) == (6, 6, q.vr + 6)   # the state's q then qd (fmi/model.c output)
    assert [table.GROUPS[f"Q_{c.upper()}"].vr for c in POSE] == list(range(table.vr("Q_X"), table.vr("Q_X") + 6))
    for version, table_ in ((2, two), (3, three)):
        source = V.scene_c_source(model, table_, version)
        sizes = re.search(r"STEWART_VALUES\[VR_END\] = \{([^}]*)\}", source).group(1)
        values = [int(x) for x in sizes.split(",")]
        assert len(values) == table.VR_END
        assert {vr: n for vr, n in enumerate(values) if n} == {v.vr: v.size for v in table_}


def test_integrator_names_are_the_cores():
    """The compiled methods' names: the core's stewart_method_name, read by native.core and
    spelled once more in integrators.COMPILED (a literal for --help); the FMU takes the core's."""
    from stewart_fmu.integrators import COMPILED
    from stewart_fmu.native import core
    from stewart_fmu.native.core import ffi, lib

    names = tuple(ffi.string(lib.stewart_method_name(k)).decode()
                  for k in range(lib.STEWART_N_METHODS))
    assert names == COMPILED == tuple(core.METHODS)
    assert lib.stewart_method_name(lib.STEWART_N_METHODS) == ffi.NULL
    assert lib.stewart_method_name(-1) == ffi.NULL
    assert core.METHODS == {"rk4": lib.STEWART_RK4, "euler": lib.STEWART_EULER,
                            "dopri5": lib.STEWART_DOPRI5}


def test_every_parameter_has_physical_bounds_and_every_scene_meets_them():
    """Each FMU parameter group (scene keys and settings) declares finite bounds min < max of
    kind CLOSED or OPEN in the one table, read alike by C (the FMU's validation) and Python
    (table.bound_reason); the values of every shipped scene lie within them; the controller's
    numbers have theirs in one table too (controller/config.py BOUNDS)."""
    from controller.config import BOUNDS, NUMBER_KEYS
    from controller.drive import MOTOR_KEYS

    params = [g for g in table.VARIABLES if g.causality == "parameter" and g.shape != table.STRING]
    assert params and all(g.bound in (table.BOUND_CLOSED, table.BOUND_OPEN) for g in params)
    assert all(np.isfinite(g.min) and np.isfinite(g.max) and g.min < g.max for g in params)
    assert all(g.bound == table.BOUND_ANY for g in table.VARIABLES if g.causality != "parameter")
    for path in shipped_scenes():
        model = load_scene(path)
        for key, g in table.scene_groups().items():
            value = V.scene_value(model, key)
            if value is not None:
                assert table.bound_reason(g, value) is None, (path.name, key)
    assert set(BOUNDS) == {*NUMBER_KEYS, *(f"motor.{k}" for k in MOTOR_KEYS)}
    mass = table.scene_groups()["platform.mass"]
    assert table.bound_reason(mass, 1e308) == "must be <= 1e+06 kg, got 1e+308"
    assert table.bound_reason(mass, 0.0) == "must be > 0, got 0.0"
