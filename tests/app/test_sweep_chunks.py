"""A resumed sweep takes back only the chunk files it wrote: each repro of a hostile chunk (random
bytes, an edited value, a row for an unknown point, 2 M duplicate rows, another sweep's chunk, a
FIFO) is refused in one line naming the file and the reason, set aside, its points computed
again, and sweep.csv is the serial table; then a seeded, bounded fuzz of chunk files: no
exception, no hang, no row other than the sweep's own (and no non-finite result) merged."""
from __future__ import annotations

import hashlib
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu.errors import SweepError
from stewart_sim.cli import main
from stewart_sim.studies.sweep.chunks import MAGIC, REFUSED, chunk_rules, resume_rows, write_chunk
from stewart_sim.studies.sweep.dask_run import eval_spec, fingerprint, run_sweep
from stewart_sim.studies.sweep.evaluate import (RESULTS, columns, evaluate_batch, evaluate_point,
                                                has_drive, result_problem)
from stewart_sim.studies.sweep.grid import load_grid
from stewart_sim.studies.sweep.result_table import CHUNKS, csv_text, merge, read_table

distributed = pytest.importorskip("distributed")

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
WAIT = 120.0  # s: the bound on every wait for the cluster
# 8 points in 2 chunks of 4; every other point fails (a row with its error and NaN results)
GRID = """
evaluation = "inverse"
batch = 4
[trajectory]
duration = 0.3
[axes]
"drive.gear_ratio" = [5.0, 10.0, 20.0, 40.0]
"platform.mass" = [0.5, -1.0]
"""
FIRST, SECOND = "part-000000000.csv", "part-000000004.csv"
FUZZ_SEED, FUZZ_CASES = 20231, 600


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A finished sweep's directory (written by the sweep on a loopback cluster), its grid file,
    the scheduler's address, the rules of its chunks and the serial table."""
    root = tmp_path_factory.mktemp("sweep")
    grid_path = root / "grid.toml"
    grid_path.write_text(GRID)
    grid = load_grid(grid_path)
    spec = eval_spec(SCENE, grid)
    points = grid.points()
    cols = columns(grid.evaluation, grid.keys)
    serial = csv_text(cols, evaluate_batch(spec, points))
    rules = chunk_rules(fingerprint(spec, grid), cols, points, grid.batch, has_drive(spec.scene))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as cluster:
        done = root / "done"
        s = run_sweep(SCENE, grid, done, scheduler=cluster.scheduler_address, timeout=WAIT)
        assert s.computed == 8 and s.failed == 4 and s.refused == 0
        assert (done / "sweep.csv").read_text() == serial
        assert sorted(p.name for p in (done / CHUNKS).iterdir()) == [FIRST, SECOND]
        yield {"dir": done, "grid": grid_path, "scheduler": cluster.scheduler_address,
               "rules": rules, "serial": serial}


def copy(sweep, dest: Path) -> Path:
    shutil.copytree(sweep["dir"], dest)
    return dest


def split(path: Path) -> tuple[bytes, bytes]:
    """A chunk file's first line and the rest."""
    head, _, body = path.read_bytes().partition(b"\n")
    return head + b"\n", body


def forge(path: Path, body: bytes, rows: int | None = None, fp: str | None = None) -> None:
    """Write `body` as a chunk with a first line whose checksum (and rows) fit it: the edit a
    forger would make."""
    words = split(path)[0].split()
    fp = fp or words[4].decode()
    rows = rows if rows is not None else body.count(b"\n") - 1
    path.write_bytes(f"{MAGIC} {fp} {rows} {hashlib.sha256(body).hexdigest()}\n".encode() + body)


def edit_cell(body: bytes, row: int, col: int, value: str) -> bytes:
    lines = body.decode().split("\n")
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)
    return "\n".join(lines).encode()


def resume(sweep, out: Path) -> int:
    """Resume the sweep in `out` through the command line; returns the exit status."""
    return main(["sweep", str(SCENE), "--grid", str(sweep["grid"]), "--out", str(out),
                 "--scheduler", sweep["scheduler"], "--no-plots"])


# --- each repro: refused in one line, set aside, computed again ------------------------------

def _random_bytes(p: Path) -> None:
    p.write_bytes(np.random.default_rng(1).bytes(4096))


def _nan(p: Path) -> None:
    head, body = split(p)
    p.write_bytes(head + edit_cell(body, 1, 5, "nan"))


def _huge(p: Path) -> None:
    head, body = split(p)
    p.write_bytes(head + edit_cell(body, 1, 5, "9e99"))


def _nan_forged(p: Path) -> None:
    forge(p, edit_cell(split(p)[1], 1, 5, "nan"))


def _huge_forged(p: Path) -> None:
    forge(p, edit_cell(split(p)[1], 1, 5, "9e99"))


def _unknown_point(p: Path) -> None:
    forge(p, edit_cell(split(p)[1], 2, 0, "8"))


def _row_added(p: Path) -> None:
    body = split(p)[1]
    forge(p, body + body.split(b"\n")[1].replace(b"0,", b"8,", 1) + b"\n")


def _unknown_point_unforged(p: Path) -> None:
    head, body = split(p)
    p.write_bytes(head + body + body.split(b"\n")[1].replace(b"0,", b"8,", 1) + b"\n")


def _two_million_duplicates(p: Path) -> None:
    head, body = split(p)
    row = body.split(b"\n")[1] + b"\n"
    with p.open("ab") as fh:
        fh.write(row * 1000)
        fh.truncate(len(head) + len(body) + len(row) * 2_000_000)  # sparse: no 400 MB written


def _two_million_declared(p: Path) -> None:
    body = split(p)[1]
    row = body.split(b"\n")[1] + b"\n"
    forge(p, body + row * 1000, rows=2_000_000)


def _not_utf8(p: Path) -> None:
    body = split(p)[1]
    forge(p, body.replace(b",ok,", b",o\xff,", 1))


def _other_sweep(p: Path) -> None:
    forge(p, split(p)[1], fp="0" * 64)


def _axis_edited(p: Path) -> None:
    forge(p, edit_cell(split(p)[1], 1, 1, "6.0"))


def _old_format(p: Path) -> None:
    p.write_bytes(split(p)[1])


def _truncated(p: Path) -> None:
    data = p.read_bytes()
    p.write_bytes(data[:len(data) * 2 // 3])


def _fifo(p: Path) -> None:
    p.unlink()
    os.mkfifo(p)


def _dev_zero(p: Path) -> None:
    p.unlink()
    p.symlink_to("/dev/zero")


REPROS = [
    (_random_bytes, "its first line is not"),
    (_nan, "its rows do not match its checksum"),
    (_huge, "its rows do not match its checksum"),
    (_nan_forged, "point 0: sigma1_max = 'nan': not finite"),
    (_huge_forged, "point 0: sigma1_max = '9e99' is not written as the sweep writes numbers"),
    (_unknown_point, "a row for point '8', not a point of the sweep (0 to 7)"),
    (_row_added, "its first line declares '5' rows: 1 to 4 (the grid's batch) expected"),
    (_unknown_point_unforged, "its rows do not match its checksum"),
    (_two_million_duplicates, "{size:,} bytes: more than 4 rows can take"),
    (_two_million_declared, "its first line declares '2000000' rows: 1 to 4"),
    (_other_sweep, "written for another sweep"),
    (_not_utf8, "not UTF-8 text at byte 326"),
    (_axis_edited, "point 0: its axis values are not the grid's"),
    (_old_format, "its first line is not"),
    (_truncated, "its rows do not match its checksum"),
    (_fifo, "not a regular file"),
    (_dev_zero, "a symbolic link"),
]


@pytest.mark.parametrize("damage, reason", REPROS, ids=[f.__name__[1:] for f, _ in REPROS])
def test_a_bad_chunk_is_refused_in_one_line_and_computed_again(sweep, tmp_path, capsys,
                                                               damage, reason):
    out = copy(sweep, tmp_path / "out")
    chunk = out / CHUNKS / FIRST
    damage(chunk)
    # a size in the reason is the damaged file's own: its rows hold paths and numbers whose
    # length is the machine's, not the test's
    reason = reason.replace("{size:,}", f"{chunk.stat().st_size:,}")
    assert resume(sweep, out) == 0
    std = capsys.readouterr()
    moved = out / REFUSED / FIRST
    assert std.err.count("\n") == 1, std.err       # one line, naming the file and the reason
    assert std.err.startswith(f"stewart-sim: {chunk}: refused ({reason}"), std.err
    assert std.err.endswith(f"); moved to {moved}, its points are computed again\n")
    assert "4 already done, 4 computed" in std.out and "1 chunk files refused" in std.out
    assert (out / "sweep.csv").read_text() == sweep["serial"]
    assert os.path.lexists(moved) and (out / CHUNKS / FIRST).is_file()
    # the chunk written again passes: a second resume takes every row back
    assert resume(sweep, out) == 0
    assert "8 already done, 0 computed" in capsys.readouterr().out


def test_a_point_in_two_chunks_is_taken_once(sweep, tmp_path, capsys):
    """A copy of a chunk under another name: the later file repeats its points and is refused."""
    out = copy(sweep, tmp_path / "out")
    copied = out / CHUNKS / "part-000000001.csv"
    shutil.copy(out / CHUNKS / FIRST, copied)
    body = split(copied)[1].split(b"\n")
    forge(copied, b"\n".join([body[0], *body[2:]]))   # points 1 to 3, under their name
    assert resume(sweep, out) == 0
    err = capsys.readouterr().err
    assert f"{copied}: refused (point 1 is in an earlier chunk too)" in err
    assert (out / "sweep.csv").read_text() == sweep["serial"]


def test_a_chunk_name_with_control_characters_is_printed_escaped(sweep, tmp_path):
    out = copy(sweep, tmp_path / "out")
    (out / CHUNKS / "part-\x1b[2J.csv").write_bytes(b"\x07")
    lines: list[str] = []
    assert len(resume_rows(out, sweep["rules"], lines.append)) == 8
    assert len(lines) == 1 and "part-\\x1b[2J.csv: refused (its first line is not" in lines[0]
    assert "\x1b" not in lines[0] and (out / REFUSED / "part-\x1b[2J.csv").exists()


def test_a_table_is_never_merged_from_rows_it_refused(sweep, tmp_path):
    """The unknown point of the repro (9 rows for 8 points, then exit 2 over a corrupt table):
    the table written is the sweep's, 8 rows, whatever the run does after."""
    out = copy(sweep, tmp_path / "out")
    (out / "sweep.csv").unlink()
    _unknown_point(out / CHUNKS / FIRST)
    lines: list[str] = []
    rows = resume_rows(out, sweep["rules"], lines.append)
    assert sorted(rows) == [4, 5, 6, 7] and len(lines) == 1
    merge(out, sweep["rules"].columns, rows)
    serial = sweep["serial"].splitlines()
    assert (out / "sweep.csv").read_text() == "\n".join([serial[0], *serial[5:9]]) + "\n"


def test_a_result_that_is_not_finite_is_an_error_row(sweep, monkeypatch):
    """No row with status ok carries a non-finite result: the point becomes a row with its
    error, the result named."""
    import stewart_sim.studies.sweep.evaluate as ev

    grid = load_grid(sweep["grid"])
    spec = eval_spec(SCENE, grid)
    monkeypatch.setattr(ev, "rack_forces", lambda model, q, *a: np.full(np.shape(q), np.inf))
    with np.errstate(invalid="ignore"):       # inf times a zero rate: NaN, as meant
        row = evaluate_point(spec, 0, grid.points()[0][1])
    assert row["status"] == "error" and row["error"] == "result sigma1_max = inf: not finite"
    assert all(math.isnan(row[c]) for c in RESULTS["inverse"])


@pytest.mark.parametrize("message", ["x" * 100_000, ""])
def test_an_error_row_is_one_a_chunk_takes(sweep, tmp_path, monkeypatch, message):
    """An error's text is cut to ERROR_CHARS (a chunk's rows have a size bound) and never
    empty: the row is written and taken back on resume."""
    import stewart_sim.studies.sweep.evaluate as ev

    def fail(*args):
        raise ValueError(message)

    grid = load_grid(sweep["grid"])
    monkeypatch.setattr(ev, "rack_forces", fail)
    row = evaluate_point(eval_spec(SCENE, grid), 0, grid.points()[0][1])
    assert row["status"] == "error" and 0 < len(row["error"]) <= ev.ERROR_CHARS
    written = write_chunk(tmp_path, sweep["rules"], [row])
    assert resume_rows(tmp_path, sweep["rules"], pytest.fail) == written


def test_the_rules_of_results(sweep):
    assert result_problem("sigma_max", 1.0, True) is None
    assert result_problem("sigma_max", -1.0, True) == "below 0"
    assert result_problem("cond_max", 0.5, True) == "below 1"
    assert result_problem("reachable", 1.5, True) == "above 1"
    assert result_problem("kp", -3.0, True) is None  # a gain need only be finite
    assert result_problem("torque_max", math.nan, False) is None  # no drive: no motor torque
    assert result_problem("torque_max", math.nan, True) == "not finite"
    assert result_problem("phase_margin", math.inf, True) == "not finite"


@pytest.mark.parametrize("change, reason", [
    ({"sigma_max": math.nan}, "point 0: sigma_max = 'nan': not finite"),
    ({"sigma_max": "1.5"}, "point 0: sigma_max = \"'1.5'\" is not a number"),
    ({"point": 8}, "a row for point '8', not a point of the sweep (0 to 7)"),
    ({"point": "0"}, "not of the sweep's types"),
    ({"platform.mass": 123.0}, "point 0: its axis values are not the grid's"),
    ({"status": "error"}, "point 0: an error row needs its text and NaN results"),
])
def test_a_task_row_the_rules_refuse_is_not_written(sweep, tmp_path, change, reason):
    """A worker running other code returns a row the rules refuse (a NaN result with status
    ok, a result that is not a number, a point not in the sweep, other axis values, an error
    row with results): the sweep stops (exit 2) before writing it, naming the fault. The same
    row unchanged is written and read back."""
    rules = sweep["rules"]
    grid = load_grid(sweep["grid"])
    row = evaluate_point(eval_spec(SCENE, grid), 0, grid.points()[0][1])
    assert row["status"] == "ok"
    good = tmp_path / "good"
    (good / CHUNKS).mkdir(parents=True)
    written = write_chunk(good, rules, [row])
    assert resume_rows(good, rules, pytest.fail) == written
    with pytest.raises(SweepError, match="a task returned a row the sweep cannot take") as exc:
        write_chunk(tmp_path, rules, [{**row, **change}])
    assert reason in str(exc.value)
    assert not (tmp_path / CHUNKS).exists()


def test_an_unreadable_manifest_is_one_line(sweep, tmp_path, capsys):
    out = copy(sweep, tmp_path / "out")
    (out / "sweep.json").unlink()
    os.mkfifo(out / "sweep.json")
    assert resume(sweep, out) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sweep.json: unreadable (not a regular file (a device, pipe or socket))" in err
    (out / "sweep.json").unlink()
    (out / "sweep.json").write_text("[" * 100_000 + "]" * 100_000)
    assert resume(sweep, out) == 2
    assert "sweep.json: unreadable" in capsys.readouterr().err


# --- the fuzz --------------------------------------------------------------------------------

def _mutate(rng: np.random.Generator, chunks: Path, sweep) -> bool:
    """Damage the chunk files at random; returns whether the checksum was forged (the rows of
    such a file may differ from the sweep's and still pass: they must then pass the rules)."""
    name = FIRST if rng.random() < 0.5 else SECOND
    p = chunks / name
    head, body = split(p)
    kind = int(rng.integers(14))
    if kind == 0:                                   # random bytes, any length
        p.write_bytes(rng.bytes(int(rng.integers(0, 5000))))
    elif kind == 1:                                 # truncated anywhere
        data = p.read_bytes()
        p.write_bytes(data[:int(rng.integers(0, len(data)))])
    elif kind == 2:                                 # bytes flipped
        data = bytearray(p.read_bytes())
        for _ in range(int(rng.integers(1, 4))):
            data[int(rng.integers(len(data)))] ^= int(rng.integers(1, 256))
        p.write_bytes(bytes(data))
    else:
        lines = body.split(b"\n")
        row = int(rng.integers(1, 5))
        cells = lines[row].split(b",")
        values = [b"nan", b"inf", b"-inf", b"9e99", b"9e+99", b"-1.0", b"", b"abc", b"1e-320",
                  b"\x00", b"\xff\xfe", b"\x1b[2J", b"\"", b"0.5\r", b"NaN", b"+1.0"]
        if kind == 3:                               # a value edited
            cells[int(rng.integers(len(cells)))] = values[int(rng.integers(len(values)))]
        elif kind == 4:                             # an unknown point
            cells[0] = [b"8", b"99", b"-1", b"01", b"4", b"99999999999999999999999",
                        b"1.0"][int(rng.integers(7))]
        elif kind == 5:                             # a row twice, or many times
            lines.insert(row, lines[row] * 1)
            lines[row + 1:row + 1] = [lines[row]] * int(rng.integers(0, 5000))
        elif kind == 6:                             # status and error text
            i = cells.index(b"ok") if b"ok" in cells else cells.index(b"error")
            cells[i:i + 2] = [[b"OK", b""], [b"error", b""], [b"ok", b"x"],
                              [b"error", b"boom"]][int(rng.integers(4))]
        elif kind == 7:                             # a row dropped
            del lines[row]
        elif kind == 8:                             # a cell dropped or added
            cells = cells[:-1] if rng.random() < 0.5 else cells + [b"1.0"]
        elif kind == 9:                             # the header of columns
            lines[0] = lines[0].replace(b"sigma", b"sygma", 1)
        elif kind == 10:                            # CRLF line ends
            lines = [ln + b"\r" for ln in lines[:-1]] + [b""]
        elif kind == 11:                            # the other chunk's name
            other = chunks / (SECOND if name == FIRST else FIRST)
            shutil.copy(p, other)
            return False
        elif kind == 12:                            # the first line
            words = head.split(b" ")
            words[int(rng.integers(len(words)))] = [b"", b"0", b"-4", b"4 4", b"x" * 300,
                                                    b"5"][int(rng.integers(6))]
            p.write_bytes(b" ".join(words) + body)
            return False
        else:                                       # a FIFO or a link in the chunk's place
            p.unlink()
            if rng.random() < 0.5:
                os.mkfifo(p)
            else:
                p.symlink_to("/dev/zero")
            return False
        if kind not in (5, 7, 10):
            lines[row] = b",".join(cells)
        new = b"\n".join(lines)
        if rng.random() < 0.5:
            p.write_bytes(head + new)
            return False
        forge(p, new, rows=(new.count(b"\n") - 1) if rng.random() < 0.8 else 4)
        return True
    return False


def test_fuzz_of_chunk_files(sweep, tmp_path):
    """FUZZ_CASES seeded random damages of a finished sweep's chunk files: resuming never raises
    nor waits, every refused file gets one line naming it and is set aside, every row taken back
    is a point of the sweep once with the grid's axis values and results that pass the rules (the
    sweep's own row unless the checksum was forged), and the merged table has no non-finite
    result in a row with status ok."""
    rng = np.random.default_rng(FUZZ_SEED)
    rules = sweep["rules"]
    own = resume_rows(sweep["dir"], rules, pytest.fail)
    n_axes = len(rules.axes[0])
    refused = forged_taken = 0
    for case in range(FUZZ_CASES):
        out = tmp_path / f"c{case}"
        shutil.copytree(sweep["dir"] / CHUNKS, out / CHUNKS)
        forged = _mutate(rng, out / CHUNKS, sweep)
        lines: list[str] = []
        rows = resume_rows(out, rules, lines.append)
        aside = sorted(p.name for p in (out / REFUSED).iterdir()) if (out / REFUSED).exists() else []
        assert len(lines) == len(aside), (case, lines)
        for line, name in zip(lines, aside):
            assert "\n" not in line and line.startswith(f"{out / CHUNKS / name}: refused (")
        refused += len(lines)
        for pid, row in rows.items():
            assert row[1:1 + n_axes] == list(rules.axes[pid]), case
            if row != own[pid]:
                assert forged, (case, row)
                forged_taken += 1
        merge(out, rules.columns, rows)
        table = read_table(out / "sweep.csv")
        assert len(set(table["point"])) == len(table["point"]) == len(rows) <= 8
        ok = table["status"] == "ok" if len(rows) else np.zeros(0, bool)
        for name in RESULTS["inverse"]:
            assert np.all(np.isfinite(np.asarray(table[name][ok], float))), (case, name)
        shutil.rmtree(out)
    assert refused >= FUZZ_CASES // 2    # most damages are caught
    print(f"chunk fuzz: {FUZZ_CASES} cases, {refused} files refused, {forged_taken} forged rows "
          "taken (finite, the grid's points)")
