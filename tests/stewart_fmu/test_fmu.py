"""The exported FMU (stewart_fmu.fmu.export.export_fmu) under real importers: fmpy (validation,
simulate_fmu, the low-level FMU2Slave) and DNV's libcosim (libcosimpy), each checked against
the in-process plant (stewart_fmu.plant.Plant) driven the same way.

Reference runs: the in-process Plant gets the same inputs (held over each step: the FMU applies
its inputs at do_step, zero-order hold), the same communication points and step sizes, and its
outputs are read the way the slave reads them. Trajectory comparisons use RTOL = 1e-10 of the
value scale: |fmu - plant| / scale, where scale is the largest |value| among all outputs of the
same unit over the run (so x, y, z share the 0.1 m scale of the leg lengths); run with
STEWART_RESIDUALS=1 to print the worst residuals. Rollback, serialization and reset are
asserted bit for bit.

The FMU is the native one (C core + C FMI layer). Its error semantics (fmi2Error for a bad
call, state unchanged) and the fuzz are tests/stewart_fmu/test_native_fmu.py's; here, calls of
the wrong variable type run in child processes, so that a crash fails a test instead of ending
the session.
"""
from __future__ import annotations

import gc
import json
import subprocess
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Discard, fmi2Error
from fmpy.validation import validate_fmu

from stewart_fmu import Model, inverse_dynamics, inverse_kinematics, load_scene
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.fmu.variables import outputs as fmu_outputs
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.io import POSE
from stewart_fmu.plant import Plant, StepRejected
from stewart_fmu.stability import default_options
from tests.helpers import fmi2_logging_callbacks, host_binary_only, record

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "scenes").glob("*.toml"))
MICRO = "micro_manipulator"
H = 1e-3            # communication step (s)
RTOL = 1e-10        # trajectory agreement, relative to the value scale of each unit
BASE_UNITS = {"1": {}, "m": {"m": 1}, "rad": {"rad": 1}, "s": {"s": 1}, "kg": {"kg": 1},
              "m/s": {"m": 1, "s": -1}, "rad/s": {"rad": 1, "s": -1}, "m/s2": {"m": 1, "s": -2},
              "kg.m2": {"kg": 1, "m": 2}, "N": {"kg": 1, "m": 1, "s": -2},
              "N.m": {"kg": 1, "m": 2, "s": -2}, "N.s/m": {"kg": 1, "s": -1}}


# --- exported FMUs (one build per scene per module) -------------------------------------------

@dataclass
class Exported:
    """One exported FMU: its file, extracted folder, model description and the scene's Model."""

    scene: Path
    path: Path
    unzipdir: Path
    md: object
    data: dict
    model: Model

    @property
    def variables(self) -> dict:
        return {v.name: v for v in self.md.modelVariables}

    @property
    def output_names(self) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == "output"]


def _export(scene: Path, folder: Path) -> Exported:
    path = export_fmu(scene, folder / f"{scene.stem}.fmu")
    unzipdir = Path(extract(str(path), str(folder / scene.stem)))
    with scene.open("rb") as fh:
        data = tomllib.load(fh)
    return Exported(scene, path, unzipdir, read_model_description(str(path)), data,
                    load_scene(scene))


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, Exported]:
    """Every shipped scene exported once with export_fmu, keyed by the scene file's stem (its
    host binary only: the Windows DLL is tested in test_windows_fmu.py)."""
    folder = tmp_path_factory.mktemp("fmus")
    with host_binary_only():
        return {scene.stem: _export(scene, folder) for scene in SCENES}


@pytest.fixture(scope="module")
def micro(exported) -> Exported:
    return exported[MICRO]


# --- drivers: the FMU through fmpy.FMU2Slave, and the in-process Plant ------------------------



class Slave:
    """An FMU2Slave instance with its own log capture (status, category, message)."""

    def __init__(self, ex: Exported, name: str = "plant"):
        self.ex = ex
        self.vr = {v.name: v.valueReference for v in ex.md.modelVariables}
        self.sigma_vr = [self.vr[f"sigma[{i}]"] for i in range(1, 7)]
        self.out_vr = [self.vr[n] for n in ex.output_names]
        self.messages: list[tuple[int, str, str]] = []

        cb = fmi2_logging_callbacks(lambda *message: self.messages.append(message))
        self.fmu = FMU2Slave(guid=ex.md.guid, unzipDirectory=str(ex.unzipdir),
                             modelIdentifier=ex.md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate(loggingOn=True, callbacks=cb)

    def init(self, reals: dict | None = None, strings: dict | None = None,
             init_reals: dict | None = None, sigma=None) -> "Slave":
        """setupExperiment(0); reals before, strings and init_reals in initialization mode."""
        self.fmu.setupExperiment(startTime=0.0)
        self.set(reals or {})
        self.fmu.enterInitializationMode()
        for name, value in (strings or {}).items():
            self.fmu.setString([self.vr[name]], [value])
        self.set(init_reals or {})
        if sigma is not None:
            self.fmu.setReal(self.sigma_vr, list(sigma))
        self.fmu.exitInitializationMode()
        return self

    def set(self, values: dict) -> None:
        if values:
            self.fmu.setReal([self.vr[n] for n in values], list(values.values()))

    def get(self, names) -> np.ndarray:
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def outputs(self) -> np.ndarray:
        return np.array(self.fmu.getReal(self.out_vr))

    def step(self, t: float, h: float, sigma) -> np.ndarray:
        """setReal(sigma), doStep(t, h), getReal(all outputs)."""
        self.fmu.setReal(self.sigma_vr, list(sigma))
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        return self.outputs()

    def run(self, times, steps, sigmas) -> np.ndarray:
        return np.array([self.step(t, h, s) for t, h, s in zip(times, steps, sigmas)])

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


class Reference:
    """The in-process Plant driven like the FMU, its outputs read the way the slave reads them."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None, q0=None,
                 qd0=None):
        self.model = model
        self.plant = Plant(model, options)  # default: default_options(model), as the FMU
        self.plant.setup_experiment(0.0)
        self.plant.enter_initialization_mode()
        if q0 is not None or qd0 is not None:
            self.plant.set_initial(q0, qd0)
        self.plant.exit_initialization_mode()
        self.vars = fmu_outputs(model)

    def outputs(self) -> np.ndarray:
        """The plant's outputs under the FMU's output names (the FMU's one variable table)."""
        p, o = self.plant, self.plant.outputs
        values = {"cond": o.cond}
        for group, vector in (("l", o.lengths), ("ldot", o.rates), ("rack_force", p.rack_force),
                              *((f"force.{k}", v) for k, v in o.parts.items())):
            values.update({f"{group}[{i + 1}]": vector[i] for i in range(6)})
        for k, c in enumerate(POSE):
            values[c], values[f"d{c}"] = o.q[k], o.qd[k]
        for k in range(3):
            values[f"v[{k + 1}]"], values[f"omega[{k + 1}]"] = o.twist[k], o.twist[3 + k]
        return np.array([values[v.name] for v in self.vars], dtype=float)

    def step(self, t: float, h: float, sigma) -> np.ndarray:
        """What the slave's do_step does: hold sigma (and zero torque with a drive), step."""
        self.plant.set_force(sigma)
        if self.model.drive is not None:
            self.plant.set_torque(np.zeros(6))
        self.plant.do_step(t, h)
        return self.outputs()

    def run(self, times, steps, sigmas) -> np.ndarray:
        return np.array([self.step(t, h, s) for t, h, s in zip(times, steps, sigmas)])


def hold_forces(model: Model) -> np.ndarray:
    """The static forces that hold the platform at home."""
    return inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))


def wiggle(model: Model, times, rel: float = 0.02, seed: int = 0) -> np.ndarray:
    """Hold forces plus small sinusoids (rel of the largest hold force), one row per time."""
    rng = np.random.default_rng(seed)
    hold = hold_forces(model)
    amp = rel * np.abs(hold).max() * rng.uniform(0.5, 1.0, 6)
    freq = rng.uniform(5.0, 20.0, 6)
    phase = rng.uniform(0.0, 2 * np.pi, 6)
    return hold + amp * np.sin(2 * np.pi * freq * np.asarray(times)[:, None] + phase)


def grid(n: int, h: float = H):
    """Communication points k h (k < n) and the step sizes between consecutive points."""
    t = np.arange(n + 1) * h
    return t[:-1].tolist(), np.diff(t).tolist()


def agree(name: str, worst: float, tol: float = RTOL) -> None:
    """Record the residual (STEWART_RESIDUALS=1 prints the table) and check it."""
    record(f"fmu: {name}", worst, tol)
    assert worst <= tol, f"{name}: {worst:.3e} > {tol:.0e}"


def residual(ex: Exported, actual: np.ndarray, expected: np.ndarray, names=None) -> float:
    """max |actual - expected| / scale, scale = largest |expected| among outputs of that unit."""
    names = ex.output_names if names is None else names
    units = [ex.variables[n].unit for n in names]
    actual, expected = np.atleast_2d(actual), np.atleast_2d(expected)
    assert actual.shape == expected.shape
    assert np.all(np.isfinite(actual)) and np.all(np.isfinite(expected))
    worst = 0.0
    for unit in set(units):
        cols = [k for k, u in enumerate(units) if u == unit]
        scale = max(float(np.abs(expected[:, cols]).max()), 1e-300)
        worst = max(worst, float(np.abs(actual[:, cols] - expected[:, cols]).max()) / scale)
    return worst


# --- 1. model description -----------------------------------------------------------------------

def _scene_values(data: dict):
    """(FMU name, value) of every numeric value in a scene dict, found independently."""
    for key, value in data.items():
        if isinstance(value, dict):
            for sub, v in _scene_values(value):
                yield f"{key}.{sub}", v
        elif isinstance(value, list):
            arr = np.asarray(value, dtype=float)
            for idx in np.ndindex(arr.shape):
                yield f"{key}[{','.join(str(i + 1) for i in idx)}]", float(arr[idx])
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            yield key, float(value)


def _check_description(ex: Exported) -> None:
    assert validate_fmu(str(ex.path)) == []
    cs = ex.md.coSimulation
    assert cs.canGetAndSetFMUstate is True
    assert cs.canSerializeFMUstate is True
    assert cs.canHandleVariableCommunicationStepSize is True
    declared = {u.name for u in ex.md.unitDefinitions}
    variables = ex.variables
    # The plant's parameters are the contract's tables; project tables ([controller], ...)
    # configure other components and are not part of the plant FMU.
    plant_tables = {"gravity", "geometry", "platform", "legs", "drive", "friction"}
    values = list(_scene_values({k: v for k, v in ex.data.items() if k in plant_tables}))
    assert len(values) > 0
    for name, value in values:
        assert name in variables, f"scene value {name} is not an FMU variable"
        v = variables[name]
        assert (v.type, v.causality, v.variability) == ("Real", "parameter", "fixed"), name
        assert v.unit and v.unit in declared, f"{name}: unit {v.unit!r}"
        assert v.description, name
        assert float(v.start) == value, f"{name}: start {v.start} != scene {value}"
    for u in ex.md.unitDefinitions:  # SI base-unit exponents, written out here independently
        base = u.baseUnit
        got = {k: getattr(base, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
               if base is not None and getattr(base, k)}
        assert got == BASE_UNITS[u.name], u.name
        assert base is None or (base.factor, base.offset) == (1.0, 0.0), u.name
    # Spot checks of the physical units.
    expect = {"platform.mass": "kg", "platform.inertia[1]": "kg.m2", "geometry.home[3]": "m",
              "geometry.home[4]": "rad", "geometry.base_joints[2,3]": "m", "gravity[3]": "m/s2"}
    for name, unit in expect.items():
        assert variables[name].unit == unit, name
    # The outputs are exactly the ones stewart_fmu.fmu.variables declares for the scene's parts.
    assert ex.output_names == [v.name for v in fmu_outputs(ex.model)]


@pytest.mark.parametrize("stem", [s.stem for s in SCENES])
def test_model_description_of_shipped_scene(exported, stem):
    """validate_fmu finds nothing; capability flags; every scene number is a fixed parameter
    with a unit, a description and the scene's value as start; tau inputs only with a drive."""
    ex = exported[stem]
    _check_description(ex)
    names = set(ex.variables)
    has_drive = "drive" in ex.data
    assert {f"sigma[{i}]" for i in range(1, 7)} <= names
    assert all((f"tau[{i}]" in names) == has_drive for i in range(1, 7))
    for i in range(1, 7):
        assert ex.variables[f"sigma[{i}]"].causality == "input"
        assert ex.variables[f"sigma[{i}]"].unit == "N"
        if has_drive:
            assert ex.variables[f"tau[{i}]"].unit == "N.m"


def test_platform_only_scene_has_no_absent_parameters(micro, tmp_path):
    """A scene with only [geometry] and [platform]: no legs/drive/friction parameters, no tau
    inputs, no force parts of absent effects (absent tables are absent, not zeros)."""
    data = micro.data
    geo = data["geometry"]
    lines = ['name = "platform-only"', f"gravity = {data['gravity']}", "", "[geometry]"]
    for key in ("base_joints", "platform_joints", "home"):
        lines.append(f"{key} = {geo[key]}")
    lines += [f"leg_min = {geo['leg_min']}", f"leg_max = {geo['leg_max']}", "", "[platform]",
              f"mass = {data['platform']['mass']}", f"inertia = {data['platform']['inertia']}"]
    scene = tmp_path / "platform_only.toml"
    scene.write_text("\n".join(lines) + "\n")
    ex = _export(scene, tmp_path)
    assert ex.model.legs is None and ex.model.drive is None and ex.model.friction is None
    _check_description(ex)
    names = set(ex.variables)
    assert not [n for n in names if n.startswith(("legs.", "drive.", "friction."))]
    assert not [n for n in names if n.startswith("tau[")]
    parts = {n.split("[")[0] for n in names if n.startswith("force.")}
    assert parts == {"force.platform", "force.gravity"}
    # And it simulates: a few steps equal the in-process plant.
    times, steps = grid(20)
    sigmas = wiggle(ex.model, times)
    s = Slave(ex).init()
    got = s.run(times, steps, sigmas)
    s.close()
    ref = Reference(ex.model).run(times, steps, sigmas)
    agree("platform-only FMU vs Plant", residual(ex, got, ref))


# --- 2. fmpy.simulate_fmu with an input signal ------------------------------------------------

@pytest.mark.parametrize("stem", [s.stem for s in SCENES])
def test_simulate_fmu_matches_plant(exported, stem):
    """simulate_fmu over 0.2 s at 1 ms with sigma = hold + sinusoids, against the Plant.

    How fmpy applies the input (fmpy.simulation.simulateCS / Input.interpolate): before each
    doStep it sets every input to the signal linearly interpolated at the step's start time
    t_k = k * output_interval (k counted, not accumulated). The signal below is sampled on that
    same grid (t_k = k * 1e-3 computed the same way), where the interpolation weight of the
    left sample is exactly 0, so the FMU receives exactly sigma(t_k) and holds it over the step
    (canInterpolateInputs = false). The Plant is stepped with the same t_k and h_k = t_k+1 - t_k.
    """
    ex = exported[stem]
    n = 200
    t = np.arange(n + 1) * H
    sigmas = wiggle(ex.model, t, seed=1)
    dtype = [("time", np.float64)] + [(f"sigma[{i}]", np.float64) for i in range(1, 7)]
    signal = np.array([(tk, *s) for tk, s in zip(t, sigmas)], dtype=dtype)
    res = simulate_fmu(str(ex.path), start_time=0.0, stop_time=n * H, output_interval=H,
                       input=signal, output=ex.output_names)
    assert np.array_equal(res["time"], t)
    got = np.column_stack([res[name] for name in ex.output_names])

    ref = Reference(ex.model)
    ref.plant.set_force(sigmas[0])       # what fmpy does in initialization mode
    first = ref.outputs()
    rows = ref.run(t[:-1].tolist(), np.diff(t).tolist(), sigmas[:-1])
    # t = 0: compare the state outputs; the input-dependent ones (rack_force, force.*) at t = 0
    # are the subject of test_outputs_follow_inputs_without_a_step (a known slave defect).
    state = [k for k, name in enumerate(ex.output_names)
             if not name.startswith(("rack_force", "force."))]
    names = [ex.output_names[k] for k in state]
    agree(f"simulate_fmu vs Plant, t = 0 [{stem}]",
          residual(ex, got[:1, state], first[None, state], names))
    agree(f"simulate_fmu vs Plant [{stem}]", residual(ex, got[1:], rows))
    # The run actually moved (the comparison is not of two constant signals).
    lengths = [k for k, name in enumerate(ex.output_names) if name.startswith("l[")]
    assert np.ptp(got[:, lengths], axis=0).max() > 1e-7 * ex.model.leg_max


def test_stiff_scene_fmu_takes_the_plants_default_step(tmp_path):
    """The FMU, Plant and the closed loop share stability.default_options: on a stiff scene the
    exported FMU starts with the same (stiffness-aware) step as Plant(model) and its outputs
    equal the in-process plant's step by step to 1e-12."""
    ex = _export(ROOT / "scenes" / "stiff" / "compliant.toml", tmp_path)
    default = default_options(ex.model)
    assert default.max_step < H   # stiff: the default internal step is below the 1 ms cap
    assert float(ex.variables["solver.max_step"].start) == default.max_step
    n = 50
    t = np.arange(n + 1) * H
    sigmas = wiggle(ex.model, t, seed=2)
    slave = Slave(ex).init(sigma=sigmas[0])
    try:
        got = slave.run(t[:-1].tolist(), np.diff(t).tolist(), sigmas[:-1])
    finally:
        slave.close()
    ref = Reference(ex.model)
    ref.plant = Plant(ex.model)   # as the FMU: the transmission preloaded with the first sigma
    ref.plant.setup_experiment(0.0)
    ref.plant.enter_initialization_mode()
    ref.plant.set_force(sigmas[0])
    ref.plant.exit_initialization_mode()
    want = ref.run(t[:-1].tolist(), np.diff(t).tolist(), sigmas[:-1])
    assert np.ptp(want[:, 0]) > 0    # it moved
    agree("stiff scene: FMU vs Plant, default options", residual(ex, got, want), 1e-12)


def test_outputs_follow_inputs_without_a_step(micro):
    """After exitInitializationMode and after setReal, rack_force equals the inputs set."""
    hold = hold_forces(micro.model)
    s = Slave(micro).init(sigma=hold)
    rack = [f"rack_force[{i}]" for i in range(1, 7)]
    try:
        after_init = s.get(rack)
        s.step(0.0, H, hold)
        s.fmu.setReal(s.sigma_vr, list(hold + 1.0))
        after_set = s.get(rack)
    finally:
        s.close()
    assert np.array_equal(after_init, hold)
    assert np.array_equal(after_set, hold + 1.0)


# --- 3. FMU2Slave: state, reset, instances, steps, parameters ---------------------------------

def test_get_set_fmu_state_rolls_back_bit_for_bit(micro):
    times, steps = grid(40)
    sigmas = wiggle(micro.model, times, seed=2)
    s = Slave(micro).init()
    try:
        s.run(times[:15], steps[:15], sigmas[:15])
        at_state = s.outputs()
        state = s.fmu.getFMUstate()
        first = s.run(times[15:], steps[15:], sigmas[15:])
        for _ in range(3):          # roll back repeatedly; each replay is identical
            s.fmu.setFMUstate(state)
            assert np.array_equal(s.outputs(), at_state)
            assert np.array_equal(s.run(times[15:], steps[15:], sigmas[15:]), first)
        s.fmu.freeFMUstate(state)
    finally:
        s.close()
    ref = Reference(micro.model)
    ref.run(times[:15], steps[:15], sigmas[:15])
    agree("rollback run vs Plant", residual(micro, first, ref.run(times[15:], steps[15:],
                                                                   sigmas[15:])))


def test_serialized_state_restores_here_and_in_a_second_instance(micro):
    times, steps = grid(40)
    sigmas = wiggle(micro.model, times, seed=3)
    s = Slave(micro, "first").init()
    other = Slave(micro, "second")   # instantiated only: the state carries everything
    try:
        s.run(times[:10], steps[:10], sigmas[:10])
        at_state = s.outputs()
        state = s.fmu.getFMUstate()
        blob = s.fmu.serializeFMUstate(state)
        s.fmu.freeFMUstate(state)
        assert isinstance(blob, bytes) and len(blob) > 0
        first = s.run(times[10:], steps[10:], sigmas[10:])
        restored = s.fmu.deSerializeFMUstate(blob)
        s.fmu.setFMUstate(restored)
        assert np.array_equal(s.outputs(), at_state)
        assert np.array_equal(s.run(times[10:], steps[10:], sigmas[10:]), first)
        s.fmu.freeFMUstate(restored)

        state2 = other.fmu.deSerializeFMUstate(blob)
        other.fmu.setFMUstate(state2)
        other.fmu.freeFMUstate(state2)
        assert np.array_equal(other.outputs(), at_state)
        assert np.array_equal(other.run(times[10:], steps[10:], sigmas[10:]), first)
    finally:
        s.close()
        other.close()


def test_reset_then_rerun_equals_first_run(micro):
    times, steps = grid(30)
    sigmas = wiggle(micro.model, times, seed=4)
    s = Slave(micro).init()
    try:
        home = s.outputs()
        first = s.run(times, steps, sigmas)
        s.fmu.reset()
        s.init()
        assert np.array_equal(s.outputs(), home)
        again = s.run(times, steps, sigmas)
    finally:
        s.close()
    assert np.array_equal(first, again)
    assert not np.array_equal(first[-1], home)


def test_two_instances_do_not_interfere(micro):
    times, steps = grid(40)
    sig_a = wiggle(micro.model, times, seed=5)
    sig_b = wiggle(micro.model, times, rel=0.05, seed=6)
    a, b = Slave(micro, "a").init(), Slave(micro, "b").init()
    rows_a, rows_b = [], []
    try:
        for t, h, sa, sb in zip(times, steps, sig_a, sig_b):
            a.fmu.setReal(a.sigma_vr, list(sa))
            b.fmu.setReal(b.sigma_vr, list(sb))
            a.fmu.doStep(t, h)
            b.fmu.doStep(t, h)
            rows_b.append(b.outputs())
            rows_a.append(a.outputs())
    finally:
        a.close()
        b.close()
    rows_a, rows_b = np.array(rows_a), np.array(rows_b)
    for name, rows, sig in (("a", rows_a, sig_a), ("b", rows_b, sig_b)):
        ref = Reference(micro.model).run(times, steps, sig)
        agree(f"two instances: {name} vs Plant", residual(micro, rows, ref))
    assert residual(micro, rows_a, rows_b) > 1e-6   # they really were driven differently


def test_variable_step_sizes(micro):
    """Steps of 1 ms, 0.3 ms, 2.5 ms in a repeating pattern equal the Plant with those steps."""
    steps = [1e-3, 0.3e-3, 2.5e-3] * 12
    times = [0.0]                # accumulated as a master does: t_k+1 = t_k + h_k
    for h in steps[:-1]:
        times.append(times[-1] + h)
    sigmas = wiggle(micro.model, times, seed=7)
    s = Slave(micro).init()
    try:
        got = s.run(times, steps, sigmas)
    finally:
        s.close()
    ref = Reference(micro.model).run(times, steps, sigmas)
    agree("variable steps vs Plant", residual(micro, got, ref))


def test_parameters_before_exit_initialization_override_the_scene(micro):
    """platform.mass, one matrix element and solver.method set before exitInitializationMode
    give exactly the Plant built with those overrides."""
    times, steps = grid(40)
    sigmas = wiggle(micro.model, times, seed=8)
    base = [list(p) for p in micro.data["geometry"]["base_joints"]]
    base[0][2] = 0.002
    s = Slave(micro).init(reals={"platform.mass": 0.6},
                          strings={"solver.method": "dopri5"},
                          init_reals={"geometry.base_joints[1,3]": 0.002})
    default = Slave(micro, "default").init()
    try:
        assert s.get(["platform.mass", "geometry.base_joints[1,3]"]).tolist() == [0.6, 0.002]
        assert s.fmu.getString([s.vr["solver.method"]]) == [b"dopri5"]
        got = s.run(times, steps, sigmas)
        plain = default.run(times, steps, sigmas)
    finally:
        s.close()
        default.close()
    model = load_scene(micro.scene, overrides={"platform.mass": 0.6,
                                               "geometry.base_joints": base})
    ref = Reference(model, IntegratorOptions(method="dopri5")).run(times, steps, sigmas)
    agree("parameters (mass, base joint, dopri5) vs Plant", residual(micro, got, ref))
    assert residual(micro, got, plain) > 1e-6    # the parameters had an effect


def test_initial_state_parameters(micro):
    """q0/qd0 set the initial state: l, ldot after initialization are the inverse kinematics
    of (q0, qd0); the pose outputs are q0, qd0; the run equals the Plant started there."""
    model = micro.model
    q0 = model.home + np.array([0.003, -0.002, 0.004, 0.04, -0.03, 0.05])
    qd0 = np.array([0.01, -0.02, 0.005, 0.1, -0.2, 0.05])
    init = {f"q0[{k + 1}]": float(q0[k]) for k in range(6)}
    init |= {f"qd0[{k + 1}]": float(qd0[k]) for k in range(6)}
    times, steps = grid(20)
    sigmas = wiggle(model, times, seed=9)
    s = Slave(micro).init(init_reals=init)
    try:
        lengths = s.get([f"l[{i}]" for i in range(1, 7)])
        rates = s.get([f"ldot[{i}]" for i in range(1, 7)])
        pose = s.get(["x", "y", "z", "thx", "thy", "thz"])
        pose_rates = s.get(["dx", "dy", "dz", "dthx", "dthy", "dthz"])
        got = s.run(times, steps, sigmas)
    finally:
        s.close()
    kin = inverse_kinematics(model, q0, qd0)
    assert np.max(np.abs(lengths - kin.lengths)) <= 1e-15 * model.leg_max
    assert np.max(np.abs(rates - kin.rates)) <= 1e-15 * np.abs(kin.rates).max()
    assert np.array_equal(pose, q0) and np.array_equal(pose_rates, qd0)
    ref = Reference(model, q0=q0, qd0=qd0).run(times, steps, sigmas)
    agree("q0/qd0 start vs Plant", residual(micro, got, ref))


# --- 4. errors ----------------------------------------------------------------------------------

def test_stroke_limit_discard_rollback_and_carry_on(micro):
    """A step pushed out of the stroke returns fmi2Discard with a log message naming the time;
    the master restores its last good state, lowers the force and carries on."""
    model = micro.model
    times, steps = grid(40)
    sigmas = wiggle(model, times, seed=10)
    k_bad = 10
    push = hold_forces(model) + 5e6      # N: leaves the stroke within one 1 ms step
    s = Slave(micro).init()
    ref = Reference(model)
    try:
        s.run(times[:k_bad], steps[:k_bad], sigmas[:k_bad])
        ref.run(times[:k_bad], steps[:k_bad], sigmas[:k_bad])
        good, good_ref = s.fmu.getFMUstate(), ref.plant.get_state()
        before = s.outputs()
        s.fmu.setReal(s.sigma_vr, list(push))
        with pytest.raises(FMICallException) as exc:
            s.fmu.doStep(times[k_bad], steps[k_bad])
        assert exc.value.status == fmi2Discard
        discards = [m for m in s.messages if m[0] == fmi2Discard]
        assert len(discards) == 1
        t_bad = times[k_bad]
        assert f"t = {t_bad!r} s" in discards[0][2] and "stroke" in discards[0][2]
        state = [k for k, name in enumerate(micro.output_names)
                 if not name.startswith(("rack_force", "force."))]
        assert np.array_equal(s.outputs()[state], before[state])  # left at the step's start
        with pytest.raises(StepRejected) as rej:
            ref.step(t_bad, steps[k_bad], push)
        assert rej.value.time == t_bad
        assert str(rej.value) == discards[0][2]   # one refusal message (stewart_refusal)
        # Roll back, lower the force, carry on.
        s.fmu.setFMUstate(good)
        s.fmu.freeFMUstate(good)
        ref.plant.set_state(good_ref)
        got = s.run(times[k_bad:], steps[k_bad:], sigmas[k_bad:])
        assert len([m for m in s.messages if m[0] >= fmi2Discard]) == 1
    finally:
        s.close()
    want = ref.run(times[k_bad:], steps[k_bad:], sigmas[k_bad:])
    agree("after discard and rollback vs Plant", residual(micro, got, want))


# Error scenarios run in child processes, so that a crash (a segfault in the importer) is seen
# as a failed test instead of ending the session, and each scenario finishes with what a master
# does after a failure (free the instance, let gc run, carry on with a new one).
_CHILD = r"""
import ctypes, gc, json, os, sys
from fmpy import calloc, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.logging import addLoggerProxy

unzipdir, scenario = sys.argv[1], sys.argv[2]
md = read_model_description(unzipdir)
vr = {v.name: v.valueReference for v in md.modelVariables}
messages = []

def log(env, instance, status, category, message):
    messages.append([status, (category or b"").decode(), message.decode()])

cb = fmi2CallbackFunctions()
cb.logger = fmi2CallbackLoggerTYPE(log)
cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
addLoggerProxy(ctypes.byref(cb))

def instance(name, init=True):
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(loggingOn=True, callbacks=cb)
    fmu.setupExperiment(startTime=0.0)
    if init:
        init_mode(fmu)
    return fmu

def init_mode(fmu):
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()

sigma = [vr[f"sigma[{i}]"] for i in range(1, 7)]
state = [vr[n] for n in [f"l[{i}]" for i in range(1, 7)] + ["x", "y", "z", "thx", "thy", "thz"]]
late = scenario in ("step_before_init", "negative_mass", "percent_in_message")
fmu = instance("bad", init=not late)
if not late:
    fmu.doStep(0.0, 1e-3)
if scenario == "negative_mass":
    fmu.setReal([vr["platform.mass"]], [-0.5])
    fmu.enterInitializationMode()
step = lambda: fmu.doStep(1e-3, 1e-3)
actions = {
    "nan_input": [("bad", lambda: fmu.setReal([sigma[0]], [float("nan")])), ("refused", step),
                  ("fix", lambda: fmu.setReal([sigma[0]], [0.0])), ("recovered", step)],
    "step_before_init": [("bad", lambda: fmu.doStep(0.0, 1e-3)), ("fix", lambda: init_mode(fmu)),
                         ("recovered", lambda: fmu.doStep(0.0, 1e-3))],
    "wrong_time": [("bad", lambda: fmu.doStep(0.5, 1e-3)), ("recovered", step)],
    "zero_step": [("bad", lambda: fmu.doStep(1e-3, 0.0)), ("recovered", step)],
    "negative_step": [("bad", lambda: fmu.doStep(1e-3, -1e-3)), ("recovered", step)],
    "negative_mass": [("bad", fmu.exitInitializationMode),
                      ("refused", lambda: fmu.doStep(0.0, 1e-3)), ("fix", fmu.reset),
                      ("setup", lambda: fmu.setupExperiment(startTime=0.0)),
                      ("init", lambda: init_mode(fmu)),
                      ("recovered", lambda: fmu.doStep(0.0, 1e-3))],
    "percent_in_message": [("bad", lambda: fmu.setString([vr["solver.method"]], ["rk4%s%n"])),
                           ("init0", lambda: init_mode(fmu)),
                           ("refused", lambda: fmu.doStep(0.0, 1e-3)), ("fix", fmu.reset),
                           ("setup", lambda: fmu.setupExperiment(startTime=0.0)),
                           ("init", lambda: init_mode(fmu)),
                           ("recovered", lambda: fmu.doStep(0.0, 1e-3))],
    "get_string_of_real": [("bad", lambda: fmu.getString([state[0]])), ("recovered", step)],
    "set_boolean": [("bad", lambda: fmu.setBoolean([sigma[0]], [True])), ("recovered", step)],
}[scenario]
result = {"status": {}, "state": {}, "messages": messages}
result["state"]["before"] = fmu.getReal(state) if not late else None
for label, action in actions:
    try:
        action()
        result["status"][label] = 0
    except FMICallException as exc:
        result["status"][label] = exc.status
    print("RESULT " + json.dumps(result), flush=True)   # kept even if a later call crashes
    if label not in ("fix", "setup", "init"):
        result["state"][label] = fmu.getReal(state)
print("RESULT " + json.dumps(result), flush=True)
fmu.terminate()
fmu.freeInstance()
gc.collect()
other = instance("after")
for k in range(5):
    other.doStep(k * 1e-3, 1e-3)
other.terminate()
other.freeInstance()
gc.collect()
print("SURVIVED", flush=True)
# Leave without the C exit handlers: in about 1 child in 60 whose scenario logged an error (0 in
# 100 plain runs), glibc aborts at exit ("corrupted double-linked list") inside the exit handler
# of scipy's bundled libgfortran (close_units -> free), after every FMI call above has returned;
# the corrupted chunk lies next to scipy.optimize._highspy signature strings. Not isolated yet
# (see the notes); what this test checks ends with the second instance above.
os._exit(0)
"""

# The error scenarios of FMI calls (NaN input, a step before initialization, a wrong time,
# zero and negative steps, a bad parameter at exitInitializationMode, a '%' in a logged value)
# are tests/stewart_fmu/test_native_fmu.py's: each returns fmi2Error with the state unchanged.
# Calls with a value reference of the wrong type (a master's mistake; FMI wants fmi2Error).
_WRONG_TYPE = ("get_string_of_real", "set_boolean")


@pytest.fixture(scope="module")
def error_runs(micro) -> dict[str, dict]:
    """Each scenario in its own child process (a few at a time): statuses, log, survival."""
    def run(scenario: str) -> dict:
        proc = subprocess.run([sys.executable, "-c", _CHILD, str(micro.unzipdir), scenario],
                              capture_output=True, text=True, timeout=120, cwd=ROOT)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        result = json.loads(lines[-1][7:]) if lines else {"status": {}, "state": {},
                                                          "messages": []}
        return {**result, "returncode": proc.returncode,
                "survived": "SURVIVED" in proc.stdout, "stderr": proc.stderr[-3000:]}

    names = list(_WRONG_TYPE)
    with ThreadPoolExecutor(max_workers=4) as pool:
        return dict(zip(names, pool.map(run, names)))


@pytest.mark.parametrize("scenario", _WRONG_TYPE)
def test_wrong_type_call_does_not_crash_the_importer(error_runs, scenario):
    run = error_runs[scenario]
    assert run["status"].get("bad") in (fmi2Error, 0), run["messages"]
    assert run["returncode"] == 0 and run["survived"], (run["returncode"], run["stderr"])


def test_simulate_fmu_stops_quietly_at_a_discard(micro):
    """fmpy.simulate_fmu at a step into the stroke: the FMU returns fmi2Discard, reports
    fmi2Terminated = true after a discard, and simulate_fmu then ends the run at the
    last successful time without raising: the result is just shorter. (Masters that want to
    roll back must drive the FMU themselves, as in the test above.)"""
    model = micro.model
    n, k_bad = 50, 20
    t = np.arange(n + 1) * H
    sigmas = wiggle(model, t, seed=11)
    sigmas[k_bad:] = hold_forces(model) + 5e6
    dtype = [("time", np.float64)] + [(f"sigma[{i}]", np.float64) for i in range(1, 7)]
    # A step change at t_k: two samples at t_k (fmpy applies the right one, after the event).
    rows = [(tk, *s) for tk, s in zip(t, sigmas)]
    rows.insert(k_bad, (t[k_bad], *sigmas[k_bad - 1]))
    res = simulate_fmu(str(micro.path), start_time=0.0, stop_time=n * H, output_interval=H,
                       input=np.array(rows, dtype=dtype), output=["z"])
    assert res["time"][-1] == pytest.approx(t[k_bad], abs=1e-15)
    assert len(res) < n + 1


# --- 5. a second importer: libcosim ------------------------------------------------------------

def test_libcosim_matches_plant(micro):
    """libcosimpy (DNV libcosim, FMI Library underneath) runs the FMU 100 steps at 1 ms with
    sigma = hold + offsets (override manipulator); l[1..6] and z equal the Plant's."""
    try:
        from libcosimpy._internal import get_last_error_message
        from libcosimpy.CosimEnums import CosimErrorCode
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except (ImportError, OSError) as exc:
        pytest.skip(f"libcosimpy cannot be loaded here: {exc!r}")
    model = micro.model
    sigma = hold_forces(model) + np.array([0.3, -0.1, 0.2, 0.0, -0.2, 0.1])
    n, step_ns = 100, 1_000_000
    execution = CosimExecution.from_step_size(step_ns)
    slave = CosimLocalSlave(fmu_path=str(micro.path), instance_name="plant")
    index = execution.add_local_slave(slave)
    if index < 0:
        pytest.skip(f"libcosim cannot load the FMU: {get_last_error_message()}")
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    observer = CosimObserver.create_last_value()
    manipulator = CosimManipulator.create_override()
    assert execution.add_observer(observer) and execution.add_manipulator(manipulator)
    assert manipulator.slave_real_values(index, [refs[f"sigma[{i}]"] for i in range(1, 7)],
                                         sigma.tolist())
    assert execution.step(n), get_last_error_message()
    status = execution.status()
    assert status.current_time == n * step_ns
    assert CosimErrorCode(status.error_code) == CosimErrorCode.SUCCESS
    names = [f"l[{i}]" for i in range(1, 7)] + ["z"]
    got = np.array(observer.last_real_values(index, [refs[name] for name in names]))
    del execution, slave, observer, manipulator
    gc.collect()

    # libcosim's times are integer nanoseconds, converted as t = ns / 1e9 and h = t1 - t0.
    t = [k * step_ns / 1e9 for k in range(n + 1)]
    ref = Reference(model)
    for k in range(n):
        ref.step(t[k], t[k + 1] - t[k], sigma)
    want = np.r_[ref.plant.outputs.lengths, ref.plant.outputs.q[2]]
    assert abs(want[6] - model.home[2]) > 1e-6          # the platform moved
    agree("libcosim l[1..6], z vs Plant", float(np.max(np.abs(got - want)) / np.abs(want).max()))
