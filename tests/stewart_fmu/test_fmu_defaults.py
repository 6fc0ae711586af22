"""The native FMU's defaults: sigma[1..6] start at the force holding home, so an importer that
never sets the inputs sees the platform stay put; the DefaultExperiment (0 to 1 s, 1 ms steps,
the solver's rtol) lets fmpy run with default settings; a discarded doStep is reported with
status Discard and its reason even with logging off (loggingOn = false), as errors are."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.fmu import variables as V
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.stability import default_options
from tests.helpers import host_binary_only, record

ROOT = Path(__file__).resolve().parents[2]
SCENES = {"micro": ROOT / "scenes" / "micro_manipulator.toml",
          "sim": ROOT / "scenes" / "motion_simulator.toml",
          "compliant": ROOT / "scenes" / "stiff" / "compliant.toml"}
HOLD_DRIFT = 1e-9   # m: |z - home z| over the DefaultExperiment with no inputs set


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Each scene's FMU, FMI 2.0 and 3.0, run here on this machine: its host binary only."""
    folder = tmp_path_factory.mktemp("fmu_defaults")
    with host_binary_only():
        return {(name, v): export_fmu(scene, folder / f"{name}_{v}.fmu", fmi_version=v)
                for name, scene in SCENES.items() for v in (2, 3)}


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_sigma_starts_at_the_hold_force_and_default_experiment(built, name, version):
    md = read_model_description(str(built[(name, version)]))
    model = load_scene(SCENES[name])
    hold = inverse_dynamics(model, np.asarray(model.home, float), np.zeros(6), np.zeros(6))
    start = {v.name: v.start for v in md.modelVariables}
    six = lambda name: ([float(start[f"{name}[{i}]"]) for i in range(1, 7)] if version == 2  # noqa: E731
                        else [float(x) for x in start[name].split()])   # FMI 3.0: one array
    assert six("sigma") == hold.tolist()
    if model.drive is not None:
        assert six("tau") == [0.0] * 6
    de = md.defaultExperiment
    assert float(de.startTime) == 0.0 and float(de.stopTime) == V.STOP_TIME
    assert float(de.stepSize) == V.STEP_SIZE
    assert float(de.tolerance) == default_options(model).rtol


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_no_inputs_platform_stays_home_to_the_default_stop_time(built, name, version):
    """fmpy.simulate_fmu with default settings (no inputs, no times): it runs the
    DefaultExperiment to its stop time and z stays within HOLD_DRIFT of home."""
    res = simulate_fmu(str(built[(name, version)]), output=["x", "y", "z", "thx", "thy", "thz"])
    model = load_scene(SCENES[name])
    assert res["time"][0] == 0.0 and res["time"][-1] == pytest.approx(V.STOP_TIME, abs=1e-12)
    assert len(res) == round(V.STOP_TIME / V.STEP_SIZE) + 1
    drift = float(np.abs(res["z"] - model.home[2]).max())
    record(f"FMU hold drift |z - home| (m), {name} FMI {version}.0", drift, HOLD_DRIFT)
    assert drift <= HOLD_DRIFT, drift


_QUIET_DISCARD = r"""
import sys, ctypes
from fmpy import read_model_description, extract
from fmpy.fmi1 import FMICallException
path, version = sys.argv[1], int(sys.argv[2])
md = read_model_description(path)
unzip = extract(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
msgs = []
common = dict(unzipDirectory=unzip, modelIdentifier="StewartPlant", instanceName="quiet")
if version == 2:
    from fmpy import calloc, free
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                           fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE)
    from fmpy.logging import addLoggerProxy
    def log(_e, _n, status, cat, msg):
        msgs.append((status, (cat or b"").decode(), msg.decode()))
    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(log)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(ctypes.byref(cb))
    fmu = FMU2Slave(guid=md.guid, **common)
    fmu.instantiate(loggingOn=False, callbacks=cb)
    fmu.setDebugLogging(False, [])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode(); fmu.exitInitializationMode()
    setr = fmu.setReal
else:
    from fmpy.fmi3 import FMU3Slave
    def log3(_e, status, cat, msg):
        msgs.append((status, (cat or b"").decode(), msg.decode()))
    fmu = FMU3Slave(guid=md.instantiationToken, **common)
    fmu.instantiate(loggingOn=False, logMessage=log3)
    fmu.enterInitializationMode(startTime=0.0); fmu.exitInitializationMode()
    setr = fmu.setFloat64
fmu.doStep(0.0, 1e-3)                          # the default inputs hold: OK
setr([vr[f"sigma[{i}]"] for i in range(1, 7)] if version == 2 else [vr["sigma"]], [5e6] * 6)
try:
    fmu.doStep(1e-3, 0.05)
    print("NO DISCARD")
except FMICallException as exc:
    print("STATUS", exc.status)
try:
    fmu.doStep(0.5, 1e-3)                      # wrong communication point: Error
except FMICallException as exc:
    print("STATUS", exc.status)
for st, cat, m in msgs:
    print("LOG", st, cat, m.replace("\n", " "))
"""


@pytest.mark.parametrize("version", [2, 3])
def test_discard_and_error_reported_with_logging_off(built, version):
    proc = subprocess.run([sys.executable, "-c", _QUIET_DISCARD, str(built[("micro", version)]), str(version)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout.splitlines()
    assert out[:2] == ["STATUS 2", "STATUS 3"], proc.stdout
    logs = [ln for ln in out if ln.startswith("LOG")]
    assert any(ln.startswith("LOG 2 logStatusDiscard") and "discarded" in ln and "stroke" in ln
               for ln in logs), logs
    assert any(ln.startswith("LOG 3 logStatusError") and "currentCommunicationPoint" in ln for ln in logs), logs
    assert not any(ln.startswith("LOG 0") for ln in logs), logs   # no events with logging off
