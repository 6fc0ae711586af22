"""`identify` at the edges of its inputs (run files with zeros, 1e300, 1e-300, tiny time
steps, NaN): one line naming the input and exit 2 with nothing written, or exit 0 with every
figure finite; never a traceback, a RuntimeWarning or a LAPACK message before the line."""
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import load_scene
from stewart_sim.cli import main

sys.path.insert(0, str(Path(__file__).parent))
from test_identify import SCENE, TRUTH, fourier_motion, write_run  # noqa: E402

NON_FINITE = re.compile(r"\b(inf|nan)\b", re.I)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    truth = load_scene(SCENE, overrides=TRUTH)
    return (write_run(d / "a.csv", truth, *fourier_motion(truth, 1)),
            write_run(d / "b.csv", truth, *fourier_motion(truth, 2)))


def edited(src: Path, dst: Path, edit) -> Path:
    header = src.read_text().splitlines()[0]
    data = np.loadtxt(src, delimiter=",", skiprows=1)
    edit(data)
    np.savetxt(dst, data, delimiter=",", header=header, comments="", fmt="%.17g")
    return dst


def identify_cli(capfd, *args):
    """`identify` in this process, its status and its stdout and stderr (file descriptors:
    a LAPACK message written by C is caught too)."""
    status = main(["identify", str(SCENE), *map(str, args)])
    out, err = capfd.readouterr()
    return status, out, err


def assert_one_line(status, err, names):
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("stewart-sim: error: ") and str(names) in lines[0], lines[0]


def test_held_out_forces_all_zero_are_refused_before_any_file(good, tmp_path, capfd):
    a, b = good
    zero = edited(b, tmp_path / "zero.csv",
                  lambda d: d.__setitem__((slice(None), slice(7, 13)), 0.0))
    status, out, err = identify_cli(capfd, "--runs", a, "--validate", zero, "--out", tmp_path / "o")
    assert_one_line(status, err, zero)
    assert "wrote" not in out and not (tmp_path / "o").exists()


def test_held_out_forces_of_1e300_are_refused_before_any_file(good, tmp_path, capfd):
    a, b = good
    huge = edited(b, tmp_path / "huge.csv", lambda d: d.__setitem__(
        (slice(None), slice(7, 13)), d[:, 7:13] * 1e300 / np.abs(d[:, 7:13]).max()))
    out_dir = tmp_path / "o"
    status, _, err = identify_cli(capfd, "--runs", a, "--out", out_dir)
    assert status == 0, err
    before = {p.name: p.read_bytes() for p in out_dir.iterdir()}
    status, out, err = identify_cli(capfd, "--runs", a, "--validate", huge, "--out", out_dir)
    assert_one_line(status, err, huge)
    assert "inf" not in out and "wrote" not in out
    assert {p.name: p.read_bytes() for p in out_dir.iterdir()} == before   # the set kept


@pytest.mark.parametrize("case", ["tiny_dt", "tiny_forces", "zero_forces"])
def test_numerical_trouble_is_one_line_without_warnings(good, tmp_path, capfd, case):
    """Times of 1e-300 s (the pose's derivatives overflow), forces of 1e-300 N, forces all
    zero: no RuntimeWarning, no '** On entry to DLASCL', one line naming the run."""
    a, _ = good
    edit = {"tiny_dt": lambda d: d.__setitem__((slice(None), 0), d[:, 0] * 1e-300),
            "tiny_forces": lambda d: d.__setitem__((slice(None), slice(7, 13)),
                                                   d[:, 7:13] * 1e-300),
            "zero_forces": lambda d: d.__setitem__((slice(None), slice(7, 13)), 0.0)}[case]
    run = edited(a, tmp_path / f"{case}.csv", edit)
    status, out, err = identify_cli(capfd, "--runs", run, "--out", tmp_path / "o")
    assert "Warning" not in err and "DLASCL" not in err + out, err
    if status == 0:
        assert not NON_FINITE.search(out + (tmp_path / "o" / "report.md").read_text())
    else:
        assert_one_line(status, err, run)
        assert not (tmp_path / "o").exists()


# Edits a fuzz case draws from: (column block, value or factor). Blocks: 0 time, 1:7 leg
# lengths, 7:13 forces.
_BLOCKS = {"time": slice(0, 1), "lengths": slice(1, 7), "forces": slice(7, 13),
           "one force": slice(7, 8)}
_VALUES = (0.0, 1e300, -1e300, 1e-300, 5e-324, np.nan, np.inf, 1e9, -1.0)
_FACTORS = (0.0, 1e300, 1e-300, 1e-9, 1e9, -1.0)


def _fuzz_edit(rng: np.random.Generator):
    block = list(_BLOCKS)[rng.integers(len(_BLOCKS))]
    sl = _BLOCKS[block]
    if rng.uniform() < 0.5:     # scale the whole block (a wrong unit)
        f = float(rng.choice(_FACTORS))
        return f"{block} x {f:g}", lambda d: d.__setitem__((slice(None), sl), d[:, sl] * f)
    v = float(rng.choice(_VALUES))
    rows = rng.choice(4000, size=int(rng.integers(1, 40)), replace=False)
    return f"{block} = {v:g} on {rows.size} rows", lambda d: d.__setitem__(
        (rows[:, None], np.arange(sl.start, sl.stop)[None, :]), v)


@pytest.mark.parametrize("seed", range(8))
def test_fuzzed_runs_never_give_a_traceback_or_a_non_finite_figure(good, tmp_path, capfd, seed):
    """Seeded, bounded: one edited file per seed, as the identification run or as the held-out
    one. Exit 2 is one line naming the edited file and nothing written; exit 0 states only
    finite figures (stdout and report.md)."""
    a, b = good
    rng = np.random.default_rng(seed)
    what, edit = _fuzz_edit(rng)
    held_out = bool(rng.integers(2))
    bad = edited(b if held_out else a, tmp_path / "fuzz.csv", edit)
    args = ("--runs", a, "--validate", bad) if held_out else ("--runs", bad, "--validate", b)
    status, out, err = identify_cli(capfd, *args, "--out", tmp_path / "o")
    assert "Warning" not in err and "DLASCL" not in err + out, (what, err)
    if status == 0:
        assert not NON_FINITE.search(out + (tmp_path / "o" / "report.md").read_text()), what
    else:
        assert_one_line(status, err, bad)
        assert not (tmp_path / "o").exists(), what
