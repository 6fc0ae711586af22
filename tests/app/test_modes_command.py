"""`stewart-sim modes` (stewart_sim/commands/modes.py, stewart_sim/studies/modes): the contract's
modes.csv, the stiffness table, --payload, --map, and bad input refused in one line (exit 2)
with nothing already written lost."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_fmu import stiffness as S
from stewart_sim import cli

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "scenes" / "motion_simulator.toml"


def _read(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_modes_csv_is_the_contract_and_the_stiffness_table_the_pivots(tmp_path, capsys):
    """modes.csv: first columns mode,frequency_hz, six rows ascending, the damping ratio (the
    scene has [friction]), the shape and leg rates, every number repr-exact as the API gives
    it; stiffness.csv: N/um and N m/urad per axis at the pivot."""
    out = tmp_path / "m"
    pose = "0.05,-0.02,2.35,0.02,-0.03,0.04"
    assert cli.main(["modes", str(SIM), "--pose", pose, "--pivot", "0,0,0.5", "--out", str(out)]) == 0
    head, rows = _read(out / "modes.csv")
    assert head[:3] == ["mode", "frequency_hz", "damping_ratio"]
    assert len(rows) == 6 and [r[0] for r in rows] == ["1", "2", "3", "4", "5", "6"]
    model = load_scene(SIM)
    q = np.array([float(v) for v in pose.split(",")])
    m = S.modes(model, q)
    f = np.array([float(r[1]) for r in rows])
    assert np.all(np.diff(f) >= 0) and np.array_equal(f, m.frequency_hz)
    assert np.array_equal([float(r[2]) for r in rows], m.damping)
    assert np.array_equal(np.array([[float(c) for c in r[3:9]] for r in rows]), m.shapes)
    head, rows = _read(out / "stiffness.csv")
    s = S.stiffness(model, q, [0.0, 0.0, 0.5])
    assert [r[0] for r in rows] == ["x", "y", "z", "thx", "thy", "thz"]
    assert [r[2] for r in rows] == ["N/um"] * 3 + ["N.m/urad"] * 3
    assert np.allclose([float(r[1]) for r in rows], s.axis_stiffness * 1e-6, rtol=1e-14)
    assert "mode 1" in capsys.readouterr().out


def test_payload_lowers_the_modes_and_is_read_from_a_mass_a_file_or_inline(tmp_path):
    """--payload as a file, inline keys or a bare mass: the same payload gives the same
    modes; a payload lowers the first mode."""
    out = tmp_path / "m"
    keys = "mass = 300.0, com = [0.0, 0.0, 0.6], inertia = [60.0, 60.0, 40.0]"
    toml = tmp_path / "p.toml"
    toml.write_text("[payload]\n" + keys.replace(", c", "\nc").replace(", i", "\ni") + "\n")
    freqs = []
    for payload in (None, str(toml), keys):
        argv = ["modes", str(SIM), "--out", str(out)] + (["--payload", payload] if payload else [])
        assert cli.main(argv) == 0
        freqs.append([float(r[1]) for r in _read(out / "modes.csv")[1]])
    assert freqs[1] == freqs[2] and freqs[1][0] < freqs[0][0]
    assert cli.main(["modes", str(SIM), "--out", str(out), "--payload", "300"]) == 0
    assert float(_read(out / "modes.csv")[1][0][1]) < freqs[0][0]


def test_map_over_a_grid_marks_poses_outside_the_stroke(tmp_path):
    """--map: every grid pose a row; inside the stroke the lowest frequency as modes gives it,
    outside it marked 0 with empty values."""
    out = tmp_path / "m"
    assert cli.main(["modes", str(SIM), "--out", str(out), "--map", "z=1.5:2.6:6,x=-0.2:0.2:3"]) == 0
    head, rows = _read(out / "map.csv")
    assert head[:8] == ["x", "y", "z", "thx", "thy", "thz", "inside", "lowest_hz"]
    assert len(rows) == 18
    model = load_scene(SIM)
    inside = [r for r in rows if r[6] == "1"]
    assert inside and len(inside) < len(rows)
    assert all(r[7] == "" for r in rows if r[6] == "0")
    for r in inside[:3]:
        q = np.array([float(c) for c in r[:6]])
        assert float(r[7]) == pytest.approx(S.modes(model, q).frequency_hz[0], rel=1e-13)


@pytest.mark.parametrize("args,words", [
    (["--pose", "0,0,3.5,0,0,0"], "--pose: leg 1 is"),
    (["--pose", "0,0,3.5,0,0,0"], "above leg_max 3.3 m"),
    (["--pose", "0,0,1"], "--pose: must be 6"),
    (["--modes", "7"], "--modes: the system has 6 modes"),
    (["--modes", "0"], "--modes"),
    (["--payload", "0"], "payload.mass"),
    (["--payload", "mass = 5, com = [0, 0, 0], inertia = [1, 1, -1]"], "payload.inertia"),
    (["--payload", "mass = 5, com = [0, 0, 0]"], "payload.inertia"),
    (["--pivot", "0,nan,0"], "--pivot"),
    (["--map", "z=1:2"], "--map"),
])
def test_bad_input_one_line_exit_2_and_the_earlier_set_kept(tmp_path, capsys, args, words):
    out = tmp_path / "m"
    assert cli.main(["modes", str(SIM), "--out", str(out)]) == 0
    before = (out / "modes.csv").read_bytes()
    capsys.readouterr()
    assert cli.main(["modes", str(SIM), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err
    assert (out / "modes.csv").read_bytes() == before


def test_scene_without_stiffness_and_bad_stiffness_are_refused(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    text = SIM.read_text()
    scene.write_text(text.replace("[stiffness]\nleg = 5.0e7", ""))
    assert cli.main(["modes", str(scene), "--out", str(tmp_path / "m")]) == 2
    assert "'stiffness'" in capsys.readouterr().err
    scene.write_text(text.replace("leg = 5.0e7", "leg = -5.0e7"))
    assert cli.main(["modes", str(scene), "--out", str(tmp_path / "m")]) == 2
    assert "'stiffness.leg': must be > 0" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()


# the machines the guide's and the README's tables state: the scene (the micro-manipulator's with
# the contract's example stiffness added), the payload and the words that name it in the table
MACHINES = {
    "micro-manipulator": ("micro_manipulator.toml", "\n[stiffness]\nleg = 2.0e7\n",
                          "mass = 0.5, com = [0.0, 0.0, 0.03], inertia = [3e-4, 3e-4, 3e-4]",
                          "0.5 kg at z = 0.03 m"),
    "motion simulator": ("motion_simulator.toml", "",
                         "mass = 300.0, com = [0.0, 0.0, 0.6], inertia = [60.0, 60.0, 40.0]",
                         "300 kg at z = 0.6 m"),
}


@pytest.mark.parametrize("document", ["docs/guides/stiffness-and-modes.md", "README.md"])
@pytest.mark.parametrize("machine", list(MACHINES))
def test_the_guide_and_the_readme_state_the_modes_and_stiffness(tmp_path, document, machine):
    """The row of each shipped machine in the guide's and the README's table: its stiffness
    and six modes, with and without the payload it names, as `modes` prints them (4
    significant digits)."""
    name, added, payload, words = MACHINES[machine]
    scene = tmp_path / name
    scene.write_text((ROOT / "scenes" / name).read_text() + added)
    text = (ROOT / document).read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith(f"| {machine} |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    out = tmp_path / "m"
    stated = {None: cells[5], payload: cells[6].split(":")[1]}
    assert words in cells[6]
    for key in stated:
        argv = ["modes", str(scene), "--out", str(out)] + (["--payload", key] if key else [])
        assert cli.main(argv) == 0
        f = [float(r[1]) for r in _read(out / "modes.csv")[1]]
        assert [float(v) for v in stated[key].split(",")] == [float(f"{v:.4g}") for v in f]
        if not key:   # the stiffness stated: the scene's own
            k = [float(r[1]) for r in _read(out / "stiffness.csv")[1]]
    assert [float(c.split()[0]) for c in cells[1:5]] == [float(f"{v:.4g}") for v in (k[0], k[2], k[3], k[5])]


def test_map_figures_label_their_axes_and_colour_bars(tmp_path):
    """--map with three axes: two PNGs in the set; each figure a slice through the first two
    axes with units on both, a colour bar of >= 3 ticks, the held axis named in the title."""
    from stewart_sim.studies.modes import study
    from stewart_sim.studies.modes.plots import map_figures

    out = tmp_path / "m"
    grid_text = "x=-0.3:0.3:7,z=1.9:2.8:10,thz=-0.1:0.1:3"
    assert cli.main(["modes", str(SIM), "--out", str(out), "--map", grid_text]) == 0
    assert (out / "map_lowest_hz.png").stat().st_size > 0 and (out / "map_weakest.png").exists()
    model = load_scene(SIM)
    grid = study.parse_grid(grid_text, model.home)
    figures = map_figures(model.name, grid, study.compute_map(model, grid, np.zeros(3)))
    for fig in figures.values():
        ax, cbar_ax = fig.axes
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "z (m)"
        assert "(Hz)" in cbar_ax.get_ylabel() or "(N/um)" in cbar_ax.get_ylabel()
        assert len(cbar_ax.get_yticks()) >= 3
        assert "slice at thz = 0 rad" in ax.get_title()
