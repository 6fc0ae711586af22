"""What the mechanism can reach: every limit's margin at a pose, one C call for a batch of poses
(native/src/reach.c), and the travel along a direction before the first limit.

Limits, in report order (table.LIMITS, from stewart_table.h STEWART_LIMITS); a margin is
positive inside, in the limit's unit, the least over its legs, pairs or obstacle-leg pairs:

==============  ======  =====================================================================
stroke_min      m       l_i - leg_min                        (geometry.leg_min)
stroke_max      m       leg_max - l_i                        (geometry.leg_max)
base_cone       rad     base_cone - angle(u_i, base axis i)  ([joints])
platform_cone   rad     platform_cone - angle(R^T u_i, platform axis i)
leg_clearance   m       distance(segment i, segment j) - 2 leg_radius  ([clearance])
obstacle        m       signed distance(segment i, obstacle) - leg_radius  ([[clearance.obstacles]])
cond            1       cond_limit - cond(J), J scaled as kinematics.condition_number
speed           m/s     speed bound - |ldot_i|               (with rates, DriveBounds)
acceleration    m/s2    acceleration bound - |lddot_i|       (with accelerations)
force           N       force bound - |sigma_i|, the rack force (inverse dynamics, drive incl.)
==============  ======  =====================================================================

Only the limits a model and a call have are present (a table the scene leaves out is a limit
that is not computed); the binding limit of a pose is the first present one, in this order,
whose margin is negative.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import table
from .errors import StewartError, TrajectoryError
from .frames import frame_change
from .native import core
from .reach_params import COND_LIMIT
from .scene_reach import pair_legs

LIMITS = table.LIMITS
NAMES = tuple(lim.name for lim in LIMITS)
TOL = 1e-9   # travel: the first limit found to this (m or rad along a unit axis)
# travel's conservative advancement: steps of at most the characteristic length / MARCH_STEPS
# (scaled units: the angles times the characteristic length); a cap on the steps, not the
# resolution (stewart_reach_travel)
MARCH_STEPS = 16

_ffi, _lib = core.ffi, core.lib


@dataclass(frozen=True)
class DriveBounds:
    """The drives' bounds on a leg (None: not limited): |leg speed| (m/s), |leg acceleration|
    (m/s^2), |rack force| (N)."""

    speed: float | None = None
    acceleration: float | None = None
    force: float | None = None


@dataclass(frozen=True)
class Verdict:
    """One pose's answer: the binding limit (None: inside every one) and where it binds, and
    every limit's margin in LIMITS order (+inf for a limit not present) with its element
    (`at`: the leg, pair or obstacle and leg where each margin is least)."""

    limit: str | None
    where: str
    margins: np.ndarray
    at: np.ndarray | None = None

    def where_of(self, index: int) -> str:
        """Where the limit LIMITS[index] is least ('leg 3', 'legs 1-2', ...)."""
        return "" if self.at is None else where_text(index, int(self.at[index]))


@dataclass(frozen=True)
class Travel:
    """How far a pose moves along a direction before a limit: `step` (in units of the
    direction: m or rad along a unit axis), the limit that stops it and where ("" and None when
    nothing does within `reach`), `inside` False when the start pose is already outside."""

    step: float
    limit: str | None
    where: str
    reach: float     # the largest step looked at
    inside: bool = True


def where_text(limit: int, element: int) -> str:
    """The leg, pair or obstacle and leg of a limit's element: 'leg 3', 'legs 1-2',
    '[1] leg 4' (the obstacle clearance.obstacles[1]), '' for cond."""
    kind = LIMITS[limit].kind
    if kind == table.LIMIT_LEG:
        return f"leg {element + 1}"
    if kind == table.LIMIT_PAIR:
        i, j = pair_legs(element)
        return f"legs {i}-{j}"
    if kind == table.LIMIT_OBSTACLE:
        o, leg = divmod(element, 6)
        return f"[{o}] leg {leg + 1}"
    return ""


class Engine:
    """The feasibility engine of one model with the drives' bounds and a cond(J) limit (None:
    cond not limited): convert once, call often."""

    def __init__(self, model, drive: DriveBounds | None = None,
                 cond_limit: float | None = COND_LIMIT):
        self.model = model
        r = np.array(model.reach, dtype=float)
        off = table.reach_offset
        r[off("COND_LIMIT")] = np.inf if cond_limit is None else float(cond_limit)
        drive = drive or DriveBounds()
        for name in ("speed", "acceleration", "force"):
            value = getattr(drive, name)
            r[off(name.upper())] = np.inf if value is None else float(value)
        r.flags.writeable = False
        self.reach = r
        self._reach_ptr = _ffi.from_buffer(r)
        self._params = model.native.ptr
        self._lc = model.characteristic_length
        self._span = model.leg_max if model.leg_max is not None else 10.0 * self._lc
        self._frames: dict[str, tuple] = {}   # frame name -> its (mov, fix) array and pointer
        self._out = (_ffi.new("double *"), _ffi.new("int *"), _ffi.new("int *"))
        self._margin = np.empty(len(LIMITS))
        self._where = np.empty(len(LIMITS), dtype=np.intc)
        self._margin_ptr = _ffi.from_buffer(self._margin)
        self._where_ptr = _ffi.from_buffer("int[]", self._where)

    def present(self, rates: bool = False, accelerations: bool = False) -> tuple[table.Limit, ...]:
        """The limits a call computes (with rates; with rates and accelerations)."""
        out = np.zeros(len(LIMITS), dtype=np.intc)
        _lib.stewart_reach_present(self._params, self._reach_ptr, int(rates),
                                   int(rates and accelerations), _ffi.from_buffer("int[]", out))
        return tuple(lim for lim in LIMITS if out[lim.index])

    def check(self, Q, QD=None, QDD=None) -> np.ndarray:
        """Every present limit's margin at each pose (N, 6) (rates QD and accelerations QDD
        optional; QDD only with QD): a structured array (N,) with fields `feasible` (bool),
        `binding` (the binding limit's index in LIMITS, -1 inside), then per present limit
        `<name>` (its margin) and `<name>_at` (the leg 0..5, pair 0..14 or 6 obstacle + leg).
        TrajectoryError naming the first pose that is not finite."""
        Q = _rows(Q, "poses")
        QD = None if QD is None else _rows(QD, "rates", len(Q))
        QDD = None if QDD is None or QD is None else _rows(QDD, "accelerations", len(Q))
        n, k = len(Q), len(LIMITS)
        margins, where = np.empty((n, k)), np.empty((n, k), dtype=np.intc)
        binding = np.empty(n, dtype=np.intc)
        b = _ffi.from_buffer
        got = _lib.stewart_reach_batch(self._params, self._reach_ptr, n, b(Q),
                                       _ffi.NULL if QD is None else b(QD),
                                       _ffi.NULL if QDD is None else b(QDD), b(margins),
                                       b("int[]", where), b("int[]", binding))
        if got < 0:
            bad = -got - 1
            raise TrajectoryError(f"pose row {bad + 1} (or its rates) is not finite", index=bad)
        present = self.present(QD is not None, QDD is not None)
        fields = [("feasible", bool), ("binding", np.int16)]
        for lim in present:
            fields += [(lim.name, float), (f"{lim.name}_at", np.int16)]
        out = np.empty(n, dtype=fields)
        out["feasible"] = binding < 0
        out["binding"] = binding
        for lim in present:
            out[lim.name] = margins[:, lim.index]
            out[f"{lim.name}_at"] = where[:, lim.index]
        return out

    def verdict(self, q, qd=None, qdd=None) -> Verdict:
        """One pose (6,) (rates, accelerations optional): the binding limit and where, and every
        limit's margin (+inf for those not present), in one C call (stewart_reach_margins) with
        no table built: what a per-sample check takes. TrajectoryError for a non-finite pose."""
        b = _ffi.from_buffer
        q = np.ascontiguousarray(q, dtype=float)
        rates = _ffi.NULL if qd is None else b(np.ascontiguousarray(qd, dtype=float))
        accel = _ffi.NULL if qdd is None or qd is None \
            else b(np.ascontiguousarray(qdd, dtype=float))
        k = _lib.stewart_reach_margins(self._params, self._reach_ptr, b(q), rates, accel,
                                       self._margin_ptr, self._where_ptr)
        if k == len(LIMITS):
            raise TrajectoryError("the pose (or its rates) is not finite")
        at = self._where.copy()
        if k < 0:
            return Verdict(None, "", self._margin.copy(), at)
        return Verdict(NAMES[k], where_text(k, int(self._where[k])), self._margin.copy(), at)

    def binding(self, Q) -> np.ndarray:
        """The binding limit of each pose (N, 6) of the geometric limits and cond(J), an index
        into LIMITS (-1: inside every one), as `check` finds it, faster: the margins' values
        are not computed where their sign is sure (stewart_reach_binding)."""
        Q = _rows(Q, "poses")
        out = np.empty(len(Q), dtype=np.intc)
        got = _lib.stewart_reach_binding(self._params, self._reach_ptr, len(Q),
                                         _ffi.from_buffer(Q), _ffi.from_buffer("int[]", out))
        if got < 0:
            raise TrajectoryError(f"pose row {-got} is not finite", index=-got - 1)
        return out

    def travel(self, q0, direction, frame: str = "platform", reach: float | None = None,
               tol: float = TOL, step: float | None = None) -> Travel:
        """The largest step s with q0 + t direction inside every geometric limit and cond(J)
        for t in [0, s] (poses in `frame`), the first limit found to `tol` however narrow the
        region outside it: conservative advancement (stewart_reach_travel: each step no longer
        than every limit's margin over a bound of how fast it can fall along the line), in
        steps of at most `step` (default: the characteristic length / MARCH_STEPS, in scaled
        units) up to `reach` (default: a half turn of the angles, twice the longest leg (or 10
        characteristic lengths) of the position). A line that runs along a limit, within tol
        of certifying for 10^6 poses, stops at the last pose certified, named by that limit."""
        q0 = np.ascontiguousarray(q0, dtype=float)
        d = np.ascontiguousarray(direction, dtype=float)
        if q0.shape != (6,) or d.shape != (6,):
            raise StewartError("travel: the pose and the direction must be six numbers each")
        dx, dy, dz, ax, ay, az = d.tolist()
        lin, ang = math.sqrt(dx * dx + dy * dy + dz * dz), math.sqrt(ax * ax + ay * ay + az * az)
        if not (math.isfinite(lin) and math.isfinite(ang)) or (lin == 0.0 and ang == 0.0):
            raise StewartError(f"travel: the direction must be finite and not zero, got "
                               f"{d.tolist()}")
        lc = self._lc
        if reach is None:
            reach = min(2.0 * self._span / lin if lin else math.inf,
                        math.pi / ang if ang else math.inf)
        if step is None:
            step = lc / MARCH_STEPS / math.hypot(lin, lc * ang)
        step = max(step, reach * 64.0 / 1e7)   # the steps' bound (stewart_reach_travel)
        change = self._frames.get(frame)
        if change is None:
            arr = frame_change(self.model, frame)
            ptr = _ffi.NULL if arr is None else _ffi.from_buffer(arr)
            change = self._frames[frame] = (arr, ptr)
        s, limit, where = self._out
        b = _ffi.from_buffer
        status = _lib.stewart_reach_travel(self._params, self._reach_ptr, change[1], b(q0), b(d),
                                           step, reach, tol, s, limit, where)
        if status < 0:
            raise StewartError(f"travel: refused: the pose not finite, or reach {reach!r}, step "
                               f"{step!r} or tol {tol!r} not finite and > 0 (or reach / step "
                               "beyond 156250)")
        if limit[0] < 0:
            return Travel(s[0], None, "", reach)
        return Travel(s[0], NAMES[limit[0]], where_text(limit[0], where[0]), reach, status != 1)


AXES = ("x", "y", "z", "thx", "thy", "thz")


@dataclass(frozen=True)
class AxisRange:
    """One row of the datasheet table: the travel from home along one axis, both signs, with
    the limit that ends each ("" where nothing does within `reach`)."""

    axis: str
    minus: float
    minus_limit: str
    minus_where: str
    plus: float
    plus_limit: str
    plus_where: str


def axis_ranges(engine: Engine, frame: str = "platform", start=None,
                tol: float = TOL) -> tuple[AxisRange, ...]:
    """Per-axis travel from `start` (the pose in `frame`; default home written in it) along each
    axis of the frame, the others held: the datasheet's ranges (interdependent: each with the
    others at the start's values)."""
    from .frames import from_platform
    q0 = from_platform(engine.model, engine.model.home, frame) if start is None else start
    rows = []
    for k, axis in enumerate(AXES):
        ends = []
        for sign in (-1.0, 1.0):
            d = np.zeros(6)
            d[k] = sign
            t = engine.travel(q0, d, frame=frame, tol=tol)
            ends.append((sign * t.step, t.limit or "", t.where))
        rows.append(AxisRange(axis, *ends[0], *ends[1]))
    return tuple(rows)


def _rows(a, what: str, n: int | None = None) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 6 or (n is not None and arr.shape[0] != n):
        raise TrajectoryError(f"{what}: need ({'N' if n is None else n}, 6) values, got "
                              f"{np.shape(a)}")
    return arr
