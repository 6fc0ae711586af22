"""The GCS 2.0 command table: each command's handler, syntax and help line (HLP? lists them).

A handler gets the controller, the connection's session and the parsed arguments; it checks
every argument before it changes anything (a GcsError leaves the state as it was) and returns
its answer (None for a set command). `execute` runs one line: an unknown command is error 2, a
refused one sets its error in the session (ERR? reads it) and answers nothing; an accepted one
may start the data recorder (hil.gcs.recorder triggers).

The pivot point (SPI/SPI?) is a change of the controller's `hil.gcs.axes.Frame`; the workspace
queries ask the feasibility engine (VMO?: the check a move gets, hil.gcs.move_path; TRA?: the
engine's travel, hil.gcs.travel_query).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Union

import numpy as np

from hil.gcs import errors as E
from hil.gcs import parser as P
from hil.gcs.axes import AXES, MM_PER_M
from hil.gcs.coordinate_systems import DIRECTED as CS_DIRECTED
from hil.gcs.coordinate_systems import TOOL as CS_TOOL
from hil.gcs.coordinate_systems import TYPES as CS_TYPES
from hil.gcs.coordinate_systems import WORK as CS_WORK
from hil.gcs.coordinate_systems import ZERO as CS_ZERO
from hil.gcs.controller import VLS_MIN, GcsController, Session
from hil.gcs.recorder import POINTS, TABLES, ShortRecord, help_text
from hil.gcs.travel_query import travel

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


# --- the pivot point and the workspace queries ---------------------------------------------

PIVOT = ("R", "S", "T")     # the pivot point's coordinates, mm, in the platform's frame C
PIVOT_MAX = 1000.0          # mm: the largest |R|, |S|, |T| SPI takes


def spi(c: GcsController, s: Session, a: Args) -> Answer:
    pivot = c.frame.pivot * MM_PER_M
    for i, v in P.axis_values(a, PIVOT):
        if not abs(v) <= PIVOT_MAX:
            raise E.GcsError(E.PARAM_OUT_OF_RANGE, f"{PIVOT[i]} beyond {PIVOT_MAX} mm")
        pivot[i] = v
    c.set_pivot(pivot)
    return None


def spi_q(c: GcsController, s: Session, a: Args) -> Answer:
    ax = P.axes(a, PIVOT)
    pivot = c.frame.pivot * MM_PER_M
    return P.answer([f"{PIVOT[i]}={P.fmt(pivot[i])}" for i in ax])


def vmo_q(c: GcsController, s: Session, a: Args) -> Answer:
    """1 when MOV to these targets would be accepted from where the next move starts, else 0
    (the reason kept in the session as a refusal's is)."""
    target = _targets(c, a, relative=False)
    try:
        c.feasible(target)
    except E.GcsError as exc:
        s.why = exc.why
        return "0\n"
    return "1\n"


def tra_q(c: GcsController, s: Session, a: Args) -> Answer:
    """The absolute position each named axis reaches along the direction (components per axis,
    the others 0) from the plant's pose, at the first limit (hil.gcs.travel_query)."""
    pairs = P.axis_values(a)
    d = np.zeros(6)
    for i, v in pairs:
        d[i] = P.finite(v, E.PARAM_OUT_OF_RANGE, AXES[i])
    if not np.all(np.isfinite(d)) or np.max(np.abs(d)) > TRA_COMPONENT_MAX:
        raise E.GcsError(E.PARAM_OUT_OF_RANGE, "a direction component is out of range")
    t, g0 = travel(c.device.model, c.frame, np.asarray(c.device.snapshot().q), d)
    end = g0 + t.step * d
    return _numbers([i for i, _ in pairs], end)


TRA_COMPONENT_MAX = 1e6     # |component| TRA? takes (only the direction matters)


# --- coordinate systems (hil.gcs.coordinate_systems) ----------------------------------------

def _define(kind: str) -> Handler:
    def handler(c: GcsController, s: Session, a: Args) -> Answer:
        if len(a) < 3:
            raise E.GcsError(E.PARAM_SYNTAX, f"{kind} <CSname> {{<AxisID> <Value>}}")
        pairs = P.axis_values(a[1:])
        c.at_rest()
        c.systems.define(kind, a[0], pairs)
        return None
    return handler


def kln(c: GcsController, s: Session, a: Args) -> Answer:
    if len(a) != 2:
        raise E.GcsError(E.PARAM_SYNTAX, "KLN <Child> <Parent>")
    c.systems.link(a[0], a[1])
    return None


def ken(c: GcsController, s: Session, a: Args) -> Answer:
    if len(a) != 1:
        raise E.GcsError(E.PARAM_SYNTAX, "KEN <CSname>")
    name = c.systems.existing(a[0])
    if name != CS_ZERO and np.any(c.zero.home[3:] != 0.0):
        # ZERO's X Y Z run along N's axes and its U V W from home's orientation: a rigid tool
        # or work system composes with them only while that orientation is N's
        raise E.GcsError(E.CMD_NOT_ALLOWED_FOR_STAGE, "the scene's home is rotated")
    c.at_rest()
    c.systems.enable(name)
    c.reframe()
    return None


def krm(c: GcsController, s: Session, a: Args) -> Answer:
    if len(a) != 1:
        raise E.GcsError(E.PARAM_SYNTAX, "KRM <CSname>")
    c.systems.remove(a[0])
    return None


def ken_q(c: GcsController, s: Session, a: Args) -> Answer:
    """The enabled systems as `NAME=TYPE` lines, ZERO not among them (nothing enabled: an empty
    line); the form with names is not there (docs/guides/gcs-twin.md)."""
    if a:
        raise E.GcsError(E.PARAM_SYNTAX, "KEN? (without names)")
    enabled = c.systems.enabled
    return P.answer([f"{enabled[kind]}={kind}" for kind in CS_TYPES if kind in enabled])


def ket_q(c: GcsController, s: Session, a: Args) -> Answer:
    enabled = c.systems.enabled
    if not a:
        rows = [f"{kind}={enabled[kind]}" for kind in CS_TYPES if kind in enabled]
        return P.answer(rows or [f"{CS_ZERO}={CS_ZERO}"])
    rows = []
    for word in a:
        kind = word.upper()
        if kind not in CS_TYPES:
            raise E.GcsError(E.CS_TYPE_UNKNOWN, word[:20])
        if kind not in enabled:
            raise E.GcsError(E.NO_CS_OF_TYPE_ENABLED, kind)
        rows.append(f"{kind}={enabled[kind]}")
    return P.answer(rows)


def klt_q(c: GcsController, s: Session, a: Args) -> Answer:
    if not 1 <= len(a) <= 2:
        raise E.GcsError(E.PARAM_SYNTAX, "KLT? <StartCS> [<EndCS>]")
    start = c.systems.existing(a[0])
    end = c.systems.existing(a[1]) if len(a) == 2 else CS_ZERO
    return _numbers(list(range(6)), c.systems.composed(start, end))


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
    "SPI": Command(spi, "SPI {<PPCoordinate> <Position>}",
                   "Set Pivot Point (R S T, mm; only while U V W are 0)"),
    "SPI?": Command(spi_q, "SPI? [{<PPCoordinate>}]", "Get Pivot Point"),
    "VMO?": Command(vmo_q, "VMO? {<AxisID> <Position>}", "Virtual Move: Is The Target Reachable"),
    "TRA?": Command(tra_q, "TRA? {<AxisID> <Component>}",
                    "Get Maximum Travel Range In Direction Of Vector"),
    "KSW": Command(_define(CS_WORK), "KSW <CSname> {<AxisID> <Value>}",
                   "Define Work Coordinate System (fixed in space)"),
    "KST": Command(_define(CS_TOOL), "KST <CSname> {<AxisID> <Value>}",
                   "Define Tool Coordinate System (fixed to the platform)"),
    "KSD": Command(_define(CS_DIRECTED), "KSD <CSname> {<AxisID> <Value>}",
                   "Set Directed Coordinate System (a pivot on the platform, turned axes)"),
    "KLN": Command(kln, "KLN <Child> <Parent>", "Link Coordinate Systems"),
    "KEN": Command(ken, "KEN <CSname>", "Enable Coordinate System (KEN ZERO: none)"),
    "KRM": Command(krm, "KRM <CSname>", "Remove Coordinate System"),
    "KEN?": Command(ken_q, "KEN?", "Get Enabled Coordinate Systems And Their Types"),
    "KET?": Command(ket_q, "KET? [{<Type>}]", "Get Enabled Coordinate Systems"),
    "KLT?": Command(klt_q, "KLT? <StartCS> [<EndCS>]", "Get Pose Of A Chain"),
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
        s.error, s.why = exc.code, exc.why
        return None
    except Exception:  # a defect of the twin: the line is refused, the device keeps serving
        s.error = E.CONTROLLER_ERROR
        c.internal_errors += 1
        return None
    c.recorder.command(line.name, c.device.k)
    return out
