"""The GCS 2.0 command table: each command's handler, syntax and help line (HLP? lists them).

A handler gets the controller, the connection's session and the parsed arguments; it checks
every argument before it changes anything (a GcsError leaves the state as it was) and returns
its answer (None for a set command). `execute` runs one line: an unknown command is error 2, a
refused one sets its error in the session (ERR? reads it) and answers nothing; an accepted one
may start the data recorder (hil.gcs.recorder triggers).

New commands slot in as entries of COMMANDS: the pivot and frames (SPI/SPI?, KSD/KST/KSW/KEN/
KLN/KLT?/KET?) as changes of the controller's `hil.gcs.axes.Frame`, the workspace queries
(VMO?, TRA?) as queries over the feasibility engine.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Union

import numpy as np

from hil.gcs import errors as E
from hil.gcs import parser as P
from hil.gcs.axes import AXES
from hil.gcs.controller import VLS_MIN, GcsController, Session
from hil.gcs.recorder import POINTS, TABLES, ShortRecord, help_text

NAME = "STEWART-SIM-TWIN"          # *IDN?'s model field (PIPython's devname)
VERSION = "0.1.0"
GCS_VERSION = "2.0"
READY, BUSY = chr(177), chr(176)   # the controller-ready byte's answers (PI's codes)

Args = tuple[str, ...]
Answer = Union[str, Iterator[str], None]     # an iterator: chunks, sent as the client reads
Handler = Callable[[GcsController, Session, Args], Answer]


@dataclass(frozen=True)
class Command:
    handler: Handler
    syntax: str
    help: str


def _rows(axes: list[int], values) -> str:
    """One line `AXIS=value` per axis named (values: one per axis of AXES)."""
    return P.answer([f"{AXES[i]}={values[i]}" for i in axes])


def _numbers(axes: list[int], values) -> str:
    return _rows(axes, [P.fmt(v) for v in values])


def _flags(axes: list[int], values) -> str:
    return _rows(axes, ["1" if v else "0" for v in values])


def _no_args(args: Args) -> None:
    if args:
        raise E.GcsError(E.PARAM_SYNTAX, "takes no arguments")


def _ready_to_move(c: GcsController) -> None:
    if not (c.servo and c.referenced) or c.referencing:
        raise E.GcsError(E.MOVE_WITHOUT_REF_OR_NO_SERVO,
                         "servo off" if not c.servo else "not referenced")


def _targets(c: GcsController, args: Args, relative: bool) -> np.ndarray:
    target = c.target.copy()
    for i, v in P.axis_values(args):
        P.finite(v, E.POS_OUT_OF_LIMITS, AXES[i])
        target[i] = target[i] + v if relative else v
    P.finite(float(np.sum(target)), E.POS_OUT_OF_LIMITS, "the target")
    return target


# --- identification and help ---------------------------------------------------------------

def idn(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    name = c.device.model.name.replace(",", " ")[:40]
    return f"stewart-sim, {NAME}, {name}, {VERSION}\n"


def csv(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return GCS_VERSION + "\n"


def err(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    code = s.error
    if c.motion_errors > s.seen_motion_errors:
        code = code or E.MOTION_ERROR
        s.seen_motion_errors = c.motion_errors
    s.error = E.NO_ERROR
    return f"{code}\n"


def hlp(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return P.answer(["The following commands are valid:"]
                    + [f"{cmd.syntax} {cmd.help}" for cmd in COMMANDS.values()]
                    + ["end of help"])


def hdr(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return P.answer(help_text())


def sai(c: GcsController, s: Session, a: Args) -> Answer:
    if a and (len(a) > 1 or a[0].upper() != "ALL"):
        raise E.GcsError(E.PARAM_SYNTAX, "SAI? [ALL]")
    return P.answer(list(AXES))


def cst(c: GcsController, s: Session, a: Args) -> Answer:
    return _rows(P.axes(a), [NAME] * 6)


# --- servo and referencing ------------------------------------------------------------------

def svo(c: GcsController, s: Session, a: Args) -> Answer:
    pairs = P.axis_values(a)
    states = {v for _, v in pairs}
    if not states <= {0.0, 1.0}:
        raise E.GcsError(E.PARAM_SYNTAX, "servo state is 0 or 1")
    if len(states) != 1:
        raise E.GcsError(E.CMD_NOT_ALLOWED_FOR_STAGE, "the six axes switch together")
    if states == {1.0}:
        c.servo_on()
    else:
        c.servo_off()
    return None


def svo_q(c: GcsController, s: Session, a: Args) -> Answer:
    return _flags(P.axes(a), [c.servo] * 6)


def frf(c: GcsController, s: Session, a: Args) -> Answer:
    P.axes(a)
    if not c.reference():
        raise E.GcsError(E.MOTION_ERROR, "the device refused to home")
    return None


def frf_q(c: GcsController, s: Session, a: Args) -> Answer:
    return _flags(P.axes(a), [c.referenced] * 6)


# --- motion ----------------------------------------------------------------------------------

def mov(c: GcsController, s: Session, a: Args) -> Answer:
    target = _targets(c, a, relative=False)
    _ready_to_move(c)
    c.move(target)
    return None


def mvr(c: GcsController, s: Session, a: Args) -> Answer:
    target = _targets(c, a, relative=True)
    _ready_to_move(c)
    c.move(target)
    return None


def mov_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a)
    return _numbers(ax, c.target)


def pos_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a)
    p = c.position()
    return _numbers(ax, p)


def ont_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a)
    on = c.on_target()
    return _flags(ax, on)


def is_moving(c: GcsController, s: Session, a: Args) -> Answer:
    mask = sum(1 << i for i, m in enumerate(c.moving()) if m)
    return f"{mask:X}\n"


def is_ready(c: GcsController, s: Session, a: Args) -> Answer:
    return (BUSY if c.referencing else READY) + "\n"


def stp(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    c.stop()
    raise E.GcsError(E.STOP, "stopped")


def hlt(c: GcsController, s: Session, a: Args) -> Answer:
    P.axes(a)
    c.halt()
    raise E.GcsError(E.STOP, "halted")


def vls(c: GcsController, s: Session, a: Args) -> Answer:
    if len(a) != 1:
        raise E.GcsError(E.PARAM_SYNTAX, "VLS takes one number")
    v = P.number(a[0])
    if not VLS_MIN <= v <= c.vls_max:
        raise E.GcsError(E.PARAM_OUT_OF_RANGE, f"VLS {a[0][:20]}")
    c.velocity = v
    return None


def vls_q(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return P.fmt(c.velocity) + "\n"


def nlm_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a)
    return _numbers(ax, c.low)


def plm_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a)
    return _numbers(ax, c.high)


# --- parameters (read-only: what PIPython's data recorder tools ask) --------------------------

def _parameters(c: GcsController) -> dict[int, tuple[str, str, object]]:
    """PI's parameter IDs the twin answers: id -> (type, description, value)."""
    return {0x0E000200: ("FLOAT", "Servo update time /s", c.device.dt),
            0x16000200: ("INT", "Data recorder max points", TABLES * POINTS),
            0x16000300: ("INT", "Data recorder channel number", TABLES)}


def _param_id(word: str) -> int:
    try:
        return int(word, 16) if word.lower().startswith("0x") else P.integer(word)
    except ValueError:
        raise E.GcsError(E.PARAM_SYNTAX, f"{word[:20]!r} is not a parameter ID") from None


def spa_q(c: GcsController, s: Session, a: Args) -> Answer:
    """SPA? {<ItemID> <PamID>}: item 1 (the controller) only."""
    table = _parameters(c)
    if not a:
        a = tuple(w for pid in table for w in ("1", f"0x{pid:08X}"))
    if len(a) % 2 or len(a) > 2 * len(table):
        raise E.GcsError(E.PARAM_SYNTAX, "SPA? takes item and parameter pairs")
    rows = []
    for item, word in zip(a[::2], a[1::2]):
        pid = _param_id(word)
        if item != "1":
            raise E.GcsError(E.INVALID_AXIS, f"item {item[:8]!r}")
        if pid not in table:
            raise E.GcsError(E.UNKNOWN_PARAMETER, f"0x{pid:08X}")
        rows.append(f"{item} 0x{pid:08X}={table[pid][2]}")
    return P.answer(rows)


def spa(c: GcsController, s: Session, a: Args) -> Answer:
    if not a or len(a) % 3:
        raise E.GcsError(E.PARAM_SYNTAX, "SPA takes item, parameter and value triples")
    pid = _param_id(a[1])
    raise E.GcsError(E.READ_ONLY_PARAMETER if pid in _parameters(c) else E.UNKNOWN_PARAMETER,
                     f"0x{pid:08X}")


def hpa_q(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return P.answer(["The following parameters are valid:"]
                    + [f"0x{pid:08X}=\t0\t1\t{kind}\tTwin\t{text}"
                       for pid, (kind, text, _) in _parameters(c).items()]
                    + ["end of help"])


# --- data recorder ---------------------------------------------------------------------------

def drc(c: GcsController, s: Session, a: Args) -> Answer:
    c.recorder.configure(a)


def drc_q(c: GcsController, s: Session, a: Args) -> Answer:
    return P.answer(c.recorder.config_rows(a))


def drt(c: GcsController, s: Session, a: Args) -> Answer:
    c.recorder.set_trigger(a, c.device.k)


def drt_q(c: GcsController, s: Session, a: Args) -> Answer:
    return P.answer(c.recorder.trigger_rows(a))


def rtr(c: GcsController, s: Session, a: Args) -> Answer:
    c.recorder.set_rate(a)


def rtr_q(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return f"{c.recorder.rtr}\n"


def drr_q(c: GcsController, s: Session, a: Args) -> Answer:
    return c.recorder.read(a)


def drl_q(c: GcsController, s: Session, a: Args) -> Answer:
    ids = c.recorder.table_ids(a)
    return P.answer([f"{i}={c.recorder.count}" for i in ids])


def tnr_q(c: GcsController, s: Session, a: Args) -> Answer:
    _no_args(a)
    return f"{TABLES}\n"


COMMANDS: dict[str, Command] = {
    "*IDN?": Command(idn, "*IDN?", "Get Device Identification"),
    "CSV?": Command(csv, "CSV?", "Get Current Syntax Version"),
    "ERR?": Command(err, "ERR?", "Get Error Number"),
    "HLP?": Command(hlp, "HLP?", "Get List Of Available Commands"),
    "HDR?": Command(hdr, "HDR?", "Get All Data Recorder Options"),
    "SAI?": Command(sai, "SAI? [ALL]", "Get List Of Current Axis Identifiers"),
    "CST?": Command(cst, "CST? [{<AxisID>}]", "Get Assignment Of Stages To Axes"),
    "SVO": Command(svo, "SVO {<AxisID> <ServoState>}", "Set Servo Mode (all axes together)"),
    "SVO?": Command(svo_q, "SVO? [{<AxisID>}]", "Get Servo Mode"),
    "FRF": Command(frf, "FRF [{<AxisID>}]", "Fast Reference Move To Reference Switch"),
    "FRF?": Command(frf_q, "FRF? [{<AxisID>}]", "Get Referencing Result"),
    "MOV": Command(mov, "MOV {<AxisID> <Position>}", "Set Target Position"),
    "MOV?": Command(mov_q, "MOV? [{<AxisID>}]", "Get Target Position"),
    "MVR": Command(mvr, "MVR {<AxisID> <Distance>}", "Set Target Relative To Current Target"),
    "POS?": Command(pos_q, "POS? [{<AxisID>}]", "Get Real Position"),
    "ONT?": Command(ont_q, "ONT? [{<AxisID>}]", "Get On Target State"),
    "#5": Command(is_moving, "#5", "Request Motion Status"),
    "#7": Command(is_ready, "#7", "Request Controller Ready Status"),
    "#24": Command(stp, "#24", "Stop All Axes"),
    "STP": Command(stp, "STP", "Stop All Axes"),
    "HLT": Command(hlt, "HLT [{<AxisID>}]", "Halt Motion Smoothly (all axes)"),
    "VLS": Command(vls, "VLS <SystemVelocity>", "Set System Velocity (mm/s, deg/s)"),
    "VLS?": Command(vls_q, "VLS?", "Get System Velocity"),
    "NLM?": Command(nlm_q, "NLM? [{<AxisID>}]", "Get Low Position Soft Limit"),
    "PLM?": Command(plm_q, "PLM? [{<AxisID>}]", "Get High Position Soft Limit"),
    "TMN?": Command(nlm_q, "TMN? [{<AxisID>}]", "Get Minimum Commandable Position"),
    "TMX?": Command(plm_q, "TMX? [{<AxisID>}]", "Get Maximum Commandable Position"),
    "SPA?": Command(spa_q, "SPA? [{<ItemID> <PamID>}]", "Get Volatile Memory Parameters"),
    "SPA": Command(spa, "SPA {<ItemID> <PamID> <PamValue>}",
                   "Set Volatile Memory Parameters (all read-only here)"),
    "HPA?": Command(hpa_q, "HPA?", "Get List Of Available Parameters"),
    "DRC": Command(drc, "DRC {<RecTableID> <Source> <RecOption>}",
                   "Set Data Recorder Configuration"),
    "DRC?": Command(drc_q, "DRC? [{<RecTableID>}]", "Get Data Recorder Configuration"),
    "DRT": Command(drt, "DRT {<RecTableID> <TriggerSource> <Value>}",
                   "Set Data Recorder Trigger Source"),
    "DRT?": Command(drt_q, "DRT? [{<RecTableID>}]", "Get Data Recorder Trigger Source"),
    "RTR": Command(rtr, "RTR <RecordTableRate>", "Set Record Table Rate"),
    "RTR?": Command(rtr_q, "RTR?", "Get Record Table Rate"),
    "DRR?": Command(drr_q, "DRR? [<StartPoint> <NumberOfPoints> [{<RecTableID>}]]",
                    "Get Recorded Data Values"),
    "DRL?": Command(drl_q, "DRL? [{<RecTableID>}]", "Get Number Of Recorded Points"),
    "TNR?": Command(tnr_q, "TNR?", "Get Number Of Record Tables"),
}


def execute(c: GcsController, s: Session, text: str) -> Answer:
    """Run one line (without its LF) for session `s`; the answer to send (a string, or chunks
    of one: DRR?), or None."""
    try:
        line = P.parse(text)
        if line is None:
            return None
        cmd = COMMANDS.get(line.name)
        if cmd is None:
            raise E.GcsError(E.UNKNOWN_COMMAND, line.name[:20])
        out = cmd.handler(c, s, line.args)
    except ShortRecord as short:          # DRR? beyond the record: what there is, and error 77
        s.error = short.code
        return short.text
    except E.GcsError as exc:
        s.error = exc.code
        return None
    except Exception:  # a defect of the twin: the line is refused, the device keeps serving
        s.error = E.CONTROLLER_ERROR
        c.internal_errors += 1
        return None
    c.recorder.command(line.name, c.device.k)
    return out
