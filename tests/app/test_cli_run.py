"""`stewart-sim run` and `stewart-sim compare` (stewart_sim.cli), called in-process through
main([...]): the files they write, the summary against the ClosedLoopResult, the FMU plant
against the in-process plant, and the errors."""
from __future__ import annotations

import contextlib
import csv
import io
import re
from pathlib import Path

import numpy as np
import pytest

from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.moves import run_reference
from stewart_fmu import load_scene
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.io import POSE
from stewart_sim import cli
from stewart_sim.closed_loop import run_files
from tests.helpers import host_binary_only

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
SIM = ROOT / "scenes" / "motion_simulator.toml"
# Short runs that stay inside each drive's limits (the out-and-back move takes 30 % of it).
DURATION = {MICRO: 1.0, SIM: 4.0}
PNGS = ("run_tracking.png", "run_errors.png", "run_forces.png")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array([[float(c) for c in row] for row in rows[1:]])


def table_rows(text: str, first: str) -> list[str]:
    """The cells of the markdown table row whose first cell is `first`."""
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] == first:
            return cells[1:]
    raise AssertionError(f"no table row '{first}' in the summary")


def g6(x: float) -> str:
    return f"{x:.6g}"


@pytest.fixture(scope="module")
def micro_fmu(tmp_path_factory) -> Path:
    """The micro-manipulator exported as an FMU (once for the module; run here: its host
    binary only)."""
    with host_binary_only():
        return export_fmu(MICRO, tmp_path_factory.mktemp("fmu") / "plant.fmu")


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    """`run` of a scene with its defaults (run_cli), once for the module: (folder, what it
    printed). Three tests read the micro scene's: its files, the feedforward mode's run (the
    scene's is kane), and the in-process run the FMU's is compared with."""
    folder, done = tmp_path_factory.mktemp("runs"), {}

    def get(scene: Path) -> tuple[Path, str]:
        if scene not in done:
            out, printed = folder / scene.stem, io.StringIO()
            with contextlib.redirect_stdout(printed):
                assert run_cli(scene, out) == 0
            done[scene] = out, printed.getvalue()
        return done[scene]
    return get


def run_cli(scene: Path, out: Path, *extra: str) -> int:
    return cli.main(["run", str(scene), "--out", str(out), "--duration",
                     str(DURATION.get(scene, 1.0)), *extra])


# --- run -------------------------------------------------------------------------------------

@pytest.mark.parametrize("scene", [MICRO, SIM], ids=["micro", "sim"])
def test_run_writes_files_and_summary_equals_result(scene, default_run) -> None:
    """run.csv is the result's table; summary.md (printed too) has the result's numbers."""
    out, printed = default_run(scene)
    for name in run_files.RUN_FILES:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
        assert f"wrote {out / name}" in printed
    for name in PNGS:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    model = load_scene(scene)
    config = controller_config(model)
    traj = run_reference(model, config, DURATION[scene])
    result = run_closed_loop(model, config, traj)

    header, values = read_csv(out / "run.csv")
    assert header == list(result.table.dtype.names)
    assert np.array_equal(values, np.column_stack([result.table[n] for n in header]))

    summary = (out / "summary.md").read_text(encoding="utf-8")
    assert summary in printed
    assert f"- feedforward: {config.feedforward}" in summary
    s, a, g, ax = result.summary, result.analysis, result.gains, result.axis
    for i in range(6):
        assert table_rows(summary, str(i + 1)) == [g6(s.leg_rms[i]), g6(s.leg_max[i]),
                                                   g6(s.voltage_rms[i]), g6(s.current_max[i])]
    for k, name in enumerate(POSE):
        assert table_rows(summary, name)[1:] == [g6(s.pose_rms[k]), g6(s.pose_max[k])]
    for label, value in (("Kp (V/m)", g.kp), ("Ki (V/(m s))", g.ki), ("Kd (V s/m)", g.kd),
                         ("phase margin (deg)", a.phase_margin_deg),
                         ("gain margin (dB)", a.gain_margin_db), ("crossover (Hz)", a.crossover_hz),
                         ("step rise time 10-90 % (s)", a.rise_time),
                         ("step overshoot (%)", a.overshoot_pct),
                         ("step settling time 2 % (s)", a.settling_time),
                         ("constant load m_load (kg)", ax.load_mass),
                         ("reflected drive inertia m_d (kg)", ax.reflected_mass)):
        assert table_rows(summary, label) == [g6(value)], label
    assert f"- saturated time: {g6(s.saturated_time)} s of {g6(traj.t[-1])} s" in summary
    assert re.search(r"- wall time: \S+ s; real-time factor: \S+", summary)
    assert f"peak current: {g6(np.max(s.current_max))} A" in summary


def test_summary_states_an_actuation_delay() -> None:
    """A run with [controller] delay = 1 says so in summary.md (one line); without, no line."""
    import dataclasses

    model = load_scene(MICRO)
    for delay in (0, 1):
        config = dataclasses.replace(controller_config(model), delay=delay)
        traj = run_reference(model, config, 0.3)
        text = run_files.run_summary(model, run_closed_loop(model, config, traj), traj, "in-process")
        lines = [ln for ln in text.splitlines() if ln.startswith("- actuation delay:")]
        assert lines == ([] if delay == 0 else [
            "- actuation delay: 1 controller period (controller.delay: each sample's torque "
            "drives the period after it)"])


def test_run_feedforward_override(default_run, tmp_path, capsys) -> None:
    """--feedforward replaces the scene's mode (kane) and changes the run."""
    kane_run, _ = default_run(MICRO)
    assert "- feedforward: kane" in (kane_run / "summary.md").read_text()
    assert run_cli(MICRO, tmp_path / "none", "--feedforward", "none") == 0
    assert "- feedforward: none" in (tmp_path / "none" / "summary.md").read_text()
    _, kane = read_csv(kane_run / "run.csv")
    header, none = read_csv(tmp_path / "none" / "run.csv")
    e = [header.index(f"e{i}") for i in range(1, 7)]
    assert np.max(np.abs(none[:, e])) > 10 * np.max(np.abs(kane[:, e]))
    v_ff = [header.index(f"v_ff{i}") for i in range(1, 7)]
    assert not np.any(none[:, v_ff])


def test_run_fmu_equals_in_process(micro_fmu, default_run, tmp_path, capsys) -> None:
    """The same run through the exported FMU (fmpy) gives the in-process run.csv to 1e-9."""
    assert run_cli(MICRO, tmp_path / "fmu", "--fmu", str(micro_fmu)) == 0
    assert "plant: FMU" in (tmp_path / "fmu" / "summary.md").read_text()
    local, _ = default_run(MICRO)
    assert "plant: in-process plant" in (local / "summary.md").read_text()
    h_fmu, fmu = read_csv(tmp_path / "fmu" / "run.csv")
    h_loc, loc = read_csv(local / "run.csv")
    assert h_fmu == h_loc and fmu.shape == loc.shape
    assert np.max(np.abs(fmu - loc)) <= 1e-9


@pytest.mark.parametrize("command", ["run", "compare"])
def test_help(command, capsys) -> None:
    """--help prints the usage and exits 0."""
    assert cli.main([command, "--help"]) == 0
    assert f"usage: stewart-sim {command}" in capsys.readouterr().out


# --- errors ----------------------------------------------------------------------------------

def _scene_text(replace: dict[str, str]) -> str:
    text = MICRO.read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    return text


@pytest.mark.parametrize("case", ["no_controller", "design", "fmu_of_other_scene", "not_fmu",
                                  "missing_fmu", "too_short"])
def test_run_errors_exit_2(case, micro_fmu, tmp_path, capsys) -> None:
    """Bad inputs print `stewart-sim: error: ...` and exit 2, writing nothing."""
    scene, extra = MICRO, []
    if case == "no_controller":
        scene = tmp_path / "scene.toml"
        text = MICRO.read_text()
        scene.write_text(text[:text.index("[controller]")])
    elif case == "design":  # no PID reaches this crossover: DesignError
        scene = tmp_path / "scene.toml"
        scene.write_text(_scene_text({"bandwidth = 20.0": "bandwidth = 2000.0"}))
    elif case == "fmu_of_other_scene":
        scene, extra = SIM, ["--fmu", str(micro_fmu)]
    elif case == "not_fmu":
        extra = ["--fmu", str(MICRO)]
    elif case == "missing_fmu":
        extra = ["--fmu", str(tmp_path / "nothing.fmu")]
    elif case == "too_short":
        extra = ["--duration", "0.001"]
    out = tmp_path / "out"
    status = cli.main(["run", str(scene), "--out", str(out), *extra])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith("stewart-sim: error: ")
    assert not (out / "run.csv").exists()


# --- compare ---------------------------------------------------------------------------------

def test_compare_writes_files(tmp_path, capsys) -> None:
    """A reduced sweep (2 points + each scene's own gear ratio) of both scenes."""
    out = tmp_path / "cmp"
    assert cli.main(["compare", str(MICRO), str(SIM), "--out", str(out), "--points", "2"]) == 0
    printed = capsys.readouterr().out
    for name in ("comparison.csv", "comparison.png", "report.md"):
        assert f"wrote {out / name}" in printed
        assert (out / name).stat().st_size > 0
    assert (out / "comparison.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with (out / "comparison.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 * 3 * 3  # scenes x (2 points + own ratio) x feedforward modes
    assert {r["mode"] for r in rows} == {"none", "constant_load", "kane"}
    assert all(r["status"] == "ok" for r in rows)
    swept = sorted({(r["scene"], float(r["md_over_mload"])) for r in rows if r["nominal"] == "0"})
    assert [ratio for _, ratio in swept] == pytest.approx([0.1, 100.0, 0.1, 100.0])
    nominal = {r["scene"]: r for r in rows if r["nominal"] == "1"}
    # the paper's claim: drive inertia dominates on the micro-manipulator, not on the simulator
    assert nominal["micro-manipulator"]["regime"] == "holds"
    assert float(nominal["micro-manipulator"]["coupling"]) < 0.1
    assert float(nominal["motion-simulator"]["coupling"]) > 1.0
    for r in rows:  # coupling = C / (m_load + m_d) with the same C along a scene's sweep
        c = float(r["coupling"]) * (float(r["m_load"]) + float(r["m_d"]))
        same = [float(o["coupling"]) * (float(o["m_load"]) + float(o["m_d"]))
                for o in rows if o["scene"] == r["scene"]]
        assert c == pytest.approx(same[0], rel=1e-12)
    report = (out / "report.md").read_text(encoding="utf-8")
    for text in ("## micro-manipulator", "## motion-simulator",
                 "## Where the paper's claim holds and where it breaks"):
        assert text in report
