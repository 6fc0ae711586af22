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
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description

from controller.axis import AxisControllers, MotorCurrents, servo_step
from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.design import tune_pid
from controller.drive import axis_model
from controller.feedforward import equilibrium, feedforward_voltage
from controller.fmu import Bound, parameter_ranges, table_rows
from controller.moves import run_reference
from controller.plants import InProcessPlant
from controller.ssp import LEGS, RANGE, RANGE_TYPE, SSC, SSV, ParameterRangeError, export_ssp, range_of
from controller.ssp_check import SspError, check_ssp
from controller.trajectory import leg_references
from stewart_fmu import load_scene, table

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
DURATION = 0.3

# libcosim on an archive whose parameter an FMU refuses: the child says "ran" only if it returns
LIBCOSIM_CHILD = r"""
import sys
sys.path.append(sys.argv[1])
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
log_output_level(CosimLogLevel.ERROR)
execution = CosimExecution.from_ssp_file(sys.argv[2])
print("loaded", flush=True)
print("ran", execution.step(1), flush=True)
"""

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
    proc = subprocess.run([sys.executable, "-I", "-S", "-c", CHILD, sysconfig.get_paths()["purelib"],
                           str(ssp), str(steps), repr(config.dt)],
                          cwd=work, env=_child_env(), capture_output=True, text=True, timeout=600)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-2000:] + proc.stderr[-4000:]
    got = {k: np.array(v) for k, v in json.loads(lines[-1][7:]).items()}
    return model, config, traj, got, ssp


def _lengths(table: np.ndarray) -> np.ndarray:
    """The leg lengths after every step of a `run` table (its samples 1..n-1), shape (steps, 6)."""
    return np.column_stack([table[f"l{i}"] for i in range(1, 7)])[1:]


@pytest.fixture(scope="module")
def delayed_run(loop):
    """`run`'s closed loop of the scene with [controller] delay = 1: the C loop's table, after
    checking the Python loop's (around InProcessPlant) equals it bit for bit, every column."""
    model, config, traj, _, _ = loop
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
    model, config, traj, _, _ = loop
    want = delayed_loop(model, config, traj, list(traj.t), list(np.diff(traj.t)), fmpy_start=False)
    assert np.array_equal(_lengths(delayed_run), want)
    prompt = run_closed_loop(model, dataclasses.replace(config, delay=0), traj).table
    assert not np.array_equal(_lengths(prompt), want)


def test_libcosim_runs_the_loop(loop, delayed_run):
    """libcosim: communication points at integer nanoseconds, t = ns / 1e9 and h = t1 - t0; the
    plant's lengths equal the in-process loop's bit for bit, and so `run`'s with delay 1: its
    points are `run`'s sample times (k / rate, the same doubles), so the figure is 0."""
    model, config, traj, got, _ = loop
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
    model, config, traj, got, _ = loop
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
    model, config, traj, got, _ = loop
    prompt = run_closed_loop(model, dataclasses.replace(config, delay=0), traj).table
    for delay, table in ((1, delayed_run), (0, prompt)):
        run_err = np.max(np.abs(np.column_stack([table[f"e{i}"] for i in range(1, 7)])))
        for name, lengths in got.items():
            diff = np.abs(lengths - _lengths(table))
            print(f"{name}: max |l - run's l (delay {delay})| = {np.max(diff):.3g} m, at the end "
                  f"{np.max(diff[-1]):.3g} m (run's own tracking error up to {run_err:.3g} m)")
            assert np.all(np.isfinite(lengths))


def _child_env() -> dict[str, str]:
    return {k: v for k, v in __import__("os").environ.items() if not k.startswith("PYTHON")}


def _edited(ssp: Path, out: Path, ssv: str, name: str, value: str, add: bool = False) -> Path:
    """A copy of the archive with one value of resources/<ssv>.ssv changed (or, with add, a
    parameter added without a declared range)."""
    with zipfile.ZipFile(ssp) as z, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as o:
        for info in z.infolist():
            data = z.read(info.filename)
            if info.filename == f"resources/{ssv}.ssv":
                if add:
                    new = (f'<ssv:Parameter name="{name}"><ssv:Real value="{value}" /></ssv:Parameter>'
                           f'</ssv:Parameters>')
                    data, n = data.replace(b"</ssv:Parameters>", new.encode()), 1
                else:
                    pattern = rf'(<ssv:Parameter name="{re.escape(name)}">\s*<ssv:Real value=")[^"]*"'
                    data, n = re.subn(pattern.encode(), rb"\g<1>" + value.encode() + b'"', data)
                assert n == 1, name
            o.writestr(info, data)
    return out


def _ranges(ssv: bytes) -> dict[str, tuple[float, Bound | None]]:
    """A parameter set's values and declared ranges (None: no annotation), by name."""
    out = {}
    for p in ElementTree.fromstring(ssv).iter(f"{{{SSV}}}Parameter"):
        value = float(p.find(f"{{{SSV}}}Real").get("value"))
        notes = [n for n in p.iter(f"{{{SSC}}}Annotation") if n.get("type") == RANGE_TYPE]
        assert len(notes) <= 1
        out[p.get("name")] = (value, range_of(notes[0].find(f"{{{RANGE}}}Range")) if notes else None)
    return out


def test_parameter_sets_declare_the_tables_ranges(loop, tmp_path):
    """Each parameter set is valid SSP 1.0 (FMPy's schema) and carries, per parameter, the range
    of the tables (stewart_table.h's bounds, an open one's min excluded, sigma's input range;
    axis_table.h's AXIS_FMU_PARAMETER_RANGES, none for integral0 and current0), equal to the
    min and max its FMU declares; the plant's set holds every Real parameter of the plant FMU;
    both FMUs pass FMPy's validation."""
    from fmpy.ssp.ssd import read_ssv
    from fmpy.validation import validate_fmu

    ssp = loop[4]
    groups = {g.name: g for g in table.VARIABLES}
    ident = {name: i for i, name, *_ in table_rows()["PARAMETERS"]}
    bounds = parameter_ranges()
    with zipfile.ZipFile(ssp) as z:
        z.extractall(tmp_path)
    for component in ("plant", "controller"):
        path = tmp_path / "resources" / f"{component}.ssv"
        assert len(read_ssv(str(path)).parameters) > 0   # validates against the SSP 1.0 schema
        assert validate_fmu(str(tmp_path / "resources" / f"{component}.fmu")) == []
        md = {v.name: v for v in read_model_description(str(tmp_path / "resources" / f"{component}.fmu"))
              .modelVariables}
        declared = _ranges(path.read_bytes())
        if component == "plant":
            real = {n for n, v in md.items() if v.causality == "parameter" and v.type == "Real"}
            assert real <= set(declared) and set(declared) - real == {f"sigma[{i}]" for i in LEGS}
        for name, (value, got) in declared.items():
            v = md[name]
            if component == "plant":
                g = groups[name.partition("[")[0]]
                lo, hi = table.INPUT_RANGES[g.id] if g.causality == "input" else (g.min, g.max)
                want = Bound(g.bound == table.BOUND_OPEN, lo, hi)
            else:
                want = bounds.get(ident[name.partition("[")[0]])
            assert got == want, name
            if want is None:
                assert v.min is None and v.max is None, name
                continue
            assert float(v.min) == want.min, name
            assert v.max is None if np.isinf(want.max) else float(v.max) == want.max, name
            assert want.reason(value) is None, name


def test_the_check_refuses_what_the_fmu_would(loop, tmp_path, capsys):
    """check_ssp (`check-ssp`) passes the exported archive and refuses, in one line naming the
    parameter and the bound and before any FMU is instantiated, a value the FMU refuses at
    initialisation: platform.mass = -1 (below the FMU's min), 0 (the min itself, which the
    annotation excludes as the FMU does: the model description's inclusive min alone would
    pass it), a gain below 0, NaN, a name the FMU does not have."""
    from stewart_sim import cli

    ssp = loop[4]
    result = check_ssp(ssp)
    assert result.components == ("plant", "controller") and result.parameters > 100
    cases = [("plant", "platform.mass", "-1", "must be a finite number >= 0, got -1.0"),
             ("plant", "platform.mass", "0", "must be a finite number > 0, got 0.0"),
             ("plant", "q0[3]", "1e4", "must be <= 1000, got 10000.0"),
             ("controller", "kp", "-2", "must be a finite number >= 0, got -2.0"),
             ("controller", "current0[2]", "NaN", "must be a finite number, got nan")]
    for k, (ssv, name, value, reason) in enumerate(cases):
        words = f"resources/{ssv}.ssv: parameter {ssv}.{name} {reason}"
        bad = _edited(ssp, tmp_path / f"bad{k}.ssp", ssv, name, value)
        with pytest.raises(ParameterRangeError) as err:
            check_ssp(bad)
        assert words in str(err.value) and "\n" not in str(err.value), str(err.value)
        assert cli.main(["check-ssp", str(bad)]) == 2
        said = capsys.readouterr()
        assert said.out == "" and said.err.count("\n") == 1 and words in said.err, said
    unknown = _edited(ssp, tmp_path / "unknown.ssp", "plant", "platform.masss", "1", add=True)
    with pytest.raises(SspError, match=r"plant.platform.masss is no Real parameter or input"):
        check_ssp(unknown)
    assert cli.main(["check-ssp", str(ssp)]) == 0
    assert "within their declared ranges" in capsys.readouterr().out


def test_libcosim_aborts_on_an_fmu_error_at_initialisation(loop, tmp_path):
    """What the FMU and SSP guide says libcosim does with platform.mass = -1 in the archive (run
    in a child process, whose abort cannot take pytest down): the plant FMU answers fmi2Error in
    initialisation mode and libcosim throws cosim::error on a worker thread: std::terminate,
    SIGABRT (exit 134 from a shell, -6 here), the step never returns. check_ssp refuses the
    archive first (test_the_check_refuses_what_the_fmu_would)."""
    bad = _edited(loop[4], tmp_path / "mass.ssp", "plant", "platform.mass", "-1")
    proc = subprocess.run([sys.executable, "-I", "-S", "-c", LIBCOSIM_CHILD,
                           sysconfig.get_paths()["purelib"], str(bad)],
                          cwd=tmp_path, env=_child_env(), capture_output=True, text=True, timeout=300)
    last = proc.stderr.strip().splitlines()[-1]
    print(f"libcosim on platform.mass = -1: exit {proc.returncode}; {last}")
    assert proc.returncode == -signal.SIGABRT and "loaded" in proc.stdout and "ran" not in proc.stdout
    assert "cosim::error" in proc.stderr and "parameters set so far are not valid" in proc.stderr


def test_export_refuses_a_value_out_of_range(loop, tmp_path):
    """export_ssp refuses a parameter set whose value breaks its declared range in one line
    naming it, before any work: an existing file at the path is kept as it was."""
    model, config, traj, _, _ = loop
    far = traj.q.copy()
    far[0, 2] = 2e3   # q0[3] beyond the pose's 1 km bound
    out = tmp_path / "far.ssp"
    out.write_bytes(b"kept")
    with pytest.raises(ParameterRangeError) as err:
        export_ssp(model, SCENE.read_bytes(), config, dataclasses.replace(traj, q=far), out)
    assert str(err.value) == "export-ssp: parameter plant.q0[3] must be <= 1000, got 2000.0"
    assert out.read_bytes() == b"kept"
