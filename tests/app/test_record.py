"""`stewart-sim run --link ... --truth TRUE.toml --trajectory T.csv --record RUN.csv` and
`stewart-sim device --truth`: the recording's exact columns, the spawned device built from the
truth scene and its [sensors] (the file equals the same run driven in process, bit for bit), the
trajectory taken or resampled at the controller rate, and every refusal in one line (exit 2).
Fixed seeds; no wall clock."""
from __future__ import annotations

import csv
import select
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from controller.config import controller_config  # noqa: E402
from hil.client import (  # noqa: E402
    Client,
    connect_device,
    link_reference,
    run_lockstep,
    run_lockstep_direct,
)
from hil.device import Device  # noqa: E402
from hil.sensors import sensor_config  # noqa: E402
from stewart_fmu.io import trajectory_table, write_csv  # noqa: E402
from stewart_fmu.kinematics import inverse_kinematics  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from stewart_sim import cli  # noqa: E402
from stewart_sim.closed_loop.over_link import link_trajectory, record_table  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
COLUMNS = ["t", *(f"l{i}" for i in range(1, 7)), *(f"sigma{i}" for i in range(1, 7)),
           *(f"current{i}" for i in range(1, 7))]
SENSORS = """
[sensors]
encoder_resolution = 1e-6
force_noise = 0.2
current_noise = 0.001
latency = 0.002
seed = 5
"""
AMPLITUDE = np.array([0.008, 0.008, 0.006, 0.06, 0.06, 0.08])
FREQUENCY = np.array([1.3, 1.7, 2.1, 1.1, 1.9, 2.3])


def write_truth(path: Path, sensors: str = SENSORS, changes: dict[str, str] | None = None
                ) -> Path:
    """The micro-manipulator with its masses and frictions off (and `changes`), `sensors`."""
    text = MICRO.read_text()
    for old, new in {"mass = 0.5\n": "mass = 0.6\n", "viscous = 5.0": "viscous = 6.0",
                     "lower_mass = 0.065": "lower_mass = 0.08", **(changes or {})}.items():
        assert old in text
        text = text.replace(old, new)
    path.write_text(text + sensors)
    return path


def write_trajectory(path: Path, rate: float, duration: float, t0: float = 0.0,
                     start=None) -> tuple[np.ndarray, ...]:
    """q = home + a (1 - cos w t), at rest at home at its first sample (or at `start`)."""
    home = load_scene(MICRO).home if start is None else np.asarray(start)
    t = np.arange(int(round(duration * rate)) + 1) / rate
    w = 2 * np.pi * FREQUENCY
    arg = w * t[:, None]
    q = home + AMPLITUDE * (1 - np.cos(arg))
    qd, qdd = AMPLITUDE * w * np.sin(arg), AMPLITUDE * w**2 * np.cos(arg)
    write_csv(path, trajectory_table(t + t0, q, qd, qdd))
    return t, q, qd, qdd


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("stewart-sim: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    return err


def test_record_from_the_device_with_a_truth_scene(tmp_path, capsys) -> None:
    """The end-to-end path of the identification guide (Recording runs): the spawned device's
    plant and sensors are the truth scene's. RUN.csv has exactly the columns identify reads (and the currents), one row per
    controller period in device time, lengths on the 1 um grid, the first two rows the start
    (latency 2 ticks); and it is the in-process run of a Device built from the same truth and
    [sensors] bit for bit (currents: DRIVE_STATUS carries float32)."""
    truth = write_truth(tmp_path / "truth.toml")
    traj = tmp_path / "T.csv"
    write_trajectory(traj, 1000.0, 0.3)
    run = tmp_path / "RUN.csv"
    assert cli.main(["run", str(MICRO), "--link", "serial", "--truth", str(truth),
                     "--trajectory", str(traj), "--record", str(run), "--out",
                     str(tmp_path / "out"), "--no-view"]) == 0
    out = capsys.readouterr().out
    assert f"wrote {run}" in out and "truth scene" in out
    with run.open(newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == COLUMNS
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (301, 19)
    assert np.allclose(data[:, 0], np.arange(1, 302) / 1000.0, rtol=0, atol=1e-12)
    lengths = data[:, 1:7]
    assert np.max(np.abs(lengths / 1e-6 - np.round(lengths / 1e-6))) < 1e-6
    model = load_scene(MICRO)
    home = np.round(inverse_kinematics(model, model.home).lengths / 1e-6) * 1e-6
    assert np.allclose(lengths[:2], home, rtol=0, atol=1e-12)
    assert not np.allclose(lengths[-1], home, rtol=0, atol=1e-6)

    config = controller_config(model)
    true_model = load_scene(truth)
    ref = link_reference(model, config, link_trajectory(model, config, traj))
    direct = run_lockstep_direct(Device(model, config, lockstep=True, truth=true_model,
                                        sensors=sensor_config(true_model)), ref, currents=True)
    expect = record_table(direct)
    for j, name in enumerate(COLUMNS[:13]):
        assert np.array_equal(data[:, j], expect[name]), name
    for j, name in enumerate(COLUMNS[13:], 13):
        assert np.allclose(data[:, j], expect[name], rtol=1e-6, atol=1e-9), name


def test_the_device_command_serves_the_truth(tmp_path) -> None:
    """`stewart-sim device SCENE --truth TRUE.toml --lockstep`, served to a host of its own:
    what it reports is the in-process device's of the same truth and [sensors], bit for bit."""
    truth = write_truth(tmp_path / "truth.toml")
    write_trajectory(tmp_path / "T.csv", 1000.0, 0.2)
    model = load_scene(MICRO)
    config = controller_config(model)
    ref = link_reference(model, config, link_trajectory(model, config, tmp_path / "T.csv"))
    proc = subprocess.Popen([sys.executable, "-m", "stewart_sim", "device", str(MICRO), "--udp",
                             "127.0.0.1:0", "--lockstep", "--truth", str(truth)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert select.select([proc.stdout], [], [], 60)[0], "the device printed nothing"
        transport, _ = connect_device("udp", proc.stdout.readline().strip())
        client = Client(transport)
        try:
            served = run_lockstep(client, ref, timeout=1.0, currents=True)
        finally:
            client.close()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
        assert proc.returncode == 0, err
        assert f"plant from {truth}" in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    true_model = load_scene(truth)
    direct = run_lockstep_direct(Device(model, config, lockstep=True, truth=true_model,
                                        sensors=sensor_config(true_model)), ref, currents=True)
    got, expect = record_table(served), record_table(direct)
    for name in COLUMNS[:13]:
        assert np.array_equal(got[name], expect[name]), name


def test_link_trajectory_at_the_rate_or_resampled(tmp_path) -> None:
    """A file at the controller rate is taken as it is (from t = 0); one at 500 Hz is resampled
    to 1 kHz by quintic Hermite interpolation: the poses, rates and accelerations of the
    analytic curve to 1e-9 of their peaks (the interpolation errs by O((w h)^6))."""
    model = load_scene(MICRO)
    config = controller_config(model)
    t, q, qd, qdd = write_trajectory(tmp_path / "a.csv", 1000.0, 0.5, t0=5.0)
    got = link_trajectory(model, config, tmp_path / "a.csv")
    assert np.array_equal(got.q, q) and np.array_equal(got.qdd, qdd)
    assert np.array_equal(got.t, np.arange(t.size) / 1000.0)
    write_trajectory(tmp_path / "b.csv", 500.0, 0.5)
    got = link_trajectory(model, config, tmp_path / "b.csv")
    assert got.t.size == 501 and got.t[-1] == pytest.approx(0.5, abs=1e-12)
    w = 2 * np.pi * FREQUENCY
    arg = w * got.t[:, None]
    for value, exact in ((got.q, model.home + AMPLITUDE * (1 - np.cos(arg))),
                         (got.qd, AMPLITUDE * w * np.sin(arg)),
                         (got.qdd, AMPLITUDE * w**2 * np.cos(arg))):
        assert np.max(np.abs(value - exact)) <= 1e-9 * np.max(np.abs(exact))


def test_scene_info_shows_the_sensors(tmp_path, capsys) -> None:
    assert cli.main(["scene-info", str(write_truth(tmp_path / "truth.toml"))]) == 0
    assert ("sensors: encoder 1e-06 m, force noise 0.2 N, current noise 0.001 A, latency "
            "0.002 s, seed 5") in capsys.readouterr().out
    assert cli.main(["scene-info", str(MICRO)]) == 0
    assert "sensors: ideal" in capsys.readouterr().out


def test_refusals_are_one_line(tmp_path, capsys) -> None:
    traj = tmp_path / "T.csv"
    write_trajectory(traj, 1000.0, 0.1)
    out = str(tmp_path / "out")
    base = ["run", str(MICRO), "--out", out]
    link = base + ["--link", "serial"]
    bad_home = write_truth(tmp_path / "home.toml",
                           changes={"home = [0.0, 0.0, 0.12,": "home = [0.0, 0.0, 0.121,"})
    late = write_truth(tmp_path / "late.toml", sensors="[sensors]\nlatency = 0.0015\n")
    noisy = write_truth(tmp_path / "noisy.toml", sensors="[sensors]\nforce_noise = -1.0\n")
    typo = write_truth(tmp_path / "typo.toml", sensors="[sensors]\nseeds = 3\n")
    odd = tmp_path / "odd.csv"
    write_trajectory(odd, 1000.0, 0.1, start=load_scene(MICRO).home + [0, 0, 0.001, 0, 0, 0])
    cases = [
        (link + ["--truth", str(bad_home)], "scene key 'geometry.home': differs from the scene's"),
        (link + ["--truth", str(tmp_path / "none.toml")], "no such scene file"),
        (link + ["--truth", str(late)], "scene key 'sensors.latency': must be a whole number"),
        (link + ["--truth", str(noisy)], "scene key 'sensors.force_noise': must be a finite"),
        (["scene-info", str(noisy)], "scene key 'sensors.force_noise'"),
        (["scene-info", str(typo)], "scene key 'sensors.seeds': unknown key"),
        (base + ["--record", str(tmp_path / "R.csv")], "--record needs --link"),
        (base + ["--truth", str(late)], "--truth needs --link"),
        (link + ["--mode", "realtime", "--record", str(tmp_path / "R.csv")],
         "--record needs --mode lockstep"),
        (link + ["--record", str(tmp_path)], "is a directory"),
        (link + ["--trajectory", str(traj), "--duration", "1"], "exclude each other"),
        (link + ["--trajectory", str(odd)], "starts at rest at the home pose"),
        (["device", str(MICRO), "--pty", "--truth", str(bad_home)], "geometry.home"),
    ]
    for argv, words in cases:
        assert cli.main(argv) == 2, argv
        err = one_error_line(capsys)
        assert words in err, (argv, err)
    assert not (tmp_path / "out").exists() and not (tmp_path / "R.csv").exists()
