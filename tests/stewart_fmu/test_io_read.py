"""stewart_fmu.io.read_samples, the one CSV reader: numpy parses blocks of plain numbers, the
row-by-row reader (csv + float()) the rest; the values are float()'s bit for bit either way,
and every error names the same line and column whichever block it lies in."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_fmu import io
from stewart_fmu.errors import TrajectoryError

COLUMNS = ("t", "a", "b")
HEADER = "t,a,b"


def _rows(n: int, rng: np.random.Generator) -> list[list[str]]:
    """n rows of repr-exact cells: t = 0, 1, ..., a and b random over many magnitudes."""
    values = rng.standard_normal((n, 2)) * 10.0 ** rng.integers(-300, 300, (n, 2))
    return [[repr(float(k)), repr(a), repr(b)] for k, (a, b) in enumerate(values.tolist())]


def _text(rows: list[list[str]], header: str = HEADER, end: str = "\r\n") -> str:
    return header + end + "".join(",".join(r) + end for r in rows)


@pytest.fixture(params=[io.CHUNK_ROWS, 4], ids=["one_block", "blocks_of_4"])
def chunk(request, monkeypatch) -> int:
    """The default block size (every file here is one block) and blocks of 4 rows (the cell
    spoiled at line 11 lies in the third block, after two that numpy parsed)."""
    monkeypatch.setattr(io, "CHUNK_ROWS", request.param)
    return request.param


def _write(tmp_path, text: str, name: str = "s.csv"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


@pytest.mark.parametrize("odd", [None, "1_0", '"2.5"', " 3.25 ", "\u0664", "1e500"])
def test_values_are_float_of_each_cell(tmp_path, chunk, odd) -> None:
    """Random doubles over 600 decades read back bit for bit; a cell numpy does not parse
    (underscores, quotes, Unicode digits) but float() does is read as float() reads it."""
    rows = _rows(23, np.random.default_rng(7))
    if odd is not None:
        rows[9][1] = odd                                  # line 11
    path = _write(tmp_path, _text(rows))
    expected = np.array([[float(c.strip('"')) for c in r] for r in rows])
    if odd == "1e500":
        with pytest.raises(TrajectoryError, match="line 11, column 'a': non-finite value inf"):
            io.read_samples(path, COLUMNS, "samples")
        return
    data = io.read_samples(path, COLUMNS, "samples")
    assert data.dtype == np.float64 and data.shape == (23, 3)
    assert np.array_equal(data.view(np.int64), expected.view(np.int64))


@pytest.mark.parametrize("end", ["\n", "\r\n", "\r"])
def test_line_endings(tmp_path, chunk, end) -> None:
    rows = _rows(10, np.random.default_rng(1))
    data = io.read_samples(_write(tmp_path, _text(rows, end=end)), COLUMNS, "samples")
    assert np.array_equal(data, np.array(rows, dtype=float))


def _spoil(line: int, text: str):
    """Replace line `line` (1 = header) of the file."""
    def spoil(rows: list[list[str]]) -> str:
        lines = _text(rows).split("\r\n")
        lines[line - 1] = text
        return "\r\n".join(lines)
    return spoil


def _cell(line: int, column: int, value: str):
    def spoil(rows: list[list[str]]) -> str:
        rows[line - 2][column] = value
        return _text(rows)
    return spoil


ERRORS = {
    "not a number": (_cell(11, 2, "abc"), "line 11, column 'b': not a number: 'abc'"),
    "empty cell": (_cell(11, 1, ""), "line 11, column 'a': not a number: ''"),
    "too many fields": (_spoil(11, "1,2,3,4"), "line 11 has 4 fields, expected 3"),
    "too few fields": (_spoil(11, "10,2"), "line 11 has 2 fields, expected 3"),
    "blank line": (_spoil(11, ""), "line 11 has 0 fields, expected 3"),
    "comment": (_spoil(11, "# 10,1,2"), "line 11, column 't': not a number: '# 10'"),
    "field limit": (_cell(11, 1, "1" * 131073),
                    "line 11: not valid CSV: field larger than field limit (131072)"),
    "nan": (_cell(11, 1, "nan"), "line 11, column 'a': non-finite value nan"),
    "-inf": (_cell(11, 2, "-inf"), "line 11, column 'b': non-finite value -inf"),
    "time repeats": (_cell(11, 0, "8.0"), "line 11, column 't': time must increase strictly"),
    "time goes back": (_cell(12, 0, "1.5"), "line 12, column 't': time must increase strictly"),
    "bad header": (_spoil(1, "t,b,a"), "header must be t,a,b; missing none, unexpected none, "
                                       "columns out of order"),
    "missing column": (_spoil(1, "t,a,c"), "header must be t,a,b; missing ['b'], "
                                           "unexpected ['c']"),
    "no samples": (lambda rows: HEADER, "no samples after the header"),
    "empty file": (lambda rows: "", "empty file, expected header t,a,b"),
}


@pytest.mark.parametrize("case", sorted(ERRORS))
def test_errors_name_file_line_and_column(tmp_path, chunk, case) -> None:
    """The same message whether the bad line lies in the first block or in a later one."""
    spoil, message = ERRORS[case]
    path = _write(tmp_path, spoil(_rows(20, np.random.default_rng(3))))
    with pytest.raises(TrajectoryError) as info:
        io.read_samples(path, COLUMNS, "samples")
    assert str(info.value) == f"{path}: {message}"


def test_the_first_error_wins_across_blocks(tmp_path, chunk) -> None:
    """Two bad lines: the earlier is named, also when numpy parsed the blocks before it."""
    rows = _rows(20, np.random.default_rng(3))
    rows[8][1] = "x"          # line 10
    rows[14] = rows[14][:2]   # line 16
    with pytest.raises(TrajectoryError, match="line 10, column 'a': not a number: 'x'"):
        io.read_samples(_write(tmp_path, _text(rows)), COLUMNS, "samples")


def test_unreadable_files(tmp_path) -> None:
    with pytest.raises(TrajectoryError, match=r"nope.csv: cannot read samples: No such file"):
        io.read_samples(tmp_path / "nope.csv", COLUMNS, "samples")
    with pytest.raises(TrajectoryError, match=r"cannot read samples: Is a directory"):
        io.read_samples(tmp_path, COLUMNS, "samples")
    binary = _write(tmp_path, "")
    binary.write_bytes(HEADER.encode() + b"\r\n0,\xff\xfe,1\r\n")
    with pytest.raises(TrajectoryError, match="s.csv: not a text file: 'utf-8' codec"):
        io.read_samples(binary, COLUMNS, "samples")
    with pytest.raises(TrajectoryError, match="not a text file"):
        io.csv_header(binary, "samples")
    with pytest.raises(TrajectoryError, match="nope.csv: cannot read samples"):
        io.csv_header(tmp_path / "nope.csv", "samples")


def test_prefix_min_rows_and_progress(tmp_path, chunk) -> None:
    """prefix: further columns (even text) ignored; progress after each full block, also
    when the rows after the first block are read one by one (a quoted cell)."""
    rows = [r + ["label"] for r in _rows(10, np.random.default_rng(5))]
    path = _write(tmp_path, _text(rows, header="t,a,b,method"))
    seen: list[int] = []
    data = io.read_samples(path, COLUMNS, "samples", prefix=True, progress=seen.append)
    assert np.array_equal(data, np.array([r[:3] for r in rows], dtype=float))
    assert seen == ([4, 8] if chunk == 4 else [])
    rows[5][1] = '"1.5"'
    seen.clear()
    io.read_samples(_write(tmp_path, _text(rows, header="t,a,b,method")), COLUMNS,
                    "samples", prefix=True, progress=seen.append)
    assert seen == ([4, 8] if chunk == 4 else [])
    with pytest.raises(TrajectoryError, match="header must be t,a,b;"):
        io.read_samples(path, COLUMNS, "samples")
    with pytest.raises(TrajectoryError, match="need 11 or more samples, got 10"):
        io.read_samples(path, COLUMNS, "samples", prefix=True, min_rows=11)
    with pytest.raises(TrajectoryError, match="need two or more samples, got 1"):
        io.read_samples(_write(tmp_path, _text(rows[:1], header="t,a,b,method")), COLUMNS,
                        "samples", prefix=True, min_rows=2)


def test_anywhere_picks_named_columns(tmp_path, chunk) -> None:
    """anywhere: the columns in the order asked for, wherever the header has them; the
    errors name the column asked for, time is columns[0] whatever its name."""
    rng = np.random.default_rng(11)
    rows = _rows(10, rng)
    header = "b,note,time,a"
    shuffled = [[b, "x y", t, a] for t, a, b in rows]
    path = _write(tmp_path, _text(shuffled, header=header))
    names = ("time", "a", "b")
    data = io.read_samples(path, names, "run table", anywhere=True)
    assert np.array_equal(data, np.array(rows, dtype=float))
    assert io.csv_header(path, "run table") == ("b", "note", "time", "a")
    assert io.csv_header(_write(tmp_path, "", "empty.csv"), "run table") == ()
    shuffled[6][2] = shuffled[5][2]                            # line 8: time repeats
    shuffled[3][3] = "nan"                                     # line 5, column a
    spoiled = _write(tmp_path, _text(shuffled, header=header))
    with pytest.raises(TrajectoryError, match="line 5, column 'a': non-finite value nan"):
        io.read_samples(spoiled, names, "run table", anywhere=True)
    shuffled[3][3] = "1.0"
    with pytest.raises(TrajectoryError, match="line 8, column 'time': time must increase"):
        io.read_samples(_write(tmp_path, _text(shuffled, header=header)), names, "run table",
                        anywhere=True)
    shuffled[3][0] = "?"
    with pytest.raises(TrajectoryError, match="line 5, column 'b': not a number: '[?]'"):
        io.read_samples(_write(tmp_path, _text(shuffled, header=header)), names, "run table",
                        anywhere=True)
    with pytest.raises(TrajectoryError, match=r"header must hold time,a,b,c \(in any order\); "
                                              r"missing \['c'\], more than once none"):
        io.read_samples(path, (*names, "c"), "run table", anywhere=True)
    twice = _write(tmp_path, _text([r + ["1"] for r in shuffled], header="b,note,time,a,a"))
    with pytest.raises(TrajectoryError, match=r"missing none, more than once \['a'\]"):
        io.read_samples(twice, names, "run table", anywhere=True)
    with pytest.raises(ValueError, match="exclude each other"):
        io.read_samples(path, names, "run table", anywhere=True, prefix=True)
