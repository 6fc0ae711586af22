"""The native FMU (stewart_fmu.fmu.export.export_fmu): C core + C FMI layer, FMI 2.0 and 3.0.

Checked against the in-process plant (stewart_fmu.plant.Plant) driven the same way: same
inputs held over each step, same communication points. Agreement is measured as in
tests/stewart_fmu/test_fmu.py: max |fmu - plant| / scale, scale = largest |value| among the outputs of the
same unit over the run, and must be <= RTOL = 1e-12 (the FMU's binary runs the same C step as Plant). Rollback, serialization and reset are asserted bit for bit. Importers: a small C
master (dlopen), fmpy (validate, simulate_fmu, FMU2Slave / FMU3Slave), libcosimpy (2.0).
Error and fuzz scenarios run in child processes, so that a crash fails a test instead of
ending the session. Every FMU is built once per module.
"""
from __future__ import annotations

import ctypes
import json
import shutil
import subprocess
import sys
import time
import tomllib
import zipfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

from stewart_fmu import Model, inverse_dynamics, load_scene, table
from stewart_fmu.fmu import variables as V
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.plant import Plant
from stewart_fmu.errors import SceneError
from stewart_fmu.scene import apply_overrides, scene_from_dict
from tests.helpers import fmi2_logging_callbacks, host_binary_only, record
from tests.stewart_fmu.native_fmu_child import Elements

ROOT = Path(__file__).resolve().parents[2]
SCENES = {"micro": ROOT / "scenes" / "micro_manipulator.toml",
          "sim": ROOT / "scenes" / "motion_simulator.toml"}
COMPLIANT = ROOT / "scenes" / "stiff" / "compliant.toml"
HERE = Path(__file__).resolve().parent
FMI_INCLUDE = ROOT / "stewart_fmu" / "native" / "fmi"
H = 1e-3
RTOL = 1e-12
ERROR, DISCARD = 3, 2



# --- exported FMUs ------------------------------------------------------------------------------

@dataclass
class Built:
    scene: Path
    version: int
    path: Path
    unzipdir: Path
    md: object
    data: dict
    model: Model

    @cached_property
    def elements(self) -> Elements:
        """The values one by one under their FMI 2.0 names (an FMI 3.0 array's elements)."""
        return Elements(self.md)

    @property
    def vr(self) -> dict[str, int]:
        """Value references of the variables and of every element (an FMI 3.0 array's element
        k at the array's + k, where the binary stores it)."""
        return self.elements.vr

    @property
    def variables(self) -> dict:
        return {v.name: v for v in self.md.modelVariables}

    @property
    def outputs(self) -> list[str]:
        """The outputs' elements, in order (sigma[1] .. in FMI 2.0 and 3.0 alike)."""
        return self.elements.outputs

    @property
    def output_vrs(self) -> list[int]:
        """The declared outputs' value references (FMI 3.0: one per array)."""
        return [v.valueReference for v in self.md.modelVariables if v.causality == "output"]

    @property
    def input_vrs(self) -> list[int]:
        """The declared inputs' value references: sigma, then tau with a drive."""
        return [v.valueReference for v in self.md.modelVariables if v.causality == "input"]

    def unit(self, name: str) -> str | None:
        """An element's unit (an FMI 3.0 pose array has none: its elements are m or rad)."""
        var = self.elements.variable[name]
        if var.unit or not var.shape:
            return var.unit
        base, _, idx = name.partition("[")
        return (V.POSE_UNITS if base in ("q", "q0", "geometry.home") else V.RATE_UNITS)[int(idx[:-1]) - 1]

    @property
    def token(self) -> str:
        return self.md.guid if self.version == 2 else self.md.instantiationToken

    @property
    def binary(self) -> Path:
        folder = "linux64" if self.version == 2 else "x86_64-linux"
        return self.unzipdir / "binaries" / folder / "StewartPlant.so"


def _build(scene: Path, version: int, folder: Path) -> Built:
    path = export_fmu(scene, folder / f"{scene.stem}_{version}.fmu", fmi_version=version)
    unzipdir = Path(extract(str(path), str(folder / f"{scene.stem}_{version}")))
    with scene.open("rb") as fh:
        data = tomllib.load(fh)
    return Built(scene, version, path, unzipdir, read_model_description(str(path)), data,
                 load_scene(scene))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[tuple[str, int], Built]:
    """Each scene's FMU, FMI 2.0 and 3.0 (its host binary only: the Windows DLL is tested in
    test_windows_fmu.py)."""
    folder = tmp_path_factory.mktemp("native_fmus")
    with host_binary_only():
        return {(name, v): _build(scene, v, folder) for name, scene in SCENES.items()
                for v in (2, 3)}


# --- driving the FMU through fmpy, and the Plant --------------------------------------------------

class Slave:
    """fmpy's FMU2Slave / FMU3Slave behind one interface, with the log captured."""

    def __init__(self, b: Built, name: str = "plant"):
        self.b, self.vr, self.elements = b, b.vr, b.elements
        self.messages: list[tuple[int, str, str]] = []
        self.inputs = b.input_vrs if b.version == 3 else [self.vr[f"sigma[{i}]"] for i in range(1, 7)]
        if "drive" in b.data and b.version == 2:
            self.inputs += [self.vr[f"tau[{i}]"] for i in range(1, 7)]
        self.out_vr = b.output_vrs if b.version == 3 else [self.vr[n] for n in b.outputs]
        self.current = self.elements.current()
        common = dict(guid=b.token, unzipDirectory=str(b.unzipdir), modelIdentifier="StewartPlant",
                      instanceName=name)
        if b.version == 2:
            from fmpy.fmi2 import FMU2Slave

            cb = fmi2_logging_callbacks(lambda *message: self.messages.append(message))
            self.fmu = FMU2Slave(**common)
            self.fmu.instantiate(loggingOn=True, callbacks=cb)
        else:
            from fmpy.fmi3 import FMU3Slave

            def log3(_env, status, category, message):
                self.messages.append((status, (category or b"").decode(), message.decode()))

            self._keep = (log3,)
            self.fmu = FMU3Slave(**common)
            self.fmu.instantiate(loggingOn=True, logMessage=log3)

    # calls that differ between the versions
    def set(self, values: dict) -> None:
        """Set elements by name (FMI 3.0: each array touched, whole, the rest as last set)."""
        if values:
            vrs, vals = [self.vr[n] for n in values], [float(x) for x in values.values()]
            if self.b.version == 2:
                self.fmu.setReal(vrs, vals)
                return
            arrays, flat = self.elements.declared(vrs, vals, self.current)
            self.fmu.setFloat64(arrays, flat)
            k = 0
            for a in arrays:
                n = self.elements.size[a]
                if a in self.current:
                    self.current[a] = flat[k:k + n]
                k += n

    def get_vr(self, vrs) -> np.ndarray:
        """Elements by value reference (FMI 3.0: their arrays read whole)."""
        if self.b.version == 2:
            return np.array(self.fmu.getReal(list(vrs)))
        arrays, n = self.elements.reads(list(vrs))
        return np.array(self.elements.pick(list(vrs), arrays, self.fmu.getFloat64(arrays, n)))

    def get(self, names) -> np.ndarray:
        return self.get_vr([self.vr[n] for n in names])

    def outputs(self) -> np.ndarray:
        """Every output element, in b.outputs order: FMI 3.0 reads the arrays in one call."""
        if self.b.version == 2:
            return np.array(self.fmu.getReal(self.out_vr))
        return np.array(self.fmu.getFloat64(self.out_vr, len(self.b.outputs)))

    def init(self, reals: dict | None = None, method: str | None = None, init_reals=None) -> "Slave":
        self.current = self.elements.current()   # after instantiate or reset: the start values
        if self.b.version == 2:
            self.fmu.setupExperiment(startTime=0.0)
        self.set(reals or {})
        if self.b.version == 2:
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
        if method:
            self.fmu.setString([self.vr["solver.method"]], [method])
        self.set(init_reals or {})
        self.fmu.exitInitializationMode()
        return self

    def step(self, t: float, h: float, u) -> np.ndarray:
        """Set the inputs (sigma, then tau with a drive; FMI 3.0: the arrays, 6 or 12 values for
        1 or 2 value references), doStep(t, h), get every output."""
        (self.fmu.setReal if self.b.version == 2 else self.fmu.setFloat64)(self.inputs, [float(x) for x in u])
        self.fmu.doStep(t, h)
        return self.outputs()

    def run(self, times, steps, inputs) -> np.ndarray:
        return np.array([self.step(t, h, u) for t, h, u in zip(times, steps, inputs)])

    def get_state(self):
        return self.fmu.getFMUstate() if self.b.version == 2 else self.fmu.getFMUState()

    def set_state(self, s) -> None:
        (self.fmu.setFMUstate if self.b.version == 2 else self.fmu.setFMUState)(s)

    def free_state(self, s) -> None:
        (self.fmu.freeFMUstate if self.b.version == 2 else self.fmu.freeFMUState)(s)

    def serialize(self, s) -> bytes:
        return (self.fmu.serializeFMUstate if self.b.version == 2 else self.fmu.serializeFMUState)(s)

    def deserialize(self, blob: bytes):
        return (self.fmu.deSerializeFMUstate if self.b.version == 2 else self.fmu.deserializeFMUState)(blob)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


class Reference:
    """The in-process Plant driven like the FMU; its outputs in the FMU's output order."""

    def __init__(self, model: Model, outputs: list[str], options: IntegratorOptions | None = None,
                 q0=None, qd0=None, sigma0=None):
        self.model, self.names = model, outputs
        self.plant = Plant(model, options or IntegratorOptions())
        self.plant.setup_experiment(0.0)
        self.plant.enter_initialization_mode()
        # the FMU's inputs start at the force holding the scene's home (variables.hold_forces)
        self.plant.set_force(hold_forces(model) if sigma0 is None else sigma0)
        if q0 is not None or qd0 is not None:
            self.plant.set_initial(q0, qd0)
        self.plant.exit_initialization_mode()

    def outputs(self) -> np.ndarray:
        p, o = self.plant, self.plant.outputs
        pose = dict(zip(("x", "y", "z", "thx", "thy", "thz"), range(6)))
        row = []
        for name in self.names:
            base, _, idx = name.partition("[")
            i = int(idx[:-1]) - 1 if idx else 0
            if name in pose:
                row.append(o.q[pose[name]])
            elif name[1:] in pose and name[0] == "d":
                row.append(o.qd[pose[name[1:]]])
            elif base == "q":
                row.append(o.q[i])
            elif base == "qd":
                row.append(o.qd[i])
            elif base == "l":
                row.append(o.lengths[i])
            elif base == "ldot":
                row.append(o.rates[i])
            elif base == "v":
                row.append(o.twist[i])
            elif base == "omega":
                row.append(o.twist[3 + i])
            elif base == "cond":
                row.append(o.cond)
            elif base == "rack_force":
                row.append(p.rack_force[i])
            elif base.startswith("force."):
                row.append(o.parts[base[6:]][i])
            else:
                raise KeyError(name)
        return np.array(row, dtype=float)

    def step(self, t: float, h: float, u) -> np.ndarray:
        self.plant.set_force(u[:6])
        if self.model.drive is not None:
            self.plant.set_torque(u[6:12] if len(u) > 6 else np.zeros(6))
        self.plant.do_step(t, h)
        return self.outputs()

    def run(self, times, steps, inputs) -> np.ndarray:
        return np.array([self.step(t, h, u) for t, h, u in zip(times, steps, inputs)])


def hold_forces(model: Model) -> np.ndarray:
    return inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))


def drive_inputs(model: Model, times, seed: int = 0, rel: float = 0.02) -> np.ndarray:
    """Rows of sigma (hold + sinusoids) and, with a drive, tau (sinusoids adding rel of the hold
    force at the rack): varying torque and force inputs."""
    rng = np.random.default_rng(seed)
    t = np.asarray(times)[:, None]
    hold = hold_forces(model)
    scale = np.abs(hold).max()
    sigma = hold + rel * scale * rng.uniform(0.5, 1.0, 6) * np.sin(2 * np.pi * rng.uniform(5, 20, 6) * t
                                                                    + rng.uniform(0, 6.3, 6))
    if model.drive is None:
        return sigma
    gain = model.drive.gear_ratio / model.drive.pinion_radius
    tau = rel * scale / gain * rng.uniform(0.5, 1.0, 6) * np.sin(2 * np.pi * rng.uniform(5, 20, 6) * t
                                                                 + rng.uniform(0, 6.3, 6))
    return np.hstack([sigma, tau])


def grid(n: int, h: float = H):
    t = np.arange(n + 1) * h
    return t[:-1].tolist(), np.diff(t).tolist()


def residual(b: Built, actual, expected, names=None) -> float:
    names = b.outputs if names is None else names
    units = [b.unit(n) for n in names]
    actual, expected = np.atleast_2d(actual), np.atleast_2d(expected)
    assert actual.shape == expected.shape
    assert np.all(np.isfinite(actual)) and np.all(np.isfinite(expected))
    worst = 0.0
    for unit in set(units):
        cols = [k for k, u in enumerate(units) if u == unit]
        scale = max(float(np.abs(expected[:, cols]).max()), 1e-300)
        worst = max(worst, float(np.abs(actual[:, cols] - expected[:, cols]).max()) / scale)
    return worst


def agree(name: str, worst: float, tol: float = RTOL) -> None:
    record(f"native fmu: {name}", worst, tol)
    assert worst <= tol, f"{name}: {worst:.3e} > {tol:.0e}"


CASES = [(name, v) for name in SCENES for v in (2, 3)]
IDS = [f"{name}-fmi{v}" for name, v in CASES]


# --- 1. the archive: self-contained, valid, the scene's values ------------------------------------

@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_fmpy_validate_finds_nothing_and_parameters_are_the_scene(fmus, case):
    b = fmus[case]
    assert validate_fmu(str(b.path)) == []
    cs = b.md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and cs.canHandleVariableCommunicationStepSize
    assert not cs.needsExecutionTool
    expected = {v.name: v for v in V.variables(b.model, b.version)}
    assert [v.name for v in b.md.modelVariables] == list(expected)
    for var in b.md.modelVariables:
        want = expected[var.name]
        assert var.valueReference == want.vr and var.causality == want.causality, var.name
        assert var.description, var.name
        assert tuple(var.shape or ()) == want.shape, var.name   # FMI 3.0: <Dimension>s, FMI 2.0 scalars
    # every number of the scene's plant tables is a fixed parameter with the scene's value
    for dotted in V.SCENE_KEYS:
        value = V.lookup(b.data, dotted)
        if value is None:
            continue
        arr = np.asarray(value, dtype=float)
        for idx in np.ndindex(arr.shape):
            name = dotted + (f"[{','.join(str(i + 1) for i in idx)}]" if idx else "")
            var = b.elements.variable[name]
            assert var.variability == "fixed" and var.causality == "parameter"
            assert b.elements.start[b.vr[name]] == float(arr[idx]), name
            assert var.unit or dotted == "geometry.home"
    assert ("tau[1]" in b.vr) == ("drive" in b.data)


@pytest.mark.parametrize("version", [2, 3])
def test_binary_needs_only_libc_and_libm(fmus, version):
    """No libpython (nor anything else) in the binary's dependencies; only fmi* symbols exported;
    every source the description lists is in the archive."""
    b = fmus[("micro", version)]
    needed = subprocess.run(["readelf", "-d", str(b.binary)], capture_output=True, text=True,
                            check=True).stdout
    libs = sorted(line.split("[")[1].split("]")[0] for line in needed.splitlines() if "(NEEDED)" in line)
    assert set(libs) <= {"libm.so.6", "libc.so.6"}, libs
    assert "python" not in needed.lower()
    if shutil.which("ldd"):
        assert "python" not in subprocess.run(["ldd", str(b.binary)], capture_output=True, text=True).stdout
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(b.binary)], capture_output=True, text=True,
                             check=True).stdout.split()
    exported = [s for s in symbols if s[:1].isalpha() and len(s) > 1 and not s.isupper()]
    prefix = f"fmi{version}"
    assert exported and all(s.startswith(prefix) for s in exported), exported
    names = zipfile.ZipFile(b.path).namelist()
    root = ElementTree.fromstring(zipfile.ZipFile(b.path).read("modelDescription.xml"))
    if version == 2:
        listed = [f.get("name") for f in root.iter("File")]
    else:
        bd = ElementTree.fromstring(zipfile.ZipFile(b.path).read("sources/buildDescription.xml"))
        listed = [f.get("name") for f in bd.iter("SourceFile")]
    assert listed and all(f"sources/{name}" in names for name in listed)
    # resources/ holds only the scene as exported (run --fmu checks it); the binary reads nothing
    assert [x for x in names if x.startswith("resources/")] == ["resources/scene.toml"]


@pytest.mark.parametrize("version", [2, 3])
def test_sources_rebuild_warning_free(fmus, version, tmp_path):
    """The FMU's sources/ compile on their own (the file list only, no include flags) without a
    warning at -Wall -Wextra -Wpedantic, into a binary that runs like the shipped one."""
    b = fmus[("micro", version)]
    src = b.unzipdir / "sources"
    root = ElementTree.fromstring((b.unzipdir / "modelDescription.xml").read_bytes())
    listed = ([f.get("name") for f in root.iter("File")] if version == 2 else
              [f.get("name") for f in ElementTree.fromstring((src / "buildDescription.xml").read_bytes())
               .iter("SourceFile")])
    out = tmp_path / "rebuilt.so"
    proc = subprocess.run(["cc", "-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared",
                           "-fvisibility=hidden", "-Wall", "-Wextra", "-Wpedantic", "-o", str(out),
                           *[str(src / f) for f in listed], "-lm"], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


@pytest.mark.parametrize("version", [2, 3])
def test_start_values_read_through_fmi(fmus, version):
    """getReal of every parameter in initialization mode returns its start value (the C table
    and the model description agree on value references)."""
    b = fmus[("sim", version)]
    s = Slave(b)
    try:
        if version == 2:
            s.fmu.setupExperiment(startTime=0.0)
            s.fmu.enterInitializationMode()
        else:
            s.fmu.enterInitializationMode(startTime=0.0)
        params = [n for n, v in b.elements.variable.items() if v.causality == "parameter" and v.type != "String"]
        got = s.get(params)
        assert got.tolist() == [b.elements.start[b.vr[n]] for n in params]
        assert s.fmu.getString([b.vr["solver.method"]]) == [b"rk4"] or \
            s.fmu.getString([b.vr["solver.method"]]) == ["rk4"]
    finally:
        s.fmu.freeInstance()


# --- 2. against the in-process Plant -----------------------------------------------------------------

@pytest.fixture(scope="module")
def master(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("master") / "fmi_master"
    subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-I", str(FMI_INCLUDE), "-o", str(exe),
                    str(HERE / "fmi_master.c"), "-ldl"], check=True)
    return exe


def write_script(path: Path, n: int, h: float, in_vr, out_vr, rows, n_out: int) -> Path:
    """fmi_master's script: the input and output value references, each line led by the number
    of values they hold (FMI 3.0 arrays: more than references) and the number of references."""
    n_in = len(rows[0])
    lines = [f"{n} {h!r}", " ".join(map(str, [n_in, len(in_vr), *in_vr])),
             " ".join(map(str, [n_out, len(out_vr), *out_vr]))]
    lines += [" ".join(repr(float(x)) for x in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("version", [2, 3])
def test_c_master_matches_plant(fmus, master, version, tmp_path):
    """A C master (dlopen, instantiate, set inputs, 100 steps, get outputs) against the Plant."""
    b = fmus[("micro", version)]
    n = 100
    times, steps = grid(n)
    u = drive_inputs(b.model, times, seed=1)
    in_vr, out_vr = (b.input_vrs, b.output_vrs) if version == 3 else \
        ([b.vr[f"sigma[{i}]"] for i in range(1, 7)] + [b.vr[f"tau[{i}]"] for i in range(1, 7)],
         [b.vr[x] for x in b.outputs])
    script = write_script(tmp_path / "script.txt", n, H, in_vr, out_vr, u, len(b.outputs))
    proc = subprocess.run([str(master), "run", str(version), str(b.binary), b.token, str(script)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    rows = np.array([[float(x) for x in line.split()] for line in proc.stdout.splitlines()])
    assert rows.shape == (n, 2 + len(b.outputs)) and np.all(rows[:, 1] == 0)
    ref = Reference(b.model, b.outputs).run(times, steps, u)
    agree(f"C master FMI {version} vs Plant", residual(b, rows[:, 2:], ref))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_step_by_step_matches_plant(fmus, case):
    """300 steps with varying rack forces and motor torques: every output at every step."""
    b = fmus[case]
    n = 300
    times, steps = grid(n)
    u = drive_inputs(b.model, times, seed=2)
    s = Slave(b).init()
    try:
        first = s.outputs()
        got = s.run(times, steps, u)
    finally:
        s.close()
    ref = Reference(b.model, b.outputs)
    agree(f"t = 0 outputs [{case}]", residual(b, first[None], ref.outputs()[None]))
    want = ref.run(times, steps, u)
    agree(f"step by step vs Plant [{case}]", residual(b, got, want))
    lengths = [k for k, name in enumerate(b.outputs) if name.startswith("l[")]
    assert np.ptp(got[:, lengths], axis=0).max() > 1e-7 * b.model.leg_max   # it moved


def test_compliant_transmission_matches_plant(tmp_path):
    """A scene with a [transmission] (24 states, preloaded at exitInitializationMode)."""
    b = _build(COMPLIANT, 2, tmp_path)
    n = 100
    times, steps = grid(n)
    u = drive_inputs(b.model, times, seed=3)
    opts = IntegratorOptions(max_step=2e-5)
    s = Slave(b).init(reals={"solver.max_step": opts.max_step}, init_reals={"sigma[1]": u[0][0]})
    try:
        got = s.run(times, steps, u)
    finally:
        s.close()
    ref = Reference.__new__(Reference)   # initialized by hand: the preload set in initialization
    ref.model, ref.names = b.model, b.outputs
    ref.plant = Plant(b.model, opts)
    ref.plant.setup_experiment(0.0)
    ref.plant.enter_initialization_mode()
    ref.plant.set_force(np.r_[u[0][0], hold_forces(b.model)[1:]])   # the others at their start
    ref.plant.exit_initialization_mode()
    agree("compliant transmission vs Plant", residual(b, got, ref.run(times, steps, u)))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_simulate_fmu_matches_plant(fmus, case):
    """fmpy.simulate_fmu, 0.2 s at 1 ms, sigma = hold + sinusoids sampled on fmpy's grid."""
    b = fmus[case]
    n = 200
    t = np.arange(n + 1) * H
    u = drive_inputs(b.model, t, seed=4)
    groups = ["sigma"] + (["tau"] if u.shape[1] > 6 else [])
    if b.version == 2:
        names = [f"{g}[{i}]" for g in groups for i in range(1, 7)]
        signal = np.array([(tk, *row) for tk, row in zip(t, u)], dtype=[("time", np.float64)] + [(x, np.float64) for x in names])
    else:   # the input arrays as fmpy takes them: one field of shape (6,) each
        signal = np.array([(tk, *row.reshape(-1, 6)) for tk, row in zip(t, u)],
                          dtype=[("time", np.float64)] + [(g, np.float64, (6,)) for g in groups])
    outputs = [v.name for v in b.md.modelVariables if v.causality == "output"]
    res = simulate_fmu(str(b.path), start_time=0.0, stop_time=n * H, output_interval=H, input=signal,
                       output=outputs)
    assert np.array_equal(res["time"], t)
    got = np.column_stack([res[name] for name in outputs])   # an array's column: its elements
    ref = Reference(b.model, b.outputs)
    rows = ref.run(t[:-1].tolist(), np.diff(t).tolist(), u[:-1])
    agree(f"simulate_fmu vs Plant [{case}]", residual(b, got[1:], rows))


def test_libcosim_runs_the_fmi2_fmu(fmus):
    """libcosimpy (DNV libcosim) runs the 2.0 FMU 100 steps at 1 ms; l[1..6] and z equal the Plant's."""
    try:
        from libcosimpy._internal import get_last_error_message
        from libcosimpy.CosimEnums import CosimErrorCode
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except (ImportError, OSError) as exc:
        pytest.skip(f"libcosimpy cannot be loaded here: {exc!r}")
    b = fmus[("micro", 2)]
    sigma = hold_forces(b.model) + np.array([0.3, -0.1, 0.2, 0.0, -0.2, 0.1])
    n, step_ns = 100, 1_000_000
    execution = CosimExecution.from_step_size(step_ns)
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(b.path), instance_name="plant"))
    assert index >= 0, get_last_error_message()
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    observer = CosimObserver.create_last_value()
    manipulator = CosimManipulator.create_override()
    assert execution.add_observer(observer) and execution.add_manipulator(manipulator)
    assert manipulator.slave_real_values(index, [refs[f"sigma[{i}]"] for i in range(1, 7)], sigma.tolist())
    assert execution.step(n), get_last_error_message()
    status = execution.status()
    assert status.current_time == n * step_ns
    assert CosimErrorCode(status.error_code) == CosimErrorCode.SUCCESS
    names = [f"l[{i}]" for i in range(1, 7)] + ["z"]
    got = np.array(observer.last_real_values(index, [refs[name] for name in names]))
    t = [k * step_ns / 1e9 for k in range(n + 1)]
    ref = Reference(b.model, names)
    for k in range(n):
        ref.step(t[k], t[k + 1] - t[k], sigma)
    want = ref.outputs()
    assert abs(want[6] - b.model.home[2]) > 1e-6
    agree("libcosim l[1..6], z vs Plant", float(np.max(np.abs(got - want)) / np.abs(want).max()))


class ArrayPlant:
    """A PlantPort (controller.plants) on the FMI 3.0 FMU through its arrays alone: q0, qd0, tau
    and sigma set as 4 value references holding 24 values, l, ldot and q read as 3 holding 18."""

    def __init__(self, b: Built):
        from fmpy.fmi3 import FMU3Slave

        self.vr = b.vr
        self.fmu = FMU3Slave(guid=b.token, unzipDirectory=str(b.unzipdir), modelIdentifier="StewartPlant",
                             instanceName="arrays")

    def start(self, q0, qd0, t0, torque0) -> None:
        f, vr = self.fmu, self.vr
        f.instantiate()
        f.enterInitializationMode(startTime=t0)
        # as controller.plants.FmuPlant: the torques drive, the rack-force inputs are zeroed
        f.setFloat64([vr["q0"], vr["qd0"], vr["tau"], vr["sigma"]],
                     [float(x) for x in (*q0, *qd0, *torque0)] + [0.0] * 6)
        f.exitInitializationMode()

    def step(self, t, h, torque) -> None:
        self.fmu.setFloat64([self.vr["tau"]], [float(x) for x in torque])
        self.fmu.doStep(t, h)

    def measure(self):
        v = np.array(self.fmu.getFloat64([self.vr["l"], self.vr["ldot"], self.vr["q"]], 18))
        return v[:6], v[6:12], v[12:]

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def test_closed_loop_through_fmi3_arrays_equals_fmi2_scalars_and_plant(fmus):
    """The per-axis controllers around the FMI 3.0 FMU driven through its arrays only, around
    the FMI 2.0 FMU through its scalars (controller.plants.FmuPlant) and around the in-process
    plant (the compiled loop): 200 steps of a 1 cm, 0.1 rad quintic, every signal of the three
    runs equal bit for bit."""
    from controller.config import controller_config
    from controller.cosim import run_closed_loop
    from controller.plants import FmuPlant
    from controller.trajectory import quintic

    b3, b2 = fmus[("micro", 3)], fmus[("micro", 2)]
    model = b3.model
    config = controller_config(model)
    traj = quintic(model.home, model.home + np.array([0.01, 0, 0, 0, 0, 0.1]), rate=config.rate, duration=0.2)
    runs = {"in-process": run_closed_loop(model, config, traj).table}
    for name, plant in (("FMI 2.0 scalars", FmuPlant(b2.path)), ("FMI 3.0 arrays", ArrayPlant(b3))):
        try:
            runs[name] = run_closed_loop(model, config, traj, plant=plant).table
        finally:
            plant.close()
    signals = [n for n in runs["in-process"].dtype.names]
    moved = np.ptp(np.column_stack([runs["in-process"][f"l{i}"] for i in range(1, 7)]), axis=0).max()
    assert moved > 1e-3   # legs travel millimetres
    for name in ("FMI 2.0 scalars", "FMI 3.0 arrays"):
        differ = [n for n in signals if not np.array_equal(runs[name][n], runs["in-process"][n])]
        record(f"native fmu: closed loop through {name} vs in-process, signals differing", len(differ), 0)
        assert differ == [], (name, differ)


def test_fmi3_arrays_read_and_written_through_fmu3slave(fmus):
    """fmpy's FMU3Slave: setFloat64 / getFloat64 with nValues > nValueReferences, an array's
    elements in row-major order (the start of geometry.base_joints as the description lists it,
    a parameter array set whole and read back, sigma and tau set in one call, q = x .. thz and
    qd = dx .. dthz); a count that does not match the arrays, an element's value reference, a
    NULL values array: Error with a logged reason, nothing changed."""
    b = fmus[("micro", 3)]
    s = Slave(b)
    vr, md = b.vr, b.variables
    try:
        s.fmu.enterInitializationMode(startTime=0.0)
        base = s.fmu.getFloat64([vr["geometry.base_joints"]], 18)
        assert base == [float(x) for x in md["geometry.base_joints"].start.split()]
        assert np.array_equal(np.reshape(base, (6, 3)), np.asarray(b.data["geometry"]["base_joints"], float))
        q0 = (b.model.home + np.array([1e-3, -1e-3, 2e-3, 0.01, -0.02, 0.03])).tolist()
        s.fmu.setFloat64([vr["q0"], vr["platform.mass"], vr["qd0"]], q0 + [0.6] + [0.0] * 6)
        assert s.fmu.getFloat64([vr["platform.mass"], vr["q0"]], 7) == [0.6] + q0
        s.fmu.exitInitializationMode()
        u = drive_inputs(b.model, [0.0], seed=12)[0]
        s.fmu.setFloat64([vr["sigma"], vr["tau"]], u.tolist())
        assert s.fmu.getFloat64([vr["tau"], vr["sigma"]], 12) == u[6:].tolist() + u[:6].tolist()
        s.fmu.doStep(0.0, H)
        pose = ["x", "y", "z", "thx", "thy", "thz"]
        names = pose + [f"d{c}" for c in pose]
        arrays = s.fmu.getFloat64([vr["q"], vr["qd"]], 12)
        assert arrays == s.fmu.getFloat64([vr[n] for n in names]) and arrays[:6] != q0
        before = s.outputs()
        bad = {"5 values for sigma": ([vr["sigma"]], 5), "7 values for sigma": ([vr["sigma"]], 7),
               "13 values for sigma, tau": ([vr["sigma"], vr["tau"]], 13),
               "an element's reference": ([vr["sigma"] + 1], 1), "sigma, 1 value": ([vr["sigma"]], 1)}
        for what, (vrs, n) in bad.items():
            for call in ("get", "set"):
                s.messages.clear()
                with pytest.raises(FMICallException) as exc:
                    if call == "get":
                        s.fmu.getFloat64(vrs, n)
                    else:
                        s.fmu.setFloat64(vrs, [1.0] * n)
                assert exc.value.status == ERROR, (what, call)
                assert any(st == ERROR and ("values for" in m or "unknown value reference" in m)
                           for st, _, m in s.messages), (what, call, s.messages)
        assert s.fmu.getFloat64([vr["tau"], vr["sigma"]], 12) == u[6:].tolist() + u[:6].tolist()
        assert np.array_equal(s.outputs(), before)
        s.messages.clear()
        with pytest.raises(FMICallException):
            s.fmu.fmi3SetFloat64(s.fmu.component, (ctypes.c_uint32 * 1)(vr["sigma"]), 1, None, 6)
        assert any("NULL" in m for _, _, m in s.messages), s.messages
    finally:
        s.close()


# --- 3. state, reset, parameters --------------------------------------------------------------------

@pytest.mark.parametrize("version", [2, 3])
def test_rollback_and_serialized_state_bit_for_bit(fmus, version):
    b = fmus[("micro", version)]
    times, steps = grid(40)
    u = drive_inputs(b.model, times, seed=5)
    s, other = Slave(b, "first").init(), Slave(b, "second")   # the second only instantiated
    try:
        s.run(times[:15], steps[:15], u[:15])
        at_state = s.outputs()
        state = s.get_state()
        blob = s.serialize(state)
        first = s.run(times[15:], steps[15:], u[15:])
        for _ in range(3):
            s.set_state(state)
            assert np.array_equal(s.outputs(), at_state)
            assert np.array_equal(s.run(times[15:], steps[15:], u[15:]), first)
        s.free_state(state)
        restored = other.deserialize(blob)
        other.set_state(restored)
        other.free_state(restored)
        assert np.array_equal(other.outputs(), at_state)
        assert np.array_equal(other.run(times[15:], steps[15:], u[15:]), first)
    finally:
        s.close()
        other.close()
    ref = Reference(b.model, b.outputs)
    ref.run(times[:15], steps[:15], u[:15])
    agree(f"rollback run vs Plant FMI {version}", residual(b, first, ref.run(times[15:], steps[15:], u[15:])))


@pytest.mark.parametrize("version", [2, 3])
def test_reset_then_rerun_equals_first_run(fmus, version):
    b = fmus[("micro", version)]
    times, steps = grid(30)
    u = drive_inputs(b.model, times, seed=6)
    s = Slave(b).init(reals={"platform.mass": 0.7})
    try:
        home = s.outputs()
        first = s.run(times, steps, u)
        s.fmu.reset()
        s.init(init_reals={"platform.mass": 0.7})        # set in initialization mode this time
        assert np.array_equal(s.outputs(), home)
        again = s.run(times, steps, u)
    finally:
        s.close()
    assert np.array_equal(first, again) and not np.array_equal(first[-1], home)
    s = Slave(b)
    try:
        s.init(reals={"platform.mass": 0.7, "sigma[1]": 1.0})
        s.fmu.reset()                                     # every value back to its start value
        s.init()
        assert s.get(["platform.mass", "sigma[1]"]).tolist() == [0.5, hold_forces(b.model)[0]]
    finally:
        s.close()


@pytest.mark.parametrize("version", [2, 3])
def test_parameter_overrides_equal_the_plant_built_with_them(fmus, version):
    """platform.mass, a base-joint element, drive.gear_ratio, solver.method = dopri5 and q0 set
    before exitInitializationMode give the Plant of the overridden scene."""
    b = fmus[("micro", version)]
    times, steps = grid(60)
    base = [list(p) for p in b.data["geometry"]["base_joints"]]
    base[0][2] = 0.002
    overrides = {"platform.mass": 0.6, "geometry.base_joints": base, "drive.gear_ratio": 25.0}
    model = scene_from_dict(apply_overrides(b.data, overrides))
    q0 = model.home + np.array([0.001, -0.001, 0.002, 0.01, -0.02, 0.03])
    u = drive_inputs(model, times, seed=7)
    s = Slave(b).init(reals={"platform.mass": 0.6, "geometry.base_joints[1,3]": 0.002, "drive.gear_ratio": 25.0},
                      method="dopri5", init_reals={f"q0[{k + 1}]": q0[k] for k in range(6)})
    try:
        got = s.run(times, steps, u)
    finally:
        s.close()
    ref = Reference(model, b.outputs, IntegratorOptions(method="dopri5"), q0=q0)
    agree(f"overrides + dopri5 vs Plant FMI {version}", residual(b, got, ref.run(times, steps, u)))


@pytest.mark.parametrize("version", [2, 3])
def test_two_instances_and_variable_steps(fmus, version):
    """Two instances stepped in turn with different inputs and steps of 1, 0.3 and 2.5 ms
    (communication points accumulated as a master does) each equal their own Plant."""
    b = fmus[("micro", version)]
    steps = [1e-3, 0.3e-3, 2.5e-3] * 20
    times = [0.0]
    for h in steps[:-1]:
        times.append(times[-1] + h)
    ua, ub = drive_inputs(b.model, times, seed=10), drive_inputs(b.model, times, seed=11, rel=0.04)
    a, c = Slave(b, "a").init(), Slave(b, "b").init()
    try:
        rows_a, rows_b = [], []
        for t, h, xa, xb in zip(times, steps, ua, ub):
            rows_a.append(a.step(t, h, xa))
            rows_b.append(c.step(t, h, xb))
    finally:
        a.close()
        c.close()
    for name, rows, u in (("a", rows_a, ua), ("b", rows_b, ub)):
        agree(f"two instances, variable steps: {name} FMI {version}",
              residual(b, np.array(rows), Reference(b.model, b.outputs).run(times, steps, u)))
    assert residual(b, np.array(rows_a), np.array(rows_b)) > 1e-6


# --- 4. errors and discards ---------------------------------------------------------------------------

@pytest.mark.parametrize("version", [2, 3])
def test_discard_keeps_the_state_and_huge_step_returns_promptly(fmus, version):
    b = fmus[("micro", version)]
    hold = hold_forces(b.model)
    zero = np.zeros(6)
    for method in ("rk4", "dopri5"):
        s = Slave(b).init(method=method)
        try:
            s.step(0.0, H, np.r_[hold, zero])
            before = s.outputs()
            for h, u in ((1e300, np.r_[hold, zero]), (0.05, np.r_[hold + 5e6, zero])):
                start = time.perf_counter()
                with pytest.raises(FMICallException) as exc:
                    s.step(H, h, u)
                assert exc.value.status == DISCARD
                assert time.perf_counter() - start < 2.0
                assert np.array_equal(s.get([x for x in b.outputs if not x.startswith(("rack", "force"))]),
                                      before[[k for k, x in enumerate(b.outputs) if not x.startswith(("rack", "force"))]])
            assert any(st == DISCARD and "discarded" in m for st, _, m in s.messages), s.messages
            s.step(H, H, np.r_[hold, zero])     # recovers from the same point
        finally:
            s.close()


_SIMULATE_DISCARD = r"""
import sys, numpy as np
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
path, k_bad, hold, version = sys.argv[1], int(sys.argv[2]), [float(x) for x in sys.argv[3:9]], int(sys.argv[9])
n, h = 50, 1e-3
t = np.arange(n + 1) * h
sig = np.tile(hold, (n + 1, 1))
sig[k_bad:] += 5e6
rows = [(tk, *s) for tk, s in zip(t, sig)]
rows.insert(k_bad, (t[k_bad], *sig[k_bad - 1]))   # a step change at t_k: fmpy applies the right one
if version == 2:
    signal = np.array(rows, dtype=[("time", float)] + [(f"sigma[{i}]", float) for i in range(1, 7)])
else:   # FMI 3.0: sigma is one array
    signal = np.array([(r[0], r[1:]) for r in rows], dtype=[("time", float), ("sigma", float, (6,))])
try:
    res = simulate_fmu(path, stop_time=n * h, output_interval=h, input=signal, output=["z"])
    print("ENDED", repr(float(res["time"][-1])), len(res))
except FMICallException as exc:
    print("RAISED", exc.status)
"""


@pytest.mark.parametrize("version", [2, 3])
def test_simulate_fmu_stops_at_a_discard(fmus, version):
    """fmpy.simulate_fmu driving a step into the stroke: with FMI 2.0 the FMU reports
    fmi2Terminated after the discard and the run ends at the last successful time (fmpy would
    otherwise retry the same step forever); with FMI 3.0 fmpy raises on the Discard."""
    b = fmus[("micro", version)]
    k_bad = 20
    proc = subprocess.run([sys.executable, "-c", _SIMULATE_DISCARD, str(b.path), str(k_bad),
                           *map(repr, hold_forces(b.model).tolist()), str(version)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    if version == 2:
        line = [ln for ln in proc.stdout.splitlines() if ln.startswith("ENDED")]
        assert line, proc.stdout[-2000:]
        end, length = float(line[0].split()[1]), int(line[0].split()[2])
        assert end == pytest.approx(k_bad * H, abs=1e-15) and length < 51
    else:
        assert f"RAISED {DISCARD}" in proc.stdout, proc.stdout


_ERROR_CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from native_fmu_child import calls_expected_to_fail
unzipdir, version = sys.argv[2], int(sys.argv[3])
print("RESULT " + json.dumps(calls_expected_to_fail(unzipdir, version)), flush=True)
"""


@pytest.mark.parametrize("version", [2, 3])
def test_bad_calls_return_error_and_change_nothing(fmus, version):
    """Out-of-order calls, unknown value references, writes to outputs, NaN/inf inputs and
    parameters, bad steps, wrong types, foreign and corrupted states, an invalid parameter at
    exitInitializationMode (logged naming it), a '%' in a logged value: each returns Error and
    the instance carries on; run in a child process."""
    b = fmus[("micro", version)]
    proc = subprocess.run([sys.executable, "-c", _ERROR_CHILD, str(HERE), str(b.unzipdir), str(version)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads([ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")][-1][7:])
    wrong = {k: v for k, v in result["status"].items() if v != ERROR}
    assert not wrong, (wrong, result["messages"][-20:])
    assert result["unchanged"], result
    assert result["recovered"] == 0
    messages = " | ".join(m for _, _, m in result["messages"])
    assert "platform.mass must be > 0, got -0.5" in messages
    assert "integrator 'rk4%s%n' unknown" in messages
    assert "not allowed in" in messages and "unknown value reference" in messages
    assert "input tau[1] = 1e+308 at t = 0.001 s is outside its declared range [-1e+06, 1e+06]" in messages


@pytest.mark.parametrize("version", [2, 3])
def test_inputs_declare_the_range_the_fmu_enforces(fmus, version):
    """sigma and tau declare min and max (the table's STEWART_FMU_INPUT_RANGES, read once by
    both the model description and the C code): the fuzz and the bad-calls test check that a
    value outside them is refused; the start values lie inside. Each bounded parameter declares
    its physical bounds (the scene table's, which exitInitializationMode applies); outputs and
    unbounded parameters declare none."""
    b = fmus[("micro", version)]
    ranges = table.INPUT_RANGES
    groups = {g.name: g for g in table.VARIABLES}
    bounded = 0
    for var in b.md.modelVariables:
        if var.causality == "input":
            lo, hi = ranges["SIGMA" if var.name.startswith("sigma") else "TAU"]
            assert (float(var.min), float(var.max)) == (lo, hi), var.name
            assert all(lo <= float(x) <= hi for x in str(var.start).split())
            continue
        g = groups.get(var.name.partition("[")[0])
        if var.causality == "parameter" and g is not None and g.bound != table.BOUND_ANY:
            assert (float(var.min), float(var.max)) == (g.min, g.max), var.name
            assert all(g.min <= float(x) <= g.max for x in str(var.start).split()), var.name
            bounded += 1
        else:
            assert var.min is None and var.max is None, var.name
    assert bounded >= 10
    assert ranges == {"SIGMA": (-1e7, 1e7), "TAU": (-1e6, 1e6)}


def test_a_hold_force_beyond_the_input_range_is_a_scene_error(fmus):
    """sigma starts at the force holding home, which must lie in sigma's declared range: a
    platform too heavy for it is refused naming platform.mass, before anything is built."""
    b = fmus[("micro", 2)]
    # within the scene's own bounds (mass <= 1e6 kg, |g| <= 1e3 m/s^2), 1.9e8 N a leg at home
    model = scene_from_dict(apply_overrides(b.data, {"platform.mass": 1e6, "gravity": [0.0, 0.0, -1e3]}))
    with pytest.raises(SceneError) as err:
        V.variables(model, 2)
    assert err.value.key == "platform.mass" and "outside the FMU's input range" in str(err.value)


_FORGED_CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from native_fmu_child import forged_states
print("RESULT " + json.dumps(forged_states(sys.argv[2], int(sys.argv[3]), json.loads(sys.argv[4]))), flush=True)
"""


@pytest.mark.parametrize("version", [2, 3])
def test_forged_states_are_refused(fmus, version):
    """A serialized state's checksum detects corruption, not forgery: a state edited with its
    checksum recomputed is validated field by field before it is applied, and refused (Error,
    logged naming the field) when a field is not finite, out of its bounds or inconsistent:
    NaN forces, y[0] = 1e300, a NaN tolerance, ... The unedited state, resealed, loads."""
    from stewart_fmu.native.core import ffi
    comp = lambda f: ffi.offsetof("stewart_component", f)   # noqa: E731
    tail = ffi.sizeof("stewart_component")   # then PlantData's own fields (fmi/model.h): method,
    par = lambda vr: tail + 16 + 8 * vr      # noqa: E731  tolerance_defined, tolerance, par[]
    nan = float("nan")
    edits = {
        "NaN force sigma[1]": [(comp("sigma"), "d", nan)],
        "tau[1] = 1e308": [(comp("tau"), "d", 1e308)],
        "sigma[2] beyond its range": [(comp("sigma") + 8, "d", 1.5e7)],
        "y[0] = 1e300": [(comp("y"), "d", 1e300)],
        "z outside the stroke": [(comp("y") + 16, "d", 5.0)],
        "NaN tolerance": [(tail + 4, "i", 1), (tail + 8, "d", nan)],
        "negative tolerance": [(tail + 4, "i", 1), (tail + 8, "d", -1e-6)],
        "tolerance without tolerance_defined": [(tail + 8, "d", 1e-6)],
        "time before the start": [(comp("time"), "d", -1.0)],
        "infinite time": [(comp("time"), "d", float("inf"))],
        "zero internal step": [(comp("step_guess"), "d", 0.0)],
        "NaN internal step": [(comp("step_guess"), "d", nan)],
        "negative evaluations": [(comp("evaluations"), "q", -5)],
        "phase 9": [(comp("phase"), "i", 9)],
        "state size 13": [(comp("n"), "i", 13)],
        "method 7": [(tail, "i", 7)],
        "NaN platform.mass": [(par(V.table.vr("MASS")), "d", nan)],
        "negative platform.mass": [(par(V.table.vr("MASS")), "d", -1.0)],
        "q0 not the initial pose": [(par(V.VR_Q0), "d", 1e-3)],
    }
    b = fmus[("micro", version)]
    proc = subprocess.run([sys.executable, "-c", _FORGED_CHILD, str(HERE), str(b.unzipdir), str(version),
                           json.dumps(edits)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads([ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")][-1][7:])
    assert result.pop("unedited") == {"status": 0, "applied": 0, "messages": []}
    loaded = {k: r for k, r in result.items() if r["status"] != ERROR}
    assert not loaded, loaded
    # refused by the serialized form's own check (the component's fields) or the FMU's, each logged
    assert all(any(m.startswith("deserializeFMUstate: not a ") for m in r["messages"]) for r in result.values())
    why = {k: " ".join(r["messages"]) for k, r in result.items()}
    assert "out of range or not finite" in why["NaN force sigma[1]"]
    assert "parameter platform.mass = nan is not finite" in why["NaN platform.mass"]
    assert "input tau[1] = 1e+308 lies outside its declared range" in why["tau[1] = 1e308"]
    assert "outside the workspace" in why["y[0] = 1e300"] and "outside the workspace" in why["z outside the stroke"]
    assert "the tolerance nan" in why["NaN tolerance"]
    assert "initial values are not q0" in why["q0 not the initial pose"]


FUZZ_SEEDS, FUZZ_CALLS = 4, 2500   # per FMI version: at least 10,000 calls (each action one or more)


@pytest.mark.parametrize("version", [2, 3])
def test_fuzz_random_call_sequences(fmus, version):
    """Over 10,000 seeded random FMI calls per version, in child processes: hostile inputs
    (NaN, inf, 1e308, denormals, just outside the declared range), steps of every size (zero,
    negative, NaN, 1e308), calls out of order, unknown value references, huge nValues, foreign,
    truncated and forged states (edited with their checksum recomputed). No crash; every call
    that must fail returns Error; no getReal answers OK with a NaN or an infinity; the FMU's own
    states always load."""
    b = fmus[("micro", version)]
    script = (f"import json, sys; sys.path.insert(0, {str(HERE)!r}); from native_fmu_child import fuzz; "
              f"print('RESULT ' + json.dumps(fuzz({str(b.unzipdir)!r}, {version}, int(sys.argv[1]), {FUZZ_CALLS})), "
              "flush=True)")
    counts = ("calls", "must_fail", "errors_returned", "discards", "steps_ok", "other_errors", "gets_ok",
              "values_read", "forged", "forged_loaded")
    lists = ("not_error", "nonfinite_ok", "refused_own_state")
    totals = {**{k: 0 for k in counts}, **{k: [] for k in lists}, "crashes": 0}
    for seed in range(FUZZ_SEEDS):
        proc = subprocess.run([sys.executable, "-c", script, str(seed)], capture_output=True, text=True, timeout=300)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        if proc.returncode != 0 or not lines:
            totals["crashes"] += 1
            continue
        r = json.loads(lines[-1][7:])
        for k in counts + lists:
            totals[k] += r[k]
    record(f"native fmu: fuzz FMI {version} calls={totals['calls']} must_fail={totals['must_fail']} "
           f"errors={totals['errors_returned']} discards={totals['discards']} values read={totals['values_read']} "
           f"forged states={totals['forged']} (loaded {totals['forged_loaded']})",
           totals["crashes"] + len(totals["nonfinite_ok"]), 0)
    print(f"fuzz FMI {version}: {totals}")
    assert totals["crashes"] == 0
    assert totals["calls"] >= 10_000
    assert totals["not_error"] == [] and totals["errors_returned"] == totals["must_fail"] > 2000
    assert totals["nonfinite_ok"] == [] and totals["values_read"] > 10_000
    assert totals["refused_own_state"] == []
    assert totals["forged"] > 300 and totals["forged_loaded"] > 0   # forged edits both refused and harmless
    assert totals["steps_ok"] > 200 and totals["discards"] > 20   # the plant really stepped and refused


@pytest.mark.skipif(shutil.which("cmake") is None, reason="fmpy.build needs cmake")
def test_fmpy_rebuilds_the_binary_from_sources(fmus, tmp_path):
    """fmpy.build (cmake, the route to Windows and macOS) rebuilds the FMI 3.0 binary from
    sources/ and buildDescription.xml alone; it simulates like the shipped binary."""
    from fmpy.build import build_platform_binary

    b = fmus[("micro", 3)]
    unzip = Path(extract(str(b.path), str(tmp_path / "rebuilt")))
    shutil.rmtree(unzip / "binaries")
    build_platform_binary(unzip)
    assert (unzip / "binaries" / "x86_64-linux" / "StewartPlant.so").exists()
    outputs = [v.name for v in b.md.modelVariables if v.causality == "output"]
    run = lambda where: simulate_fmu(str(where), stop_time=0.05, output_interval=H,  # noqa: E731
                                     start_values={"sigma": [1.0] * 6}, output=outputs)
    got, want = run(unzip), run(b.unzipdir)
    rows = lambda r: np.column_stack([r[n] for n in outputs])  # noqa: E731
    agree("fmpy.build binary vs shipped", residual(b, rows(got), rows(want)))


# --- 5. export ----------------------------------------------------------------------------------------

def test_platform_only_scene_declares_only_what_it_has(tmp_path, fmus):
    """A scene with only [geometry] and [platform]: no legs/drive/friction parameters, no tau,
    force parts platform and gravity only; those value references are unknown to the binary;
    and it simulates like the Plant."""
    data = fmus[("micro", 2)].data
    geo = data["geometry"]
    lines = ['name = "platform-only"', "", "[geometry]"]
    lines += [f"{key} = {geo[key]}" for key in ("base_joints", "platform_joints", "home", "leg_min", "leg_max")]
    lines += ["", "[platform]", f"mass = {data['platform']['mass']}", f"inertia = {data['platform']['inertia']}"]
    scene = tmp_path / "platform_only.toml"
    scene.write_text("\n".join(lines) + "\n")
    for version in (2, 3):
        b = _build(scene, version, tmp_path)
        assert validate_fmu(str(b.path)) == []
        names = set(b.vr)                               # variables and their elements
        assert not [n for n in names if n.startswith(("legs.", "drive.", "friction.", "tau["))]
        assert {n.split("[")[0] for n in names if n.startswith("force.")} == {"force.platform", "force.gravity"}
        assert "gravity[3]" in names                    # the default gravity is a parameter too
        times, steps = grid(50)
        u = drive_inputs(b.model, times, seed=9)
        s = Slave(b).init()
        try:
            for vr in (V.SCENE_KEYS["legs.lower_mass"][0], V.SCENE_KEYS["drive.gear_ratio"][0], V.VR_TAU,
                       V.VR_PARTS + 6):                 # declared in other scenes, not in this one
                with pytest.raises(FMICallException) as exc:
                    s.get_vr([vr])
                assert exc.value.status == ERROR
            got = s.run(times, steps, u)
        finally:
            s.close()
        agree(f"platform-only FMI {version} vs Plant", residual(b, got, Reference(b.model, b.outputs).run(times, steps, u)))


def test_export_errors_are_typed(tmp_path, monkeypatch):
    """No compiler: CompilerNotFoundError (no traceback from the compiler call, nothing written);
    a bad scene: its SceneError before anything is built."""
    from stewart_fmu.errors import SceneError
    from stewart_fmu.fmu.export import CompilerNotFoundError

    bad = tmp_path / "bad.toml"
    bad.write_text(SCENES["micro"].read_text().replace("mass = 0.5", "mass = -0.5"))
    with pytest.raises(SceneError, match="platform.mass"):
        export_fmu(bad, tmp_path / "bad.fmu")
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(CompilerNotFoundError, match="no C compiler"):
        export_fmu(SCENES["micro"], tmp_path / "none.fmu")
    assert not (tmp_path / "none.fmu").exists() and not (tmp_path / "bad.fmu").exists()
    with pytest.raises(ValueError):
        export_fmu(SCENES["micro"], tmp_path / "x.fmu", fmi_version=4)
