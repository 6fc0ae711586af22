"""A seeded, bounded fuzz of the CSV inputs through the commands that read them.

Valid trajectory, force, vehicle-motion and run files are mutated (random bytes, truncation,
non-finite, huge and tiny numbers, text in a number cell, stretched or reversed times, columns
dropped, added, renamed or swapped, rows of the wrong width, repeated rows, control characters,
an endless line, an empty file) and each mutant is given to every command that reads its kind:
`inverse`, `view` and `trajectory --waypoints` (trajectories), `simulate` and `view --trajectory`
(forces), `cue` (vehicle motion), `identify` and `view` (run files). Every command must end
with exit 0 or with one line and exit 2 (never a traceback, no warning printed beside it),
within a bound that only a hang reaches, and a command that succeeds must have written finite
numbers only.

The inputs are fixed by SEED and their number by INPUTS (in CI with `make test`): the mutations
of MUTATIONS in turn, each as often as the others. Figures are
not rasterised here (Figure.savefig writes a stub): what is fuzzed is how the inputs are read,
checked and computed on, and a figure of finite data is not an input's concern.
"""
from __future__ import annotations

import contextlib
import csv
import io as _io
import math
import signal
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from stewart_fmu import io, load_scene
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim import cli

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
SIM = ROOT / "scenes" / "motion_simulator.toml"
SEED = 20231
MUTATIONS = ("bytes", "truncate", "cell", "cells", "column", "times", "drop", "add", "rename",
             "swap", "width", "repeat", "control", "long", "empty", "header", "crlf")
# Inputs of each kind: each mutation in turn, so that every one is tried as often as the others
# (7, 3, 3 and 2 times; identify, which reads the run files, is the slowest reader).
INPUTS = {"trajectory": 7 * len(MUTATIONS), "forces": 3 * len(MUTATIONS),
          "motion": 3 * len(MUTATIONS), "run": 2 * len(MUTATIONS)}   # 255 inputs in all
HANG = 120          # s: a bound only a hang reaches (no speed is judged)
NUMBERS = ("nan", "NaN", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e309", "9e999",
           "1e-320", "-0.0", "1e-300", "1" + "0" * 400, "", "abc", "0x10", "1_0", " 1 ",
           '"1"', "1e", "--1", "\x00", "\x1b[31m")
SCALES = (2e7, 1e-300, 1e300, -1.0, 0.0, 1e-9)


class Hang(Exception):
    """A command that ran past HANG seconds."""


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> dict[str, bytes]:
    """Valid files of each kind, small (0.2 s at 1 kHz; a motion of 0.3 s)."""
    d = tmp_path_factory.mktemp("base")
    with contextlib.redirect_stdout(_io.StringIO()):
        assert cli.main(["trajectory", str(MICRO), "--move", "demo", "--duration", "0.2",
                         "--out", str(d / "T.csv")]) == 0
        assert cli.main(["inverse", str(MICRO), "--trajectory", str(d / "T.csv"), "--out",
                         str(d / "F.csv"), "--no-view"]) == 0
    t, q, _, _ = io.read_trajectory(d / "T.csv")
    forces = io.read_samples(d / "F.csv", io.FORCE_COLUMNS, "forces", prefix=True)
    lengths = inverse_kinematics(load_scene(MICRO), q, with_cond=False).lengths
    run = {"t": t, **{f"l{i + 1}": lengths[:, i] for i in range(6)},
           **{f"sigma{i + 1}": forces[:, i + 1] for i in range(6)}}
    io.write_csv(d / "run.csv", io.named_array(run))
    motion = (ROOT / "scenes" / "motions" / "braking_car.csv").read_text().splitlines()[:31]
    return {"trajectory": (d / "T.csv").read_bytes(), "forces": (d / "F.csv").read_bytes(),
            "motion": ("\n".join(motion) + "\n").encode(), "run": (d / "run.csv").read_bytes()}


def _rows(data: bytes) -> list[list[str]]:
    return list(csv.reader(_io.StringIO(data.decode())))


def _join(rows: list[list[str]]) -> bytes:
    return "".join(",".join(r) + "\n" for r in rows).encode()


def _mutate(data: bytes, rng: np.random.Generator, kind: str) -> tuple[str, bytes]:
    """One mutant of a valid CSV by the mutation `kind` (of MUTATIONS), its row, column and
    values drawn from rng; and the name of its mutation."""
    rows = _rows(data)
    r = 1 + int(rng.integers(len(rows) - 1))        # a data row
    c = int(rng.integers(len(rows[0])))              # a column
    if kind == "bytes":
        return kind, rng.bytes(int(rng.integers(0, 3000)))
    if kind == "truncate":
        return kind, data[:int(rng.integers(0, len(data)))]
    if kind == "cell":
        rows[r][c] = str(rng.choice(NUMBERS))
    elif kind == "cells":     # a whole column of one value (huge, tiny, non-finite)
        value = str(rng.choice(NUMBERS[:13]))
        for row in rows[1:]:
            row[c] = value
    elif kind == "column":    # one column scaled
        factor = float(rng.choice((1e300, -1e300, 1e-300, 1e6, 0.0)))
        for row in rows[1:]:
            row[c] = repr(float(row[c]) * factor)
    elif kind == "times":
        factor = float(rng.choice(SCALES))
        for row in rows[1:]:
            row[0] = repr(float(row[0]) * factor)
    elif kind == "drop":
        for row in rows:
            del row[c]
    elif kind == "add":
        for k, row in enumerate(rows):
            row.insert(c, "extra" if k == 0 else "1.5")
    elif kind == "rename":
        rows[0][c] = str(rng.choice(["T", "x ", "sigma7", "", "time", "t"]))
    elif kind == "swap":
        other = int(rng.integers(len(rows[0])))
        rows[0][c], rows[0][other] = rows[0][other], rows[0][c]
    elif kind == "width":
        del rows[r][c]
    elif kind == "repeat":
        rows.insert(r, list(rows[r]))
    elif kind == "control":
        rows[r][c] = rows[r][c] + "\x00\x1b[2J\x85"
    elif kind == "long":
        rows[r][c] = "1" * int(rng.choice((200_000, 1_100_000)))
    elif kind == "empty":
        return kind, b""
    elif kind == "header":
        return kind, _join(rows[:1])
    elif kind == "crlf":
        return kind, _join(rows).replace(b"\n", b"\r\n")
    return kind, _join(rows)


def _commands(kind: str, path: Path, out: Path, base_dir: Path) -> list[list[str]]:
    """The commands that read a file of `kind`, writing under `out`."""
    view = ["view", str(path), "--scene", str(MICRO), "-o", str(out / "view.html")]
    return {
        "trajectory": [["inverse", str(MICRO), "--trajectory", str(path), "--out",
                        str(out / "F.csv"), "--no-view"],
                       view,
                       ["trajectory", str(MICRO), "--waypoints", str(path), "--out",
                        str(out / "W.csv")]],
        "forces": [["simulate", str(MICRO), "--forces", str(path), "--out", str(out / "sim")],
                   view + ["--trajectory", str(base_dir / "T.csv")]],
        "motion": [["cue", str(SIM), "--motion", str(path), "--out", str(out / "cue"),
                    "--no-view"]],
        "run": [["identify", str(MICRO), "--runs", str(path), "--out", str(out / "id")],
                view],
    }[kind]


def _non_finite(out: Path) -> list[str]:
    """The CSV cells under `out` that are numbers but not finite ones."""
    bad = []
    for path in sorted(out.rglob("*.csv")):
        for row in csv.reader(_io.StringIO(path.read_text(encoding="utf-8"))):
            for cell in row:
                try:
                    value = float(cell)
                except ValueError:
                    continue
                if not math.isfinite(value):
                    bad.append(f"{path.name}: {cell}")
    return bad


def _alarm(signum, frame):
    raise Hang(f"no answer in {HANG} s")


def _stub_savefig(monkeypatch) -> None:
    from matplotlib.figure import Figure

    def savefig(self, fname, *args, **kwargs):
        if hasattr(fname, "write"):
            fname.write(b"stub")
        else:
            Path(fname).write_bytes(b"stub")
    monkeypatch.setattr(Figure, "savefig", savefig)


@pytest.mark.parametrize("kind", list(INPUTS))
def test_fuzzed_csv_inputs(kind, base, tmp_path, monkeypatch, capsys) -> None:
    _stub_savefig(monkeypatch)
    base_dir = tmp_path / "base"
    base_dir.mkdir()
    (base_dir / "T.csv").write_bytes(base["trajectory"])
    rng = np.random.default_rng([SEED, list(INPUTS).index(kind)])
    previous = signal.signal(signal.SIGALRM, _alarm)
    failures: list[str] = []
    tried: dict[str, int] = {}
    try:
        for n in range(INPUTS[kind]):
            mutation, data = _mutate(base[kind], rng, MUTATIONS[n % len(MUTATIONS)])
            tried[mutation] = tried.get(mutation, 0) + 1
            path = tmp_path / f"in{n}.csv"
            path.write_bytes(data)
            for args in _commands(kind, path, tmp_path / f"out{n}", base_dir):
                where = f"input {n} ({mutation}), {args[0]}"
                signal.alarm(HANG)
                try:
                    with warnings.catch_warnings(record=True) as warned:
                        warnings.simplefilter("always")
                        status = cli.main(args)
                except BaseException as exc:      # a traceback or a hang
                    failures.append(f"{where}: {type(exc).__name__}: {exc}"[:300])
                    continue
                finally:
                    signal.alarm(0)
                err = capsys.readouterr().err
                if warned:     # printed on stderr beside the one line or the results
                    failures.append(f"{where}: warning: {warned[0].message}"[:300])
                if status == 2:
                    lines = err.strip().splitlines()
                    if len(lines) != 1 or not lines[0].startswith("stewart-sim: error: "):
                        failures.append(f"{where}: exit 2 without one line: {err[:300]!r}")
                elif status != 0:
                    failures.append(f"{where}: exit {status}: {err[:300]!r}")
                elif bad := _non_finite(tmp_path / f"out{n}"):
                    failures.append(f"{where}: non-finite results written: {bad[:3]}")
            path.unlink()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert sum(tried.values()) == INPUTS[kind] and set(tried) == set(MUTATIONS)
    assert not failures, "\n".join(failures)
