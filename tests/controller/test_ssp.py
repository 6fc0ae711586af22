"""`export-ssp` (controller.ssp): `run`'s closed loop as an SSP 1.0 archive, run by FMPy's
simulate_ssp and by libcosim (libcosimpy) in a child process that cannot import this project
(python -I -S, only the venv's site-packages directory on its path, so the project's editable
install is not seen; run from a temporary directory).

What each importer computes is held, bit for bit, to an independent in-process loop (the
stewart_fmu Plant and controller.axis.servo_step, no FMU) that follows the importer's algorithm:
both step every FMU over the period and then pass outputs on, so the torque of the sample at t_k
drives the plant over [t_k+1, t_k+2] (the controller's parameter delay = 1); libcosim first runs
the initial exchange (the plant starts with the drives' holding torque), FMPy's simulate_ssp
starts every connector at 0.0 (its first plant step has tau = 0, the controller's first sample
sees l = 0). That loop is `run` (controller.cosim.run_closed_loop, both its paths) of the scene
with `[controller] delay = 1`: libcosim's lengths equal `run`'s bit for bit; FMPy's differ by its
zero start (the figure is printed). With delay 0 (the plant stepped after the controller within
a sample) the lengths differ by that period's delay: printed too.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest

from controller.axis import AxisControllers, MotorCurrents, servo_step
from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.design import tune_pid
from controller.drive import axis_model
from controller.feedforward import equilibrium, feedforward_voltage
from controller.moves import run_reference
from controller.plants import InProcessPlant
from controller.trajectory import leg_references
from stewart_fmu import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
DURATION = 0.3

CHILD = r"""
import importlib.util, json, sys
sys.path[:0] = ["."]                    # ssp_child.py, copied here (-I puts no directory first)
sys.path.append(sys.argv[1])            # the venv's site-packages, without its .pth files
assert importlib.util.find_spec("stewart_fmu") is None and importlib.util.find_spec("controller") is None
from ssp_child import fmpy_run, libcosim_run
ssp, n, step = sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
print("RESULT " + json.dumps({"fmpy": fmpy_run(ssp, n, step), "libcosim": libcosim_run(ssp, n)}))
"""


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """The SSP written by the command, and both importers' leg lengths after every step."""
    from stewart_sim import cli

    tmp = tmp_path_factory.mktemp("ssp")
    ssp = tmp / "loop.ssp"
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        assert cli.main(["export-ssp", str(SCENE), "-o", str(ssp), "--duration", str(DURATION)]) == 0
    model = load_scene(SCENE)
    config = controller_config(model)
    assert config.delay == 0   # the scene's: export-ssp says the SSP is delay 1's
    notes = [ln for ln in said.getvalue().splitlines() if "controller.delay = 1" in ln]
    assert len(notes) == 1 and "controller.delay = 0" in notes[0], said.getvalue()
    config = dataclasses.replace(config, delay=1)
    traj = run_reference(model, config, DURATION)
    steps = len(traj.t) - 1
    work = tmp / "clean"
    work.mkdir()
    shutil.copy(Path(__file__).with_name("ssp_child.py"), work / "ssp_child.py")
    env = {k: v for k, v in __import__("os").environ.items() if not k.startswith("PYTHON")}
    proc = subprocess.run([sys.executable, "-I", "-S", "-c", CHILD, sysconfig.get_paths()["purelib"],
                           str(ssp), str(steps), repr(config.dt)],
                          cwd=work, env=env, capture_output=True, text=True, timeout=600)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-2000:] + proc.stderr[-4000:]
    got = {k: np.array(v) for k, v in json.loads(lines[-1][7:]).items()}
    return model, config, traj, got


def _lengths(table: np.ndarray) -> np.ndarray:
    """The leg lengths after every step of a `run` table (its samples 1..n-1), shape (steps, 6)."""
    return np.column_stack([table[f"l{i}"] for i in range(1, 7)])[1:]


@pytest.fixture(scope="module")
def delayed_run(loop):
    """`run`'s closed loop of the scene with [controller] delay = 1: the C loop's table, after
    checking the Python loop's (around InProcessPlant) equals it bit for bit, every column."""
    model, config, traj, _ = loop
    compiled = run_closed_loop(model, config, traj).table
    python = run_closed_loop(model, config, traj, plant=InProcessPlant(model)).table
    for name in compiled.dtype.names:
        assert np.array_equal(compiled[name], python[name]), name
    return compiled


def delayed_loop(model, config, traj, times, sizes, fmpy_start: bool) -> np.ndarray:
    """The in-process loop as an SSP importer runs the two FMUs: the torque of sample k drives
    the plant over the next period; before it the drives hold (libcosim's initial exchange), or
    with fmpy_start tau is 0 and the first sample measures l = ldot = 0 (simulate_ssp's
    connectors start at 0.0). times: the communication points, sizes: the step sizes passed
    with them. Leg lengths after every step, shape (steps, 6)."""
    refs = leg_references(model, traj)
    axis = axis_model(model, config.motor, config.load_mass)
    gains = tune_pid(axis, config.bandwidth, config.phase_margin)
    v_ff, i_ff = feedforward_voltage(model, config, axis, traj, refs)
    ctrl, motors = AxisControllers(gains, axis, config.dt), MotorCurrents(axis, config.dt)
    motors.current, ctrl.integral = equilibrium(model, traj.q[0], traj.qd[0], refs.ldot[0], i_ff[0],
                                                gains, axis)
    applied = np.zeros(6) if fmpy_start else motors.current * config.motor.torque_constant
    plant = InProcessPlant(model)
    plant.start(traj.q[0], traj.qd[0], times[0], applied)
    l, ldot, _ = plant.measure()
    if fmpy_start:
        l, ldot = np.zeros(6), np.zeros(6)
    out = []
    for k in range(len(times) - 1):
        _, torque, _ = servo_step(ctrl, motors, refs.l[k], refs.ldot[k], l, ldot, v_ff[k])
        plant.step(times[k], sizes[k], applied)
        applied = torque
        l, ldot, _ = plant.measure()
        out.append(l.copy())
    return np.array(out)


def test_run_with_delay_is_the_delayed_loop(loop, delayed_run):
    """`run` with [controller] delay = 1 (the C loop and the Python loop, equal: delayed_run) is
    the in-process loop of an SSP importer at `run`'s sample times, bit for bit; and the delay
    is a real one: the lengths differ from delay 0's."""
    model, config, traj, _ = loop
    want = delayed_loop(model, config, traj, list(traj.t), list(np.diff(traj.t)), fmpy_start=False)
    assert np.array_equal(_lengths(delayed_run), want)
    prompt = run_closed_loop(model, dataclasses.replace(config, delay=0), traj).table
    assert not np.array_equal(_lengths(prompt), want)


def test_libcosim_runs_the_loop(loop, delayed_run):
    """libcosim: communication points at integer nanoseconds, t = ns / 1e9 and h = t1 - t0; the
    plant's lengths equal the in-process loop's bit for bit, and so `run`'s with delay 1: its
    points are `run`'s sample times (k / rate, the same doubles), so the figure is 0."""
    model, config, traj, got = loop
    step_ns = round(config.dt * 1e9)
    times = [k * step_ns / 1e9 for k in range(len(traj.t))]
    sizes = [t1 - t0 for t0, t1 in zip(times, times[1:])]
    want = delayed_loop(model, config, traj, times, sizes, fmpy_start=False)
    assert got["libcosim"].shape == want.shape
    assert np.array_equal(got["libcosim"], want)
    assert np.array_equal(np.array(times), traj.t)
    diff = float(np.max(np.abs(got["libcosim"] - _lengths(delayed_run))))
    print(f"libcosim: max |l - run's l (delay 1)| = {diff:.3g} m over {len(times) - 1} steps")
    assert diff <= 1e-9
    assert np.array_equal(got["libcosim"], _lengths(delayed_run))


def test_fmpy_runs_the_loop(loop):
    """FMPy's simulate_ssp: the step size as given, time advanced by adding it; the same bit for
    bit, with its zero start."""
    model, config, traj, got = loop
    times = [0.0]
    for _ in range(len(traj.t) - 1):
        times.append(times[-1] + config.dt)
    want = delayed_loop(model, config, traj, times, [config.dt] * (len(times) - 1), fmpy_start=True)
    assert got["fmpy"].shape == want.shape
    assert np.array_equal(got["fmpy"], want)


def test_against_run(loop, delayed_run):
    """The figures against `run`: with delay 1, FMPy's differ only by its zero start (the first
    period without torque, the first sample seeing l = 0; libcosim's are equal:
    test_libcosim_runs_the_loop); with delay 0 (the plant stepped after the controller within
    a sample) both differ by the SSP exchange's period of delay, not an error of either FMU
    (those equal `run` bit for bit under a master that passes the torque within the sample:
    test_controller_fmu.py)."""
    model, config, traj, got = loop
    prompt = run_closed_loop(model, dataclasses.replace(config, delay=0), traj).table
    for delay, table in ((1, delayed_run), (0, prompt)):
        run_err = np.max(np.abs(np.column_stack([table[f"e{i}"] for i in range(1, 7)])))
        for name, lengths in got.items():
            diff = np.abs(lengths - _lengths(table))
            print(f"{name}: max |l - run's l (delay {delay})| = {np.max(diff):.3g} m, at the end "
                  f"{np.max(diff[-1]):.3g} m (run's own tracking error up to {run_err:.3g} m)")
            assert np.all(np.isfinite(lengths))
