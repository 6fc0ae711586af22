"""The controller FMU (controller.fmu, `export-fmu --controller`): fmpy validates it (FMI 2.0
and 3.0); beside the plant FMU, stepped by a small fmpy master at the controller rate, it
reproduces the closed loop (controller.cosim.run_closed_loop with the in-process plant) bit for
bit; it refuses a step that is not a whole number of controller periods and names why.

The master of a sample k: read the plant's l, ldot; set the controller's references, feedforward
and measurements; read its tau (the sample at t_k, direct feedthrough); step the controller and
the plant (tau held) over the period. That is closed_loop_run's order, so the two loops compute
the same numbers: the controller's arithmetic is axis.c's axis_step in both. With the scene's
[controller] delay = 1 the FMU's parameter delay starts at 1: its tau is the last step's
sample, and the same master reproduces the closed loop with that delay.
"""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.drive import axis_model
from controller.feedforward import equilibrium, feedforward_voltage
from controller.fmu import (export_controller, input_ranges, parameter_ranges, start_values, table_rows,
                            variables)
from controller.moves import run_reference
from controller.plants import FmuPlant
from controller.design import tune_pid
from controller.trajectory import leg_references
from stewart_fmu import load_scene
from stewart_fmu.fmu.export import export_model
from tests.helpers import fmi2_logging_callbacks

ROOT = Path(__file__).resolve().parents[2]
DURATION = 0.3   # s of `run`'s reference: out, hold, back, hold


@pytest.fixture(scope="module")
def micro(tmp_path_factory):
    """The micro-manipulator's model, config, plant FMU and controller FMUs (2.0, 3.0)."""
    tmp = tmp_path_factory.mktemp("ctl")
    path = ROOT / "scenes" / "micro_manipulator.toml"
    model = load_scene(path)
    config = controller_config(model)
    plant = export_model(model, path.read_bytes(), tmp / "plant.fmu", 2)
    ctl = {(v, 0): export_controller(model, config, tmp / f"controller{v}.fmu", v) for v in (2, 3)}
    late = dataclasses.replace(config, delay=1)
    ctl[2, 1] = export_controller(model, late, tmp / "controller2_delay1.fmu", 2)
    return model, config, plant, ctl


def _slave(path: Path, name: str):
    md = read_model_description(str(path))
    cls = FMU2Slave if md.fmiVersion == "2.0" else FMU3Slave
    slave = cls(guid=md.guid, unzipDirectory=extract(str(path)),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return md, slave, vr


def _group(vr: dict[str, int], name: str) -> list[int]:
    return [vr[f"{name}[{i}]"] for i in range(1, 7)]


@pytest.mark.parametrize("version", [2, 3])
def test_validates(micro, version):
    assert validate_fmu(str(micro[3][version, 0])) == []


@pytest.mark.parametrize("version,delay", [(2, 0), (3, 0), (2, 1)])
def test_loop_of_two_fmus_equals_closed_loop(micro, version, delay):
    """Plant FMU + controller FMU under an fmpy master == run_closed_loop (in-process, the C
    loop) with the scene's delay, bit for bit on the leg lengths, torques and voltages of every
    sample (with delay 1 the FMU's tau and voltage are the closed loop's of the sample before,
    the drives' start at the first)."""
    model, config, plant_path, ctl = micro
    config = dataclasses.replace(config, delay=delay)
    md = read_model_description(str(ctl[version, delay]))
    assert [float(v.start) for v in md.modelVariables if v.name == "delay"] == [float(delay)]
    traj = run_reference(model, config, DURATION)
    ref = run_closed_loop(model, config, traj).table
    refs = leg_references(model, traj)
    axis = axis_model(model, config.motor, config.load_mass)
    gains = tune_pid(axis, config.bandwidth, config.phase_margin)
    v_ff, i_ff = feedforward_voltage(model, config, axis, traj, refs)
    current0, integral0 = equilibrium(model, traj.q[0], traj.qd[0], refs.ldot[0], i_ff[0], gains, axis)
    # `run` starts at rest at home: the FMU's start values are that start
    start = start_values(model, config)
    assert np.array_equal(start["current0"], current0) and np.array_equal(start["integral0"], integral0)

    md, ctrl, vr = _slave(ctl[version, delay], "controller")
    set_real = ctrl.setReal if version == 2 else ctrl.setFloat64
    get_real = ctrl.getReal if version == 2 else ctrl.getFloat64
    ctrl.instantiate()
    if version == 2:
        ctrl.setupExperiment(startTime=float(traj.t[0]))
        ctrl.enterInitializationMode()
    else:
        ctrl.enterInitializationMode(startTime=float(traj.t[0]))
    ctrl.exitInitializationMode()
    plant = FmuPlant(plant_path)
    plant.start(traj.q[0], traj.qd[0], float(traj.t[0]), current0 * config.motor.torque_constant)
    inputs = [v for name in ("l_ref", "ldot_ref", "v_ff", "l", "ldot") for v in _group(vr, name)]
    outputs = _group(vr, "tau") + _group(vr, "voltage")
    n = len(traj.t)
    l_rec, tau_rec, v_rec = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 6))
    try:
        for k in range(n):
            l, ldot, _ = plant.measure()
            set_real(inputs, [float(x) for x in np.concatenate([refs.l[k], refs.ldot[k], v_ff[k], l, ldot])])
            out = np.array(get_real(outputs))
            l_rec[k], tau_rec[k], v_rec[k] = l, out[:6], out[6:]
            if k + 1 < n:
                h = float(traj.t[k + 1] - traj.t[k])
                ctrl.doStep(currentCommunicationPoint=float(traj.t[k]), communicationStepSize=h)
                plant.step(float(traj.t[k]), h, out[:6])
    finally:
        plant.close()
        ctrl.terminate()
        ctrl.freeInstance()

    def legs(prefix):
        return np.column_stack([ref[f"{prefix}{i}"] for i in range(1, 7)])

    diff = np.max(np.abs(l_rec - legs("l")))
    print(f"FMI {version}.0 controller FMU (delay {delay}) + plant FMU vs run_closed_loop: "
          f"max |dl| = {diff:.3g} m over {n} samples")
    assert diff == 0.0
    if delay:
        assert np.array_equal(tau_rec[0], current0 * config.motor.torque_constant)
        tau_rec, v_rec = tau_rec[1:], v_rec[1:]
    assert np.array_equal(tau_rec, legs("torque")[:n - delay])
    assert np.array_equal(v_rec, legs("voltage")[:n - delay])
    assert np.ptp(legs("l")) > 1e-3   # the move is a real one


def test_refuses_a_partial_period(micro):
    """doStep over 1.5 periods is an Error with the reason logged; whole periods pass."""
    _, config, _, ctl = micro
    code = f"""
import sys
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
path = {str(ctl[2, 0])!r}
md = read_model_description(path)
s = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="c")
s.instantiate()  # fmpy's default logger prints the FMU's messages
s.setupExperiment(startTime=0.0)
s.enterInitializationMode()
s.exitInitializationMode()
s.doStep(0.0, 3 * {config.dt!r})
try:
    s.doStep(3 * {config.dt!r}, 1.5 * {config.dt!r})
except FMICallException:
    print("refused")
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "refused" in proc.stdout and "not a whole number of controller periods" in proc.stdout, \
        proc.stdout + proc.stderr


def test_variables_follow_the_table(micro):
    """Names and value references come from native/fmi/axis_table.h: every group of six,
    consecutive; the FMU answers each (the C and the Python reading of the table agree)."""
    _, config, _, ctl = micro
    md, slave, vr = _slave(ctl[2, 0], "c")
    table = variables()
    assert [(x.name, x.vr) for x in table] == [(v.name, v.valueReference) for v in md.modelVariables]
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    values = slave.getReal([x.vr for x in table])
    slave.exitInitializationMode()
    starts = {v.name: float(v.start) for v in md.modelVariables if v.start is not None}
    assert all(values[k] == starts[x.name] for k, x in enumerate(table) if x.name in starts)
    assert values[[x.name for x in table].index("rate")] == config.rate
    with pytest.raises(FMICallException):
        slave.setReal([vr["tau[1]"]], [0.0])
    slave.terminate()
    slave.freeInstance()


@pytest.mark.parametrize("version", [2, 3])
def test_parameters_declare_the_bounds_the_fmu_enforces(micro, version):
    """Each bounded parameter declares its bounds (axis_table.h's AXIS_FMU_PARAMETER_RANGES, read
    by model.c and controller/fmu.py) as min and max (max only where it has one); the others
    none; the start values lie inside. exitInitializationMode refuses a value just outside
    (an open bound's min itself, a closed one's next double down, past max), naming it."""
    path = micro[3][version, 0]
    bounds = parameter_ranges()
    by_name = {name: ident for ident, name, *_ in table_rows()["PARAMETERS"]}
    md, _, vr = _slave(path, "probe")
    declared = 0
    for v in md.modelVariables:
        if v.causality != "parameter":
            continue
        b = bounds.get(by_name[v.name.split("[")[0]])
        if b is None:
            assert v.min is None and v.max is None, v.name
            continue
        declared += 1
        assert float(v.min) == b.min and (v.max is None if np.isinf(b.max) else float(v.max) == b.max), v.name
        assert b.reason(float(v.start)) is None and b.min <= float(v.start) <= b.max, v.name
    assert declared == len(bounds) == 13
    for ident, b in bounds.items():
        name = next(n for n, i in by_name.items() if i == ident)
        bad = b.min if b.open else np.nextafter(b.min, -np.inf)
        for value in (bad, *(() if np.isinf(b.max) else (np.nextafter(b.max, np.inf),))):
            _, slave, _ = _slave(path, "probe")
            said: list[str] = []
            if version == 2:
                slave.instantiate(callbacks=fmi2_logging_callbacks(lambda _s, _c, m: said.append(m)))
                slave.setupExperiment(startTime=0.0)
            else:
                slave.instantiate(logMessage=lambda _env, _status, _cat, m: said.append(m.decode()))
            slave.enterInitializationMode()
            (slave.setReal if version == 2 else slave.setFloat64)([vr[name]], [float(value)])
            with pytest.raises(FMICallException):
                slave.exitInitializationMode()
            slave.freeInstance()
            assert any(f"exitInitializationMode: parameter {name} must be" in m for m in said), said


def test_command(tmp_path, capsys):
    """`export-fmu SCENE --controller -o F`: the FMU written; a scene without [controller] is
    one line naming the table, exit 2, nothing written."""
    from stewart_sim import cli

    out = tmp_path / "controller.fmu"
    assert cli.main(["export-fmu", str(ROOT / "scenes" / "micro_manipulator.toml"), "--controller",
                     "-o", str(out), "--fmi-version", "3"]) == 0
    assert read_model_description(str(out)).coSimulation.modelIdentifier == "StewartController"
    capsys.readouterr()
    bare = ROOT / "scenes" / "extreme" / "massless_legs.toml"
    assert "[controller]" not in bare.read_text()
    assert cli.main(["export-fmu", str(bare), "--controller", "-o", str(tmp_path / "x.fmu")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "controller" in err[0], err
    assert not (tmp_path / "x.fmu").exists()


def _fuzz_child(path: Path, seed: int, n_calls: int) -> dict:
    """Random calls on one controller FMU: hostile inputs, steps of every size, outputs read
    (run in a child process, so that a crash fails the test instead of ending it)."""
    import math
    import random

    md = read_model_description(str(path))
    version = 2 if md.fmiVersion == "2.0" else 3
    cls = FMU2Slave if version == 2 else FMU3Slave
    slave = cls(guid=md.guid if version == 2 else md.instantiationToken, unzipDirectory=extract(str(path)),
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="fuzz")
    inputs = {v.valueReference: (float(v.min), float(v.max)) for v in md.modelVariables if v.causality == "input"}
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    set_real = slave.setReal if version == 2 else slave.setFloat64
    get_real = slave.getReal if version == 2 else slave.getFloat64
    rng = random.Random(seed)
    dt = 1.0 / float(next(v.start for v in md.modelVariables if v.name == "rate"))
    out = {"calls": 0, "must_fail": 0, "errors": 0, "not_error": [], "nonfinite_ok": [], "values_read": 0}

    def call(fn, *args, must_fail=False):
        out["calls"] += 1
        out["must_fail"] += must_fail
        try:
            result = fn(*args)
        except FMICallException:
            out["errors"] += must_fail
            return None
        if must_fail:
            out["not_error"].append([fn.__name__, [a if isinstance(a, (int, float)) else None for a in args]])
        return result if result is not None else True

    slave.instantiate()
    if version == 2:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
    else:
        slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    t = 0.0
    for _ in range(n_calls):
        action = rng.choice(["set", "set", "step", "step", "get"])
        if action == "set":
            ks = rng.sample(list(inputs), rng.randint(1, 6))
            values = [rng.choice([rng.uniform(-1, 1), rng.uniform(-1e3, 1e3), 1e308, -1e308, math.nan, math.inf,
                                  5e-324, -5e-324, 1e6, 1.0000001e6, 1e3, -1e3, 0.0]) for _ in ks]
            outside = any(not inputs[k][0] <= x <= inputs[k][1] for k, x in zip(ks, values))
            call(set_real, ks, values, must_fail=outside)
        elif action == "step":
            h = rng.choice([dt, dt, 3 * dt, 1000 * dt, 0.0, -dt, math.nan, math.inf, 1e308, 1.5 * dt, 2e7 * dt])
            periods = h / dt   # model.c's rule: a whole number of periods, at most 1e7
            whole = math.isfinite(periods) and 1 <= round(periods) <= 1e7 and \
                abs(periods - round(periods)) <= 1e-9 * round(periods)
            if call(slave.doStep, t, h, must_fail=not whole) is not None:
                t += h
        else:
            ks = rng.sample(outputs, rng.randint(1, len(outputs)))
            values = call(get_real, ks)
            if values is not None:
                out["values_read"] += len(values)
                bad = [x for x in values if not math.isfinite(x)]
                if bad:
                    out["nonfinite_ok"].append([t, bad[:3]])
    slave.terminate()
    slave.freeInstance()
    return out


@pytest.mark.parametrize("version", [2, 3])
def test_inputs_are_ranged_and_outputs_never_ok_non_finite(micro, version):
    """Every input declares min and max (axis_table.h's AXIS_FMU_INPUT_RANGES, read by C and
    by controller/fmu.py); seeded random calls with hostile values (1e308, NaN, inf,
    denormals, just outside a range) and steps: a value outside its range is refused with
    Error, and no getReal answers OK with a NaN or an infinity."""
    path = micro[3][version, 0]
    md = read_model_description(str(path))
    ranges = input_ranges()
    by_name = {name: ident for ident, name, *_ in table_rows()["INPUTS"]}
    for v in md.modelVariables:
        if v.causality == "input":
            lo, hi = ranges[by_name[v.name.split("[")[0]]]
            assert (float(v.min), float(v.max)) == (lo, hi) and lo <= float(v.start) <= hi, v.name
    code = (f"import json, sys; sys.path.insert(0, {str(ROOT)!r}); "
            f"from tests.controller.test_controller_fmu import _fuzz_child; from pathlib import Path; "
            f"print('RESULT ' + json.dumps(_fuzz_child(Path({str(path)!r}), int(sys.argv[1]), 2500)))")
    totals = {"calls": 0, "must_fail": 0, "errors": 0, "values_read": 0, "not_error": [], "nonfinite_ok": []}
    for seed in range(2):
        proc = subprocess.run([sys.executable, "-c", code, str(seed)], capture_output=True, text=True, timeout=300)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        assert proc.returncode == 0 and lines, proc.stderr[-3000:]
        r = json.loads(lines[-1][7:])
        for k in totals:
            totals[k] += r[k]
    assert totals["calls"] >= 5000 and totals["values_read"] > 10_000
    assert totals["not_error"] == [] and totals["errors"] == totals["must_fail"] > 1000
    assert totals["nonfinite_ok"] == []
