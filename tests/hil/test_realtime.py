"""The real-time serve loop on a simulated clock (deterministic): input drained before every
tick, no skipped ticks after a stall (device time stays on the wall clock), the watchdog by the
wall clock, lateness statistics; and the host's timing helpers."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.framing import Receiver  # noqa: E402
from hil.serve import serve  # noqa: E402
from hil.timing import Lateness, gc_frozen, wait_until  # noqa: E402
from hil.warmup import warm_up  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


class SimClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class SimTransport:
    """Datagrams queued by wall time; recv(timeout) advances the simulated clock."""

    def __init__(self, clock: SimClock) -> None:
        self.clock = clock
        self.inbox: list[tuple[float, bytes]] = []
        self.sent: list[bytes] = []

    def send(self, data: bytes) -> int:
        self.sent.append(data)
        return len(data)

    def recv(self, timeout: float = 0.0) -> bytes:
        if self.inbox and self.inbox[0][0] <= self.clock.t:
            return self.inbox.pop(0)[1]
        nxt = self.inbox[0][0] if self.inbox else math.inf
        self.clock.t = min(self.clock.t + timeout, max(nxt, self.clock.t))
        if self.inbox and self.inbox[0][0] <= self.clock.t:
            return self.inbox.pop(0)[1]
        return b""

    def close(self) -> None:
        pass


def host():
    return ms.MAVLink(None, srcSystem=255, srcComponent=190)


def frame(mav, msg) -> bytes:
    data = bytes(msg.pack(mav))
    mav.seq = (mav.seq + 1) % 256
    return data


def setpoint(k, lengths):
    return ms.MAVLink_leg_setpoint_message(k, k, list(map(float, lengths)), [0.0] * 6, 0)


class Recording(Device):
    """Records the tick count at which every message is handled, and can stall one tick."""

    def __init__(self, *a, stall_at=None, stall=0.0, clock=None, **kw):
        super().__init__(*a, **kw)
        self.handled_at: list[tuple[str, int]] = []
        self.handled_wall: list[float] = []
        self._stall = (stall_at, stall, clock)

    def receive(self, msg):
        clock = self._stall[2]
        self.handled_at.append((msg.get_type(), self.k))
        self.handled_wall.append(clock.t if clock is not None else math.nan)
        return super().receive(msg)

    def tick(self, step=None):
        at, stall, clock = self._stall
        if at is not None and self.k == at:
            clock.t += stall       # this tick takes `stall` s of wall time
        return super().tick(step)


def test_backlog_is_drained_before_the_next_tick(model):
    clock = SimClock()
    tr = SimTransport(clock)
    dev = Recording(model)
    mav = host()
    l0 = dev.plant.outputs.lengths
    tr.inbox.append((clock.t, frame(mav, ms.MAVLink_command_long_message(
        1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))))
    # 40 setpoints all waiting at 2.5 ms: handled together before tick 3
    tr.inbox += [(clock.t + 0.0025, frame(mav, setpoint(k, l0))) for k in range(40)]
    st = serve(dev, tr, True, max_ticks=10, clock=clock)
    ks = [k for t, k in dev.handled_at if t == "LEG_SETPOINT"]
    assert ks == [2] * 40 and dev.counters.setpoints_accepted == 40
    assert st.ticks == 10 and dev.k == 10 and st.messages_in == 41


class SimUdpServer(SimTransport):
    """An unconnected UDP server end (as hil.link.udp_server) on the simulated clock: every
    datagram comes from SENDER; what is sent goes to `peer`, or nowhere while it is None."""

    SENDER = ("127.0.0.1", 40000)
    connected = False

    def __init__(self, clock: SimClock) -> None:
        super().__init__(clock)
        self.follow_sender = True
        self.peer = self.sender = None

    def send(self, data: bytes) -> int:
        return super().send(data) if self.peer is not None else 0

    def recv(self, timeout: float = 0.0) -> bytes:
        data = super().recv(timeout)
        if data:
            self.sender = self.SENDER
        return data


def test_first_datagram_drained_before_a_tick_makes_its_sender_the_peer(model):
    """A host's first datagram that arrives while the loop catches up is taken by the drain
    before a tick; the peer rule (hil.peer) must see it there too, or the device never answers
    that host (its replies and telemetry would go nowhere)."""
    clock = SimClock()
    tr = SimUdpServer(clock)
    dev = Recording(model, stall_at=50, stall=0.05, clock=clock)
    mav = host()
    t_req = clock.t + 0.0515    # arrives during the stall of tick 50: drained at the catch-up
    tr.inbox.append((t_req, frame(mav, ms.MAVLink_param_request_list_message(1, 1))))
    st = serve(dev, tr, True, max_ticks=200, clock=clock)
    i = [t for t, _ in dev.handled_at].index("PARAM_REQUEST_LIST")
    assert dev.handled_wall[i] > t_req + 0.04 and st.ticks == 200   # taken at the catch-up
    assert tr.peer == SimUdpServer.SENDER and dev.counters.frames_valid == 1
    replies = [m for f in tr.sent for m in Receiver(ms).feed(f)]
    names = [m.get_type() for m in replies]
    assert names.count("PARAM_VALUE") == len(dev.params)            # every parameter answered
    assert names[:len(dev.params)] == ["PARAM_VALUE"] * len(dev.params)   # before telemetry


def test_no_tick_skipped_after_a_stall_device_time_stays_on_the_wall_clock(model):
    clock = SimClock()
    tr = SimTransport(clock)
    dev = Recording(model, stall_at=100, stall=0.2, clock=clock)
    start = clock.t
    st = serve(dev, tr, True, max_ticks=1000, clock=clock)
    # every tick ran: device time k / rate == the wall time of the schedule
    assert st.ticks == dev.k == 1000
    assert dev.time == pytest.approx(clock.t - start, abs=dev.dt)
    assert st.overruns == 1 and dev.counters.overruns == 1
    assert st.late.count == 1000
    assert st.late.misses in (198, 199)  # ticks due in the 0.2 s stall, a period late or more (fp)
    assert st.late.max == pytest.approx(0.2 - dev.dt, abs=1e-9)
    s = st.late.summary()
    assert s["p50"] <= s["p99"] <= s["p99.9"] <= s["max"]


def test_watchdog_by_the_wall_clock_not_by_caught_up_ticks(model):
    """Served in real time the watchdog trips `watchdog` s of wall time after the last
    setpoint, however many ticks a catch-up runs in between."""
    clock = SimClock()
    tr = SimTransport(clock)
    dev = Recording(model, watchdog=0.2, stall_at=50, stall=0.05, clock=clock)
    mav = host()
    l0 = dev.plant.outputs.lengths
    tr.inbox.append((clock.t, frame(mav, ms.MAVLink_command_long_message(
        1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))))
    t_sp = clock.t + 0.0515     # arrives during the stall of tick 50: handled at the catch-up
    tr.inbox.append((t_sp, frame(mav, setpoint(0, l0))))
    trips = []
    orig = dev.statustext

    def spy(sev, text):
        if text.startswith("watchdog"):
            trips.append(clock.t)
        return orig(sev, text)

    dev.statustext = spy
    serve(dev, tr, True, max_ticks=400, clock=clock)
    assert dev.counters.watchdog_trips == 1 and len(trips) == 1
    i = [t for t, _ in dev.handled_at].index("LEG_SETPOINT")
    k_sp, wall_sp = dev.handled_at[i][1], dev.handled_wall[i]
    assert wall_sp > t_sp + 0.04            # taken at the catch-up after the stall
    # 0.2 s of wall time after it was taken, at the first tick past that (not 200 ticks later,
    # which the catch-up would have reached 0.05 s early)
    assert 0.2 <= trips[0] - wall_sp < 0.2 + 2 * dev.dt
    assert dev.k == 400 and k_sp < 100


class WaitLog(SimTransport):
    """SimTransport that logs every recv timeout (how the loop waits)."""

    def __init__(self, clock: SimClock) -> None:
        super().__init__(clock)
        self.timeouts: list[float] = []

    def recv(self, timeout: float = 0.0) -> bytes:
        self.timeouts.append(timeout)
        return super().recv(timeout)


def test_real_time_rate_sleeps_between_ticks(model):
    """1000 ticks take 1 s of (simulated) wall time, spent waiting in the transport until each
    tick is due (select, not a spin: a few recv calls per tick), and the telemetry goes out at
    its rates. The wall-clock figures (lateness, busy share) are benchmarks/bench_realtime_jitter.py's."""
    clock = SimClock()
    tr = WaitLog(clock)
    dev = Device(model)
    start = clock.t
    st = serve(dev, tr, True, max_ticks=1000, clock=clock)
    assert st.ticks == dev.k == 1000 and st.overruns == 0 and st.late.misses == 0
    assert clock.t - start == pytest.approx(1.0, abs=1e-9) == st.wall
    waits = [t for t in tr.timeouts if t > 0]
    assert sum(waits) == pytest.approx(1.0, abs=1e-9)       # all of it waiting for input
    assert len(tr.timeouts) <= 2 * st.ticks + 1              # one wait + one drain per tick
    names = [m.get_type() for f in tr.sent for m in Receiver(ms).feed(f)]
    assert names.count("LEG_STATE") == 100 and names.count("HEARTBEAT") == 1   # 100 Hz, 1 Hz


def test_watchdog_in_process_counts_ticks(model):
    dev = Device(model, watchdog=0.05)
    dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                                0, 0, 0, 0, 0, 0))
    dev.receive(setpoint(0, dev.plant.outputs.lengths))
    for _ in range(50):
        dev.tick()
    assert dev.counters.watchdog_trips == 0
    dev.tick()   # the first tick that starts 50 ticks (0.05 s) after the setpoint
    assert dev.counters.watchdog_trips == 1


def test_watchdog_clock_set_ignores_ticks(model):
    t = [0.0]
    dev = Device(model, watchdog=0.05)
    dev.clock = lambda: t[0]
    dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                                0, 0, 0, 0, 0, 0))
    dev.receive(setpoint(0, dev.plant.outputs.lengths))
    t[0] = 0.049
    for _ in range(200):       # a catch-up of 200 ticks within 49 ms of wall time
        dev.tick()
    assert dev.counters.watchdog_trips == 0
    t[0] = 0.05
    dev.tick()
    assert dev.counters.watchdog_trips == 1


def test_lateness_histogram():
    late = Lateness(0.001)
    for x in [0.0] * 900 + [0.0001] * 90 + [0.002] * 9 + [0.5]:
        late.add(x)
    s = late.summary()
    assert s["count"] == 1000 and s["misses"] == 10 and s["max"] == 0.5
    assert s["p50"] == pytest.approx(1e-6) and s["p99"] == pytest.approx(0.000101, abs=1e-6)
    assert s["p99.9"] == pytest.approx(0.002001, abs=1e-6)
    assert "10 deadline misses of 1000" in late.text()
    assert math.isnan(Lateness(0.001).percentile(50))


def test_wait_until_sleeps_then_spins():
    t = [0.0]
    calls = []

    def poll(timeout):
        calls.append(timeout)
        t[0] += max(timeout, 1e-5)

    wait_until(0.01, lambda: t[0], poll, spin=0.0005)
    assert calls[0] == pytest.approx(0.0095)
    assert sum(c for c in calls if c > 0) == pytest.approx(0.0095)    # slept until 0.5 ms before
    assert t[0] >= 0.01 and sum(1 for c in calls if c == 0.0) >= 40    # then spun


def test_gc_frozen_restores():
    import gc
    assert gc.isenabled()
    with gc_frozen():
        assert not gc.isenabled()
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_warm_up_leaves_no_state(model):
    dev = Device(model)
    l0 = dev.plant.outputs.lengths.copy()
    assert warm_up(model, dev.config, ticks=100) > 0
    assert dev.k == 0 and not dev.armed and np.array_equal(dev.plant.outputs.lengths, l0)


# --------------------------------------------------------------------------- a flood

# Costs on the simulated clock, as measured on the reference machine: decoding one datagram
# (a 21-byte HEARTBEAT: Device.feed), one tick, one recv that returns a datagram.
FEED_COST, TICK_COST, RECV_COST = 27e-6, 110e-6, 4e-6
HOST, ATTACKER = ("127.0.0.1", 40000), ("127.0.0.1", 50000)


class Costly(Device):
    """A device whose feed and tick take their measured time on the simulated clock."""

    def __init__(self, *a, clock: SimClock, **kw):
        super().__init__(*a, **kw)
        self._clock = clock

    def feed(self, data: bytes):
        self._clock.t += FEED_COST
        return super().feed(data)

    def tick(self, step=None):
        self._clock.t += TICK_COST
        return super().tick(step)


class FloodedServer:
    """An unconnected UDP server end on the simulated clock: the host's datagrams at their
    times, and from `flood_start` on valid HEARTBEATs from another port at `flood_rate` per s,
    in order of arrival; each datagram received costs RECV_COST."""

    connected = False

    def __init__(self, clock: SimClock, host_frames, flood_start: float, flood_rate: float):
        self.clock, self.host = clock, list(reversed(host_frames))
        self.follow_sender = True
        self.peer = self.sender = None
        self.flood_next, self.flood_dt, self.flood_sent = flood_start, 1.0 / flood_rate, 0
        self.heartbeat = frame(ms.MAVLink(None, srcSystem=200, srcComponent=1),
                               ms.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        self.sent_to: dict = {}

    def send(self, data: bytes) -> int:
        if self.peer is not None:
            self.sent_to[self.peer] = self.sent_to.get(self.peer, 0) + 1
        return len(data)

    def recv(self, timeout: float = 0.0) -> bytes:
        t_host = self.host[-1][0] if self.host else math.inf
        nxt = min(t_host, self.flood_next)
        if nxt > self.clock.t:
            self.clock.t = min(self.clock.t + timeout, nxt)
            if nxt > self.clock.t:
                return b""
        self.clock.t += RECV_COST
        if t_host <= self.flood_next:
            self.sender = HOST
            return self.host.pop()[1]
        self.sender = ATTACKER
        self.flood_next += self.flood_dt
        self.flood_sent += 1
        return self.heartbeat

    def close(self) -> None:
        pass


def _flooded_run(model, flood_limit: bool, seconds: float = 1.0, flood_rate: float = 50_000.0):
    """The host arms and streams a setpoint per tick; from 10 ms on another local port floods
    valid HEARTBEATs (unsigned device). Simulated clock: (device, server, ServeStats, lag),
    lag: the most a setpoint waited between its arrival and its handling (s)."""
    clock = SimClock()
    dev = Costly(model, clock=clock)
    mav, l0, t0 = host(), dev.plant.outputs.lengths.copy(), clock.t
    frames = [(t0, frame(mav, ms.MAVLink_command_long_message(
        1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)))]
    n = round(seconds * dev.rate)
    frames += [(t0 + (k + 0.5) * dev.dt, frame(mav, setpoint(k, l0))) for k in range(n)]
    tr = FloodedServer(clock, frames, t0 + 0.01, flood_rate)
    arrival = {k: t for k, (t, _) in enumerate(frames[1:])}
    lag = [0.0]
    receive = dev.receive

    def timed(msg):
        if msg.get_type() == "LEG_SETPOINT":
            lag[0] = max(lag[0], clock.t - arrival[msg.sequence])
        return receive(msg)

    dev.receive = timed
    st = serve(dev, tr, True, max_ticks=n, clock=clock, flood_limit=flood_limit)
    return dev, tr, st, lag[0]


def test_a_flood_from_another_port_cannot_make_the_ticks_late(model):
    """50,000 valid HEARTBEATs a second from another local port: each tick starts on time, the host's setpoints are handled
    within the tick they arrive in and its replies stay with it, and the flood's datagrams
    over their budget are dropped undecoded and counted. Without the budget the same flood is
    decoded in full: 1.35 ms of work a millisecond, a backlog that grows without end, and the
    host's setpoints reach the device later and later (a third never in the run). Simulated
    clock, measured costs (FEED_COST...): no wall-clock figure."""
    dev, tr, st, lag = _flooded_run(model, flood_limit=True)
    c = dev.counters
    assert st.ticks == dev.k == 1000 and st.late.misses == 0 and st.late.max < 0.5 * dev.dt
    assert c.setpoints_accepted == 1000 and c.watchdog_trips == 0 and dev.armed
    assert lag < dev.dt                                     # within the tick it arrived in
    assert tr.peer == HOST and c.peer_changes == 0
    assert tr.sent_to.get(ATTACKER, 0) == 0                # nothing goes to the flooder
    assert tr.flood_sent > 45_000 and c.flood_dropped > 0.99 * tr.flood_sent
    # the flood's admitted part: one stranger's burst plus its rate, and nothing more
    from hil import throttle
    admitted = tr.flood_sent - c.flood_dropped
    assert admitted * len(tr.heartbeat) <= throttle.STRANGER_BURST + throttle.STRANGER_RATE * 1.0
    # "before": no budget (the drain still stops at the tick's due time)
    dev0, tr0, st0, lag0 = _flooded_run(model, flood_limit=False, seconds=0.5)
    assert dev0.counters.flood_dropped == 0
    assert dev0.counters.setpoints_accepted < 0.7 * 500 and lag0 > 0.1   # 0.1 s late and more


def test_ticks_start_on_time_even_when_the_flood_is_the_peer(model):
    """The worst case of an unsigned device: the flooding port spoke first, so it is the peer
    and its input is not limited (hil.peer): 50,000 valid HEARTBEATs a second, 1.35 ms of
    decoding per millisecond. The drains stop at the ticks' due times (hil.serve), so every tick
    still starts within half a period and device time stays on the wall clock; the surplus
    waits in the socket. Simulated clock."""
    clock = SimClock()
    dev = Costly(model, clock=clock)
    tr = FloodedServer(clock, [], clock.t, 50_000.0)
    start = clock.t
    st = serve(dev, tr, True, max_ticks=500, clock=clock)
    assert tr.peer == ATTACKER and dev.counters.flood_dropped == 0
    assert st.ticks == dev.k == 500 and st.late.misses == 0
    assert st.late.max <= 0.5 * dev.dt + FEED_COST + RECV_COST + 1e-12
    assert dev.time == pytest.approx(clock.t - start, abs=dev.dt)
    assert dev.counters.frames_valid > 0.5 * tr.flood_sent    # the flood was decoded


def test_a_flooding_port_never_takes_the_peer_even_when_the_host_goes_quiet(model):
    """Unsigned: the host streams for 0.1 s and then goes quiet for 0.9 s (far past the peer's
    hold) while another port floods valid HEARTBEATs. That port has been over its budget within
    FLOOD_MEMORY s at every one of its admitted frames, so it never becomes the peer: the
    replies and the telemetry stay with the host. Simulated clock."""
    clock = SimClock()
    dev = Costly(model, clock=clock)
    mav, l0, t0 = host(), dev.plant.outputs.lengths.copy(), clock.t
    frames = [(t0 + (k + 0.5) * dev.dt, frame(mav, setpoint(k, l0))) for k in range(100)]
    tr = FloodedServer(clock, frames, t0 + 0.01, 50_000.0)
    st = serve(dev, tr, True, max_ticks=1000, clock=clock)
    c = dev.counters
    assert st.ticks == 1000 and st.late.misses == 0
    assert tr.peer == HOST and c.peer_changes == 0 and c.peer_kept > 0
    assert tr.sent_to.get(ATTACKER, 0) == 0 and c.flood_dropped > 0.99 * tr.flood_sent
