"""The GCS data recorder (DRC, DRT, RTR, DRR?, HDR?, DRL?, TNR?) at the servo rate.

TABLES record tables of POINTS values each. A table records one source and one option (DRC):
sources are the axes X Y Z U V W (options 1 commanded position: the move's reference that
tick, 2 actual position: the plant's pose, 3 position error: 1 - 2, in mm or deg) or the legs
"1".."6" (1 the length setpoint the drives follow, 2 the measured length, 3 their difference,
in mm; OPTION_FORCE the rack force, N); option 8 (any source) is the device time in s; option 0
records nothing. Recording starts on its trigger (DRT): 0 (the default) and 1 on the next
command that moves (MOV, MVR, FRF), 2 on the next command of any kind (once: the trigger is
0 again after it; PIPython's own ERR? after DRT is that command unless its error check is off,
as its Datarecorder turns it off), 4 at once; it takes one
value every RTR servo ticks (RTR?, 1..RTR_MAX) until the tables are full, and restarts (empty)
at the next trigger. The values are the device's own (hil.device.Device.snapshot and l_ref at
the tick), so a table equals what the device publishes to its observers at the same ticks.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from hil.gcs import errors as E
from hil.gcs import parser as P
from hil.gcs.axes import AXES, MM_PER_M

TABLES = 8
POINTS = 16384
RTR_MAX = 10000
ROWS_PER_CHUNK = 16     # DRR? lines formatted per chunk (hil.gcs.server takes one a poll)
LEGS = ("1", "2", "3", "4", "5", "6")
OPTION_FORCE = 100
OPTIONS = {0: "Nothing is recorded", 1: "Commanded position of axis",
           2: "Actual position of axis", 3: "Position error of axis", 8: "Time",
           OPTION_FORCE: "Rack force of leg"}
TRIGGERS = {0: "Default setting: a command that changes position (MOV, MVR, FRF)",
            1: "Any command changing position (MOV, MVR, FRF)",
            2: "Next command", 4: "Immediately"}
MOVING = ("MOV", "MVR", "FRF")


@dataclass
class Sample:
    """What one tick offers the recorder (GCS units: mm, deg; legs in mm, forces in N)."""

    t: float
    commanded: np.ndarray     # (6,) GCS reference of the move
    actual: np.ndarray        # (6,) GCS position of the plant
    leg_set: np.ndarray       # (6,) mm
    leg_actual: np.ndarray    # (6,) mm
    force: np.ndarray         # (6,) N


@dataclass
class Table:
    source: str = "X"
    option: int = 0
    trigger: int = 0
    values: np.ndarray = field(default_factory=lambda: np.empty(POINTS))


class Recorder:
    """The record tables (see the module doc)."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.tables = [Table() for _ in range(TABLES)]
        self.rtr = 1
        self.count = 0           # values in every table of the running record
        self.recording = False
        self._k0 = 0

    # --- commands ------------------------------------------------------------------------

    def table_ids(self, words: tuple[str, ...]) -> list[int]:
        ids = [P.integer(w) for w in words] if words else list(range(1, TABLES + 1))
        for i in ids:
            if not 1 <= i <= TABLES:
                raise E.GcsError(E.INVALID_RECORDER_CHAN, f"table {i}")
        return ids

    def configure(self, args: tuple[str, ...]) -> None:
        """DRC {table source option}: all checked before any is set."""
        if not args or len(args) % 3:
            raise E.GcsError(E.PARAM_SYNTAX, "DRC takes table source option triples")
        new = []
        for i in range(0, len(args), 3):
            (t,) = self.table_ids(args[i:i + 1])
            source, option = args[i + 1], P.integer(args[i + 2])
            if source not in AXES and source not in LEGS:
                raise E.GcsError(E.INVALID_RECORDER_SRC_CHAN, f"source {source[:8]!r}")
            if option not in OPTIONS or (option == OPTION_FORCE and source not in LEGS):
                raise E.GcsError(E.INVALID_RECORDER_SRC_OPT, f"option {option}")
            new.append((t, source, option))
        for t, source, option in new:
            self.tables[t - 1].source, self.tables[t - 1].option = source, option

    def set_trigger(self, args: tuple[str, ...], k: int) -> None:
        """DRT {table source value}; table 0: every table."""
        if not args or len(args) % 3:
            raise E.GcsError(E.PARAM_SYNTAX, "DRT takes table source value triples")
        new = []
        for i in range(0, len(args), 3):
            t, trig = P.integer(args[i]), P.integer(args[i + 1])
            if t != 0:
                self.table_ids((args[i],))
            if trig not in TRIGGERS:
                raise E.GcsError(E.PARAM_OUT_OF_RANGE, f"trigger source {trig}")
            new.append((t, trig))
        for t, trig in new:
            for tab in (self.tables if t == 0 else [self.tables[t - 1]]):
                tab.trigger = trig
        if any(trig == 4 for _, trig in new):
            self.start(k)

    def set_rate(self, args: tuple[str, ...]) -> None:
        if len(args) != 1:
            raise E.GcsError(E.PARAM_SYNTAX, "RTR takes one number")
        n = P.integer(args[0])
        if not 1 <= n <= RTR_MAX:
            raise E.GcsError(E.PARAM_OUT_OF_RANGE, f"RTR {n}")
        self.rtr = n

    def command(self, name: str, k: int) -> None:
        """A command was accepted at tick k: start recording when it is the trigger."""
        triggers = {t.trigger for t in self.tables}
        if 2 in triggers or (name in MOVING and triggers & {0, 1}):
            self.start(k)
        for t in self.tables:          # "next command" fires once, then is back to the default
            if t.trigger == 2:
                t.trigger = 0

    def start(self, k: int) -> None:
        """Restart the record at tick k (nothing to record while no table has an option)."""
        if any(t.option for t in self.tables):
            self.recording, self.count, self._k0 = True, 0, k

    # --- ticks ---------------------------------------------------------------------------

    def due(self, k: int) -> bool:
        return self.recording and self.count < POINTS and (k - self._k0) % self.rtr == 0

    def sample(self, s: Sample) -> None:
        for tab in self.tables:
            tab.values[self.count] = _value(tab, s)
        self.count += 1

    # --- answers -------------------------------------------------------------------------

    def read(self, args: tuple[str, ...]) -> Iterator[str]:
        """DRR? [offset n [tables...]]: PI's GCS data, a header and one line per point, as
        chunks of ROWS_PER_CHUNK lines formatted when the connection takes them (a full record
        is megabytes: formatted at once it would hold the servo loop for a tenth of a second).
        The values are copied now. Asking for more points than are recorded sets error 77 and
        answers those there are."""
        if len(args) == 1:
            raise E.GcsError(E.PARAM_SYNTAX, "DRR? takes offset and count together")
        offset, n = (P.integer(args[0]), P.integer(args[1])) if args else (1, self.count)
        ids = self.table_ids(args[2:])
        if offset < 1 or n < 0:
            raise E.GcsError(E.PARAM_OUT_OF_RANGE, "offset from 1, count from 0")
        end = min(self.count, offset - 1 + n)
        short = offset - 1 + n > self.count
        rows = max(0, end - (offset - 1))
        head = ["# REM stewart-sim GCS twin data recorder", "#", "# VERSION = 1", "# TYPE = 1",
                "# SEPARATOR = 32", f"# DIM = {len(ids)}",
                f"# SAMPLE_TIME = {P.fmt(self.rtr / self.rate)}", f"# NDATA = {rows}", "#"]
        head += [f"# NAME{j} = {OPTIONS[self.tables[i - 1].option]} "
                 f"{self.tables[i - 1].source}" for j, i in enumerate(ids)]
        head.append("# END_HEADER")
        block = np.array([self.tables[i - 1].values[offset - 1:offset - 1 + rows] for i in ids])
        text = _chunks(head, block)
        if short:
            raise ShortRecord(text)
        return text

    def config_rows(self, args: tuple[str, ...]) -> list[str]:
        return [f"{i}={self.tables[i - 1].source} {self.tables[i - 1].option}"
                for i in self.table_ids(args)]

    def trigger_rows(self, args: tuple[str, ...]) -> list[str]:
        return [f"{i}={self.tables[i - 1].trigger} 0" for i in self.table_ids(args)]


def _chunks(head: list[str], block: np.ndarray) -> Iterator[str]:
    """The header, then the rows of `block` (columns: tables) ROWS_PER_CHUNK at a time; every
    line ends " \n" but the answer's last, "\n"."""
    rows = block.shape[1]
    yield P.answer(head) if rows == 0 else " \n".join(head) + " \n"
    for i in range(0, rows, ROWS_PER_CHUNK):
        j = min(rows, i + ROWS_PER_CHUNK)
        lines = [" ".join(P.fmt(v) for v in block[:, r]) for r in range(i, j)]
        yield " \n".join(lines) + ("\n" if j == rows else " \n")


class ShortRecord(E.GcsError):
    """DRR? asked for more points than recorded: the answer (what there is) and error 77."""

    def __init__(self, text: Iterator[str]) -> None:
        super().__init__(E.NOT_ENOUGH_RECORDED_DATA, "fewer points recorded than asked")
        self.text = text


def help_text() -> list[str]:
    """HDR?'s lines."""
    return (["#RecordOptions"] + [f"{k}={v}" for k, v in OPTIONS.items()]
            + ["#SourceIDs", "X Y Z U V W=axes (mm, deg)", "1 2 3 4 5 6=legs (mm; option "
               f"{OPTION_FORCE}: N)", "#TriggerOptions"]
            + [f"{k}={v}" for k, v in TRIGGERS.items()]
            + ["#Additional information", f"{TABLES} data recorder tables",
               f"{POINTS} datapoints per table", f"RTR 1..{RTR_MAX} servo cycles",
               "end of help"])


def _value(tab: Table, s: Sample) -> float:
    o = tab.option
    if o == 0:
        return 0.0
    if o == 8:
        return s.t
    if tab.source in AXES:
        i = AXES.index(tab.source)
        c, a = s.commanded[i], s.actual[i]
    else:
        i = LEGS.index(tab.source)
        if o == OPTION_FORCE:
            return float(s.force[i])
        c, a = s.leg_set[i], s.leg_actual[i]
    return float({1: c, 2: a, 3: c - a}[o])


def leg_mm(lengths) -> np.ndarray:
    return np.asarray(lengths, dtype=float) * MM_PER_M
