"""`cue` and `size` warn when a motion's content reaches the first mode
(stewart_sim/cueing/resonance.py): the content's share against Parseval on sines of known
amplitude, the first mode against stewart_fmu.stiffness pose by pose, a motion near the mode
warned on stderr and in the report, a slow one and the shipped ones not, a scene without
[stiffness] silent."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import io, load_scene
from stewart_fmu import stiffness as S
from stewart_sim import cli
from stewart_sim.cueing.motion import VehicleMotion, read_motion, write_motion
from stewart_sim.cueing.resonance import BAND, SIGNIFICANT, resonance
from stewart_sim.cueing.study import cue_study
from stewart_sim.scene.load import scene_of
from stewart_sim.shell.markdown import md_text

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"
MOTIONS = sorted((ROOT / "scenes" / "motions").glob("*.csv"))
DT = 0.002                          # s: 500 Hz, the Nyquist frequency well above the mode
T = np.arange(2001) * DT            # 4 s
# two sines 20 Hz apart under a sin^2 envelope over 4 s: each spectrum spans +-0.5 Hz, their
# cross term and the tails across the edge are below 1e-9 of the energy
SEPARATE = 1e-8


@pytest.fixture(scope="module")
def model():
    return load_scene(SIM)


def _vertical(model, parts) -> tuple[np.ndarray, ...]:
    """Home plus sum of A sin(2 pi f t) along z (each a whole number of cycles over T)."""
    q, qd, qdd = (np.tile(model.home, (T.size, 1)) * k for k in (1.0, 0.0, 0.0))
    for a, f in parts:
        w = 2 * np.pi * f
        q[:, 2] += a * np.sin(w * T)
        qd[:, 2] += a * w * np.cos(w * T)
        qdd[:, 2] -= a * w**2 * np.sin(w * T)
    return T, q, qd, qdd


def test_the_share_above_the_edge_is_parsevals(model):
    """At home, a vertical acceleration of two sines under a sin^2 envelope, one below f1 /
    sqrt(2), one above: the share of the energy above is the upper one's energy summed over
    time (Parseval; the legs' accelerations are u_z z'' at rest, the same weight for both)."""
    env = np.sin(np.pi * T / T[-1]) ** 2
    parts = [env * a * np.sin(2 * np.pi * f * T) for a, f in ((0.03, 2.0), (0.2, 22.0))]
    q, qd, qdd = np.tile(model.home, (T.size, 1)), np.zeros((T.size, 6)), np.zeros((T.size, 6))
    qdd[:, 2] = parts[0] + parts[1]
    r = resonance(model, T, q, qd, qdd)
    energy = [float(np.sum(p**2)) for p in parts]
    assert r.fraction == pytest.approx(energy[1] / sum(energy), rel=SEPARATE)
    assert r.edge_hz == pytest.approx(BAND * S.modes(model, model.home).frequency_hz[0], rel=1e-13)
    assert 2.0 < r.edge_hz < 22.0 and r.reaches and r.nyquist_hz == pytest.approx(0.5 / DT)
    qdd[:, 2] = parts[0]
    assert resonance(model, T, q, qd, qdd).fraction < 1e-9


def test_the_first_mode_is_the_lowest_over_the_poses(model):
    """A vertical motion: the first mode the lowest of stewart_fmu.stiffness.modes over its
    poses, at its time, every pose counted."""
    t, q, qd, qdd = _vertical(model, ((0.2, 0.5),))
    r = resonance(model, t, q, qd, qdd)
    f1 = [S.modes(model, p).frequency_hz[0] for p in q]
    k = int(np.argmin(f1))
    assert r.lowest_hz == pytest.approx(f1[k], rel=1e-13) and r.lowest_t == t[k]
    assert r.poses == T.size and not r.reaches


def test_a_scene_without_stiffness_says_nothing(model):
    from dataclasses import replace

    assert resonance(replace(model, stiffness=None), *_vertical(model, ((1e-5, 22.0),))) is None


def test_legs_that_buckle_are_a_warning(model):
    """Legs too soft for the platform's weight (1e3 N/m against some 2.5 kN a leg over 2.5 m:
    the loads' geometric term wins): the warning says so, as stewart_fmu.stiffness does."""
    from dataclasses import replace

    soft = replace(model, stiffness=replace(model.stiffness, leg=1e3))
    with pytest.raises(S.UnstablePoseError):
        S.modes(soft, model.home)
    r = resonance(soft, *_vertical(model, ((1e-5, 22.0),)))
    assert r.reaches and "buckle the legs" in r.line("m") and r.line("m").startswith("warning: m:")


def _warnings(err: str) -> list[str]:
    """The warning lines of stderr (a slow machine adds the progress line: shell.progress)."""
    return [line for line in err.replace("\r", "\n").splitlines() if line.startswith("warning")]


def _vehicle(path: Path, f: float, a: float) -> Path:
    """fx = a sin(2 pi f t) under a sin^2 envelope over 3 s: a smooth onset."""
    env = np.where((T > 0.5) & (T < 3.5), np.sin(np.pi * (T - 0.5) / 3.0) ** 2, 0.0)
    fx = a * env * np.sin(2 * np.pi * f * T)
    write_motion(path, VehicleMotion(T, np.column_stack([fx, 0 * T, 9.81 + 0 * T]),
                                     np.zeros((T.size, 3))))
    return path


@pytest.mark.parametrize("f,warns", [(22.0, True), (2.0, False)])
def test_cue_warns_on_stderr_and_in_the_summary(model, tmp_path, capsys, f, warns):
    """0.5 m/s^2 at 22 Hz: over 99.9 % of the energy at or above f1 / sqrt(2); at 2 Hz under
    1e-9 (the guide's figures)."""
    motion = _vehicle(tmp_path / "v.csv", f, 0.5)
    (r,) = cue_study(scene_of(model), read_motion(motion)).resonance
    assert r.fraction > 0.999 if warns else r.fraction < 1e-9
    assert cli.main(["cue", str(SIM), "--motion", str(motion), "--out", str(tmp_path / "o"),
                     "--no-view"]) == 0
    err = _warnings(capsys.readouterr().err)
    summary = (tmp_path / "o" / "summary.md").read_text()
    if warns:
        assert len(err) == 1 and err[0].startswith("warning: the classical cue reaches the first")
        assert "## First mode ([stiffness]): reached" in summary and md_text(err[0]) in summary
    else:
        assert err == []
        assert "## First mode ([stiffness]): not reached" in summary
        assert "the classical cue stays below the first mode" in summary


def test_cue_on_a_scene_without_stiffness_says_nothing(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(SIM.read_text().replace("[stiffness]\nleg = 5.0e7", ""))
    motion = _vehicle(tmp_path / "v.csv", 22.0, 0.5)
    assert cli.main(["cue", str(scene), "--motion", str(motion), "--out", str(tmp_path / "o"),
                     "--no-view"]) == 0
    assert _warnings(capsys.readouterr().err) == []
    assert "First mode" not in (tmp_path / "o" / "summary.md").read_text()


def test_size_warns_for_the_motion_that_reaches_the_mode(model, tmp_path, capsys):
    paths = []
    for name, parts in (("fast", ((1e-5, 22.0),)), ("slow", ((2e-3, 1.0),))):
        paths.append(tmp_path / f"{name}.csv")
        io.write_csv(paths[-1], io.trajectory_table(*_vertical(model, parts)))
    assert cli.main(["size", str(SIM), "--motions", *map(str, paths),
                     "--out", str(tmp_path / "o")]) == 0
    err = _warnings(capsys.readouterr().err)
    assert len(err) == 1 and err[0].startswith(f"warning: {paths[0]} reaches the first mode")
    report = (tmp_path / "o" / "report.md").read_text()
    assert "## First mode ([stiffness]): reached" in report and md_text(err[0]) in report
    assert md_text(f"{paths[1]} stays below the first mode") in report


@pytest.mark.parametrize("path", MOTIONS, ids=lambda p: p.stem)
def test_the_shipped_motions_stay_below_the_first_mode(model, path):
    """The guide's figures: the classical cue of every shipped motion keeps under 0.6 % of its
    energy at or above f1 / sqrt(2) (the onsets' tail), below SIGNIFICANT."""
    (r,) = cue_study(scene_of(model), read_motion(path)).resonance
    assert r.fraction < 0.006 < SIGNIFICANT and not r.reaches


def test_a_rate_limited_tilt_reaches_the_mode_by_its_steps(model, tmp_path):
    """A 1 Hz, 1 m/s^2 fx switched on for 2 s: the tilt coordination runs into its rate limit,
    whose switching steps the angular acceleration; the tail of those steps holds 2.9 % of the
    energy at or above f1 / sqrt(2) (the guide's figure)."""
    fx = np.where((T > 1) & (T < 3), np.sin(2 * np.pi * (T - 1)), 0.0)
    motion = VehicleMotion(T, np.column_stack([fx, 0 * T, 9.81 + 0 * T]), np.zeros((T.size, 3)))
    (r,) = cue_study(scene_of(model), motion).resonance
    assert r.reaches and f"{100 * r.fraction:.2g}" == "2.9"

