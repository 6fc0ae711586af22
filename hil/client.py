"""The host side: a MAVLink client of the emulated device, and the closed loop over the link.

`Client` wraps a transport of `hil.link`; `connect_pty` and `connect_udp` open the device's
serial port (its pseudo-terminal) or UDP 127.0.0.1:PORT with `pymavlink.mavutil`
(`hil.link.MavutilTransport`), and the client speaks our dialect: it packs
with a host `MAVLink` (system 255, component 190), receives through the robust
`hil.framing.Receiver` (which drops unknown ids and bad frames), and offers arm / disarm / home
(COMMAND_LONG -> COMMAND_ACK), parameter read / set, LEG_SETPOINT, POSE_SETPOINT (a pose in a
frame of the scene's [frames]: `send_pose`) and LOCKSTEP.

Closed loop over the link
-------------------------
The reference is a pose trajectory sampled at the controller rate (`controller.trajectory`);
the host sends its leg references (`leg_references`: lengths and rates) and the feed-forward
force F of the configured mode with its rate dF/dt (`controller.feedforward.feedforward_force`:
``kane``, the Kane inverse dynamics; ``constant_load``, m lddot + b ldot of the axis model;
``none``: no force, the FORCE_VALID flag cleared). The device applies R i + L di/dt + Ke ldot
with i = F / Kf, as the in-process loop does, so lockstep over the link equals
`controller.cosim.run_closed_loop` (test_hil_client).

* `run_lockstep`: for each sample k, LEG_SETPOINT(k) + LOCKSTEP(k), then wait (bounded) for
  LEG_STATE(step=k); both go in one transport send (one datagram over UDP, so a lossy link
  loses both or neither: the device must never tick step k without setpoint k, and it does not
  check that itself); on a timeout both are sent again (the device answers a repeated step
  without ticking), up to `retries` times. The state after step k is at device time t_(k+1),
  so row k compares it with the reference at t_(k+1) (the last sample past the end). The run
  is deterministic and equals `run_lockstep_direct` (the same device driven in process) bit
  for bit.
* `run_realtime`: the device runs on its own clock; the host sends setpoint k at wall time
  t0 + t_k and records every LEG_STATE as it arrives (the LEG_STATE stream is raised to the
  controller rate through the parameter SR_LEG_STATE). The device time of a state is mapped
  to host time by the smallest (host receive time - device time) seen over `sync_time` before
  and during the run (so it includes the one-way latency of the fastest message), and the error is taken against the
  reference at that time (linear interpolation, held at the ends). Latency and loss of the
  link therefore show up in the tracking error. The host waits for each due time with a hybrid
  schedule (select until half a millisecond before, then a non-blocking spin:
  `hil.timing.wait_until`), with the garbage collector frozen during the run, and reports how
  late each setpoint went out (`LinkSummary.send_late`, `deadline_misses`).

Both return a `LinkRun`: a structured array (one row per state: time, step, l_ref1..6,
l1..6, e1..6, ldot1..6, force1..6, rtt) and a `LinkSummary` (RMS / max leg errors, messages
sent / received / lost, round-trip latency statistics). In lockstep with `currents=True` the
host raises the DRIVE_STATUS stream to the controller rate (parameter SR_DRIVE_STATUS) and
keeps, for each LEG_STATE, the motor currents of the DRIVE_STATUS of the same device time
(`LinkRun.currents`; DRIVE_STATUS goes out before LEG_STATE in the same tick's reply).
"""
from __future__ import annotations

import dataclasses
import ipaddress
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from controller.config import ControllerConfig, scene_axis
from controller.feedforward import feedforward_force
from controller.trajectory import LegReferences, Trajectory, leg_references
from hil import mavlink_stewart as ms
from hil.dialect import connection
from hil.errors import LinkError
from hil.framing import Receiver, pack
from hil.link import MavutilTransport
from hil.pose_setpoint import FRAMES
from hil.spawn import parse_udp
from hil.timing import Lateness, gc_frozen, wait_until
from stewart_fmu.errors import StewartError
from stewart_fmu.io import named_array
from stewart_fmu.model import Model

HOST_SYSTEM, HOST_COMPONENT = 255, 190
TIMEOUT = 0.5        # s: default wait for one reply
RETRIES = 5          # lockstep resends of one step before giving up
_FLAGS_RATE = ms.STEWART_SETPOINT_FLAG_RATE_VALID
_FLAGS_FORCE = ms.STEWART_SETPOINT_FLAG_FORCE_VALID
_FLAGS_FORCE_RATE = ms.STEWART_SETPOINT_FLAG_FORCE_RATE_VALID
_FRAME_CODES = {name: code for code, name in FRAMES.items()}   # frame name -> STEWART_FRAME


# ---------------------------------------------------------------- connecting

def connect_pty(path: str, baud: int = 921600) -> MavutilTransport:
    """Open the device's serial port (here its pseudo-terminal `path`) with
    pymavlink.mavutil (mavserial over pyserial: raw mode, `baud`, non-blocking)."""

    try:
        mf = connection(path, baud=baud, source_system=HOST_SYSTEM,
                        source_component=HOST_COMPONENT)
    except OSError as exc:          # pyserial's SerialException is an OSError
        raise LinkError(f"cannot open {path}: {exc}") from exc
    return MavutilTransport(mf, f"serial {path}")


def connect_udp(host: str, port: int) -> MavutilTransport:
    """pymavlink.mavutil's `udpout` connection to the device at host:port (loopback only)."""


    if host == "localhost":
        host = "127.0.0.1"
    if not ipaddress.IPv4Address(host).is_loopback:
        raise LinkError(f"connect_udp: {host} is not a loopback address")
    try:
        mf = connection(f"udpout:{host}:{port}", source_system=HOST_SYSTEM,
                        source_component=HOST_COMPONENT)
    except OSError as exc:
        raise LinkError(f"udp {host}:{port}: {exc}") from exc
    return MavutilTransport(mf, f"udp {host}:{port}")


def connect_device(link: str, first: str) -> tuple[MavutilTransport, str]:
    """(transport, description) to a device process whose first line is `first` (hil.spawn):
    ``udp 127.0.0.1:PORT`` over UDP, the pseudo-terminal's path over ``serial``."""

    if link == "udp":
        host, port = parse_udp(first)
        return connect_udp(host, port), f"UDP {host}:{port}"
    return connect_pty(first), f"pseudo-terminal {first}"


# ---------------------------------------------------------------- the client

@dataclass
class ClientCounters:
    sent: int = 0
    received: int = 0
    by_type: dict[str, int] = field(default_factory=dict)
    statustexts: list[str] = field(default_factory=list)


class Client:
    """A host-side MAVLink client of the device over `transport` (see the module doc)."""

    def __init__(self, transport, target_system: int = 1, target_component: int = 1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.transport = transport
        self.target = (target_system, target_component)
        self.mav = ms.MAVLink(None, srcSystem=HOST_SYSTEM, srcComponent=HOST_COMPONENT)
        self.rx = Receiver(ms, self.mav)
        self.counters = ClientCounters()
        self.clock = clock
        self._inbox: list[Any] = []
        self.on_message: Callable[[Any, float], None] | None = None

    # --- bytes and messages --------------------------------------------------------------

    def send(self, *msgs: Any) -> None:
        """Pack and send each message (one transport send per message), each frame numbered
        (hil.framing.pack)."""
        for m in msgs:
            self.transport.send(pack(self.mav, m))
            self.counters.sent += 1

    def send_together(self, *msgs: Any) -> None:
        """Pack the messages into one transport send (one datagram: lost or delivered together)."""
        self.transport.send(b"".join(pack(self.mav, m) for m in msgs))
        self.counters.sent += len(msgs)

    def poll(self, timeout: float = 0.0) -> list[Any]:
        """Messages decoded from what arrives within `timeout` s (then whatever else is queued)."""
        out: list[Any] = []
        data = self.transport.recv(timeout)
        while data:
            now = self.clock()
            for m in self.rx.feed(data):
                self._note(m, now)
                out.append(m)
            data = self.transport.recv(0.0)
        return out

    def _note(self, m: Any, now: float) -> None:
        c = self.counters
        c.received += 1
        t = m.get_type()
        c.by_type[t] = c.by_type.get(t, 0) + 1
        if t == "STATUSTEXT":
            c.statustexts.append(m.text)
        if self.on_message is not None:
            self.on_message(m, now)

    def wait_for(self, match: Callable[[Any], bool], timeout: float = TIMEOUT) -> Any | None:
        """The first message (received from now on, or kept from earlier waits) that `match`es,
        within `timeout` s; None if none came. Other messages are kept for later waits."""
        for i, m in enumerate(self._inbox):
            if match(m):
                return self._inbox.pop(i)
        deadline = self.clock() + timeout
        while True:
            left = deadline - self.clock()
            if left < 0:
                return None
            for j, m in enumerate(got := self.poll(min(left, 0.05))):
                if match(m):
                    self._inbox += got[j + 1:]
                    self._trim()
                    return m
            self._inbox += got
            self._trim()

    def _trim(self) -> None:
        if len(self._inbox) > 1000:
            del self._inbox[:-1000]

    def drain(self) -> None:
        """Forget kept messages and whatever is waiting on the link."""
        self.poll(0.0)
        self._inbox.clear()

    # --- commands and parameters --------------------------------------------------------

    def command(self, cmd: int, *params: float, timeout: float = TIMEOUT, retries: int = 20) -> int:
        """COMMAND_LONG -> the COMMAND_ACK result (LinkError when no ack comes)."""
        p = list(params) + [0.0] * (7 - len(params))
        for attempt in range(retries + 1):
            self.send(ms.MAVLink_command_long_message(*self.target, cmd, attempt, *p))
            ack = self.wait_for(lambda m: m.get_type() == "COMMAND_ACK" and m.command == cmd, timeout)
            if ack is not None:
                return ack.result
        raise LinkError(f"no COMMAND_ACK for command {cmd} after {retries + 1} tries")

    def arm(self, timeout: float = TIMEOUT) -> bool:
        return self.command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1,
                            timeout=timeout) == ms.MAV_RESULT_ACCEPTED

    def disarm(self, timeout: float = TIMEOUT) -> bool:
        return self.command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                            timeout=timeout) == ms.MAV_RESULT_ACCEPTED

    def home(self, timeout: float = TIMEOUT) -> bool:
        return self.command(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                            timeout=timeout) == ms.MAV_RESULT_ACCEPTED

    def _param_reply(self, name: str | None, timeout: float) -> Any | None:
        def match(m):
            return m.get_type() == "PARAM_VALUE" and (name is None or _name(m.param_id) == name)
        return self.wait_for(match, timeout)

    def get_param(self, name: str, timeout: float = TIMEOUT, retries: int = 20) -> float:
        for _ in range(retries + 1):
            self.send(ms.MAVLink_param_request_read_message(*self.target, name.encode(), -1))
            m = self._param_reply(name, timeout)
            if m is not None:
                return float(m.param_value)
        raise LinkError(f"no PARAM_VALUE for {name}")

    def set_param(self, name: str, value: float, timeout: float = TIMEOUT, retries: int = 20) -> float:
        """PARAM_SET; returns the value the device reports afterwards (unchanged if refused)."""
        for _ in range(retries + 1):
            self.send(ms.MAVLink_param_set_message(*self.target, name.encode(), float(value),
                                                   ms.MAV_PARAM_TYPE_REAL32))
            m = self._param_reply(name, timeout)
            if m is not None:
                return float(m.param_value)
        raise LinkError(f"no PARAM_VALUE for {name} after PARAM_SET")

    def params(self, timeout: float = 2.0) -> dict[str, float]:
        """PARAM_REQUEST_LIST: every parameter (name -> value)."""
        self.send(ms.MAVLink_param_request_list_message(*self.target))
        out: dict[str, float] = {}
        count = None
        deadline = self.clock() + timeout
        while count is None or len(out) < count:
            m = self._param_reply(None, max(0.0, deadline - self.clock()))
            if m is None:
                break
            out[_name(m.param_id)] = float(m.param_value)
            count = m.param_count
        return out

    def ping(self, timeout: float = TIMEOUT) -> float | None:
        """Round trip of PARAM_REQUEST_READ(index 0) -> PARAM_VALUE in seconds (None: lost)."""
        self.drain()
        t0 = time.perf_counter()
        self.send(ms.MAVLink_param_request_read_message(*self.target, b"", 0))
        m = self.wait_for(lambda m: m.get_type() == "PARAM_VALUE", timeout)
        return None if m is None else time.perf_counter() - t0

    # --- setpoints -------------------------------------------------------------------------

    def setpoint_message(self, seq: int, t: float, l, ldot, force=None, force_rate=None) -> Any:
        """LEG_SETPOINT with the rate, and the force (and its rate) feed-forward when given."""
        flags = (_FLAGS_RATE | (_FLAGS_FORCE if force is not None else 0)
                 | (_FLAGS_FORCE_RATE if force is not None and force_rate is not None else 0))
        f = [0.0] * 6 if force is None else [float(x) for x in force]
        fr = [0.0] * 6 if force_rate is None else [float(x) for x in force_rate]
        return ms.MAVLink_leg_setpoint_message(int(round(t * 1e6)), seq & 0xFFFFFFFF,
                                               [float(x) for x in l], [float(x) for x in ldot],
                                               flags, f, fr)

    def pose_setpoint_message(self, seq: int, t: float, pose, frame: str = "platform",
                              hold: bool = False, rate=None) -> Any:
        """POSE_SETPOINT of `pose` (x, y, z, thx, thy, thz; m, rad) in `frame` (platform,
        pivot, tool or user: the scene's [frames]); with `rate` (dx, dy, dz, dthx, dthy, dthz;
        m/s, rad/s Euler-angle rates, in `frame`) its RATE_VALID, the device's leg-rate
        feed-forward; HOLD (pose and rate ignored) with `hold`. StewartError naming an unknown
        frame or a pose or rate that is not six numbers."""
        code = _FRAME_CODES.get(frame)
        if code is None:
            raise StewartError(f"frame {frame!r}: unknown frame (known: {', '.join(_FRAME_CODES)})")
        p = np.asarray(pose, dtype=float)
        if p.shape != (6,):
            raise StewartError(f"pose: six numbers x, y, z, thx, thy, thz, got shape {p.shape}")
        flags = ms.STEWART_POSE_SETPOINT_FLAG_HOLD if hold else 0
        if rate is None:
            return ms.MAVLink_pose_setpoint_message(int(round(t * 1e6)), seq & 0xFFFFFFFF,
                                                    *map(float, p), code, flags)
        r = np.asarray(rate, dtype=float)
        if r.shape != (6,):
            raise StewartError(f"rate: six numbers dx, dy, dz, dthx, dthy, dthz, got shape "
                               f"{r.shape}")
        return ms.MAVLink_pose_setpoint_message(
            int(round(t * 1e6)), seq & 0xFFFFFFFF, *map(float, p), code,
            flags | ms.STEWART_POSE_SETPOINT_FLAG_RATE_VALID, [float(v) for v in r])

    def send_pose(self, seq: int, t: float, pose, frame: str = "platform", rate=None) -> None:
        """Send POSE_SETPOINT `seq` of `pose` in `frame` at time `t` (s), with its `rate` when
        given (pose_setpoint_message)."""
        self.send(self.pose_setpoint_message(seq, t, pose, frame, rate=rate))

    def reference_setpoint(self, ref: "LinkReference", k: int) -> Any:
        """LEG_SETPOINT k of a LinkReference (sequence k, its time, lengths, rates, feedforward)."""
        r = ref.refs
        return self.setpoint_message(k, r.t[k], r.l[k], r.ldot[k],
                                     None if ref.force is None else ref.force[k],
                                     None if ref.force_rate is None else ref.force_rate[k])

    def close(self) -> None:
        self.transport.close()


def _name(param_id: Any) -> str:
    if isinstance(param_id, bytes):
        param_id = param_id.decode("ascii", "replace")
    return str(param_id).rstrip("\x00")


# ---------------------------------------------------------------- references

@dataclass(frozen=True)
class LinkReference:
    """What the host sends: times, leg references and the feed-forward force (or None)."""

    traj: Trajectory
    refs: LegReferences
    force: np.ndarray | None
    force_rate: np.ndarray | None
    feedforward: str


def link_reference(model: Model, config: ControllerConfig, traj: Trajectory) -> LinkReference:
    """Leg references of `traj`, the feed-forward force of config.feedforward and its rate
    (controller.feedforward.feedforward_force: the in-process loop's feedforward)."""
    refs = leg_references(model, traj)
    force = feedforward_force(model, config, scene_axis(model, config),
                              traj, refs)
    rate = None if force is None else np.gradient(force, traj.t, axis=0)
    return LinkReference(traj, refs, force, rate, config.feedforward)


# ---------------------------------------------------------------- results

@dataclass(frozen=True)
class LinkSummary:
    mode: str
    samples: int
    leg_rms: np.ndarray       # (6,) m
    leg_max: np.ndarray       # (6,) m
    sent: int
    received: int
    lost: int                 # lockstep: resends after a timeout; real time: LEG_STATEs missing
    rtt_median: float         # s (nan if not measured)
    rtt_p99: float
    rtt_max: float
    wall_time: float
    statustexts: tuple[str, ...] = ()
    # real time: how late the host sent its setpoints after their due times (s): p50, p99,
    # p99.9, max (hil.timing.Lateness), and the deadline misses (a period or more late)
    send_late: tuple[float, float, float, float] = (math.nan,) * 4
    deadline_misses: int = 0

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.leg_rms ** 2)))

    @property
    def max(self) -> float:
        return float(np.max(self.leg_max))


@dataclass(frozen=True)
class LinkRun:
    table: np.ndarray
    summary: LinkSummary
    currents: np.ndarray | None = None   # (rows, 6) A, DRIVE_STATUS of each state (lockstep)


def _currents(states: list[Any], by_usec: dict[int, Any]) -> np.ndarray:
    """The DRIVE_STATUS currents of each LEG_STATE's device time (LinkError when one is
    missing)."""
    missing = [s.time_usec for s in states if s.time_usec not in by_usec]
    if missing:
        raise LinkError(f"lockstep: no DRIVE_STATUS at device time {missing[0] * 1e-6:g} s "
                        f"({len(missing)} missing)")
    return np.array([by_usec[s.time_usec].current for s in states], float).reshape(-1, 6)


def _table(time_s, step, l_ref, l, ldot, force, rtt) -> np.ndarray:
    cols: dict[str, np.ndarray] = {"time": np.asarray(time_s, float), "step": np.asarray(step, float)}
    for name, arr in (("l_ref", l_ref), ("l", l), ("e", l_ref - l), ("ldot", ldot), ("force", force)):
        cols.update({f"{name}{i + 1}": arr[:, i] for i in range(6)})
    cols["rtt"] = np.asarray(rtt, float)
    return named_array(cols)


def _summarise(mode: str, table: np.ndarray, sent: int, received: int, lost: int, wall: float,
               texts=()) -> LinkSummary:
    e = np.column_stack([table[f"e{i}"] for i in range(1, 7)]) if len(table) else np.zeros((1, 6))
    rtt = table["rtt"][np.isfinite(table["rtt"])] if len(table) else np.array([])
    stats = ((float(np.median(rtt)), float(np.percentile(rtt, 99)), float(np.max(rtt)))
             if len(rtt) else (math.nan,) * 3)
    return LinkSummary(mode, len(table), np.sqrt(np.mean(e ** 2, axis=0)), np.max(np.abs(e), axis=0),
                       sent, received, lost, *stats, wall, tuple(texts))


def _state_rows(states: list[Any], ref: LinkReference) -> tuple[np.ndarray, ...]:
    """Lockstep rows: state k (after step k, at t_(k+1)) against the reference at t_(k+1)."""
    n = len(ref.refs.t)
    nxt = np.minimum(np.arange(len(states)) + 1, n - 1)
    l = np.array([s.length for s in states], float).reshape(-1, 6)
    ldot = np.array([s.rate for s in states], float).reshape(-1, 6)
    f = np.array([s.force for s in states], float).reshape(-1, 6)
    t = np.array([s.time_usec for s in states], float) * 1e-6
    return t, np.array([s.step for s in states], float), ref.refs.l[nxt], l, ldot, f


# ---------------------------------------------------------------- lockstep

def run_lockstep(client: Client, ref: LinkReference, *, timeout: float = TIMEOUT,
                 retries: int = RETRIES, arm: bool = True, currents: bool = False) -> LinkRun:
    """The lockstep closed loop over the link (see the module doc); `currents`: record the
    motor currents of every state too."""
    if arm and not client.arm():
        raise LinkError("the device refused to arm")
    drive: dict[int, Any] = {}
    if currents:
        client.set_param("SR_DRIVE_STATUS", 1.0 / float(ref.refs.t[1] - ref.refs.t[0]))
        client.on_message = (lambda m, now: drive.__setitem__(m.time_usec, m)
                             if m.get_type() == "DRIVE_STATUS" else None)
    client.drain()
    sent0, recv0 = client.counters.sent, client.counters.received
    n = len(ref.refs.t)
    states, rtts, resends = [], np.full(n, math.nan), 0
    start = time.perf_counter()
    try:
        for k in range(n):
            msgs = (client.reference_setpoint(ref, k),
                    ms.MAVLink_lockstep_message(int(round(ref.refs.t[k] * 1e6)), k))
            for attempt in range(retries + 1):
                t0 = time.perf_counter()
                client.send_together(*msgs)
                st = client.wait_for(lambda m: m.get_type() == "LEG_STATE" and m.step == k,
                                     timeout)
                if st is not None:
                    rtts[k] = time.perf_counter() - t0
                    break
                resends += 1
            else:
                raise LinkError(f"lockstep: no LEG_STATE for step {k} after {retries + 1} "
                                f"tries of {timeout:g} s")
            states.append(st)
    finally:
        client.on_message = None
    wall = time.perf_counter() - start
    t, step, l_ref, l, ldot, f = _state_rows(states, ref)
    table = _table(t, step, l_ref, l, ldot, f, rtts)
    c = client.counters
    return LinkRun(table, _summarise("lockstep", table, c.sent - sent0, c.received - recv0,
                                     resends, wall, c.statustexts),
                   _currents(states, drive) if currents else None)


def run_lockstep_direct(device, ref: LinkReference, currents: bool = False) -> LinkRun:
    """The same loop driving a lockstep `hil.device.Device` in process (no link, no encoding)."""
    host = ms.MAVLink(None, srcSystem=HOST_SYSTEM, srcComponent=HOST_COMPONENT)
    client = Client.__new__(Client)  # only for setpoint_message
    client.mav = host
    device.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                                   1, 0, 0, 0, 0, 0, 0))
    if currents:
        device.receive(ms.MAVLink_param_set_message(
            1, 1, b"SR_DRIVE_STATUS", 1.0 / float(ref.refs.t[1] - ref.refs.t[0]),
            ms.MAV_PARAM_TYPE_REAL32))
    n, states, drive = len(ref.refs.t), [], {}
    start = time.perf_counter()
    for k in range(n):
        device.receive(client.reference_setpoint(ref, k))
        out = device.receive(ms.MAVLink_lockstep_message(int(round(ref.refs.t[k] * 1e6)), k))
        states += [m for m in out if m.get_type() == "LEG_STATE" and m.step == k]
        drive.update((m.time_usec, m) for m in out if m.get_type() == "DRIVE_STATUS")
    wall = time.perf_counter() - start
    t, step, l_ref, l, ldot, f = _state_rows(states, ref)
    table = _table(t, step, l_ref, l, ldot, f, np.full(len(states), math.nan))
    return LinkRun(table, _summarise("direct", table, 2 * n, len(states), 0, wall),
                   _currents(states, drive) if currents else None)


# ---------------------------------------------------------------- real time

def run_realtime(client: Client, ref: LinkReference, *, tail: float = 0.02,
                 state_rate: float | None = None, sync_time: float = 0.2,
                 arm: bool = True, every: int = 1) -> LinkRun:
    """The real-time closed loop over the link (see the module doc); a setpoint every `every`
    controller samples (a slower link)."""
    t_ref, n = ref.refs.t, len(ref.refs.t)
    dt = float(t_ref[1] - t_ref[0]) if n > 1 else 1e-3
    rate = state_rate if state_rate is not None else 1.0 / dt
    if arm and not client.arm():
        raise LinkError("the device refused to arm")
    client.set_param("SR_LEG_STATE", rate)
    client.drain()
    # device time -> host time: the smallest (receive time - device time) over sync_time
    end = client.clock() + sync_time
    records: list[tuple[float, Any]] = []
    client.on_message = lambda m, now: records.append((now, m)) if m.get_type() == "LEG_STATE" else None
    while client.clock() < end:
        client.poll(0.002)
    if not records:
        client.on_message = None
        raise LinkError(f"real time: no LEG_STATE within {sync_time:g} s (is the device in "
                        "real-time mode?)")
    sync = list(records)
    records.clear()
    sent0, recv0 = client.counters.sent, client.counters.received
    step = max(1, int(every))
    late = Lateness(step * dt)
    msgs = [client.reference_setpoint(ref, k) for k in range(0, n, step)]  # built before
    with gc_frozen():     # no collection pauses in the loop
        t0 = client.clock()
        start = time.perf_counter()
        try:
            for k, msg in zip(range(0, n, step), msgs):
                due = t0 + t_ref[k]
                wait_until(due, client.clock, client.poll)   # sleep, then spin the last bit
                late.add(client.clock() - due)
                client.send(msg)
                client.poll(0.0)
            end = client.clock() + tail
            while (left := end - client.clock()) > 0:
                client.poll(left)
        finally:
            client.on_message = None
    wall = time.perf_counter() - start
    # device time -> host time: the smallest (receive time - device time) of the whole stream
    offset = min(now - m.time_usec * 1e-6 for now, m in sync + records)
    tau = np.array([m.time_usec * 1e-6 + offset - t0 for _, m in records], float)
    keep = (tau >= 0) & (tau <= t_ref[-1])
    states = [m for (_, m), ok in zip(records, keep) if ok]
    tau = tau[keep]
    l_ref = np.column_stack([np.interp(tau, t_ref, ref.refs.l[:, i]) for i in range(6)])
    l = np.array([s.length for s in states], float).reshape(-1, 6)
    ldot = np.array([s.rate for s in states], float).reshape(-1, 6)
    f = np.array([s.force for s in states], float).reshape(-1, 6)
    table = _table(tau, np.zeros(len(states)), l_ref, l, ldot, f, np.full(len(states), math.nan))
    # states missing from the stream (by gaps of the device time stamps)
    if len(states) > 1:
        us = np.diff(np.array([s.time_usec for s in states], float))
        period = 1e6 / rate
        lost = int(np.sum(np.maximum(np.round(us / period) - 1, 0)))
    else:
        lost = 0
    c = client.counters
    sm = _summarise("realtime", table, c.sent - sent0, c.received - recv0, lost, wall,
                    c.statustexts)
    ls = late.summary()
    sm = dataclasses.replace(sm, send_late=(ls["p50"], ls["p99"], ls["p99.9"], ls["max"]),
                             deadline_misses=late.misses)
    return LinkRun(table, sm)
