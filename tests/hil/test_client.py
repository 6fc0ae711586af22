"""hil.client (the host side) against the device served in a thread over loopback UDP, a
pseudo-terminal, or in-process queues through the link emulator. Every wait is bounded."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from controller.config import controller_config  # noqa: E402
from controller.cosim import run_closed_loop  # noqa: E402
from controller.moves import (
    move_and_hold,  # noqa: E402
    run_reference,  # noqa: E402
)
from hil import mavlink_stewart as ms  # noqa: E402
from hil.client import (  # noqa: E402
    Client,
    connect_device,
    connect_pty,
    connect_udp,
    link_reference,
    run_lockstep,
    run_lockstep_direct,
    run_realtime,
)
from hil.device import Device  # noqa: E402
from hil.link import (  # noqa: E402
    Impairments,
    LinkEmulator,
    VirtualClock,
    pty_pair,
    queue_pair,
    udp_server,  # noqa: E402
)
from hil.serve import serve_in_thread  # noqa: E402
from hil.spawn import device_process  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
# s: the longest wait for a reply that must come (a bound against a hang on a loaded machine,
# never a pass/fail figure; on a quiet machine replies take well under a millisecond)
WAIT = 10.0


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def config(model):
    return controller_config(model)


@pytest.fixture(scope="module")
def lockstep_ref(model, config):
    return link_reference(model, config, run_reference(model, config, 0.3))


@pytest.fixture(scope="module")
def direct(model, config, lockstep_ref):
    return run_lockstep_direct(Device(model, config, lockstep=True), lockstep_ref)


class Served:
    """A device served in a thread; the client end; stopped and closed on exit."""

    def __init__(self, device, dev_end, client_transport, *closers, **kw):
        self.device = device
        self.thread, self.stop, self.result = serve_in_thread(device, dev_end, poll=0.01, **kw)
        self.client = Client(client_transport)
        self.closers = (dev_end, client_transport) + closers

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(5)
        for c in self.closers:
            c.close()
        assert not self.thread.is_alive()


def udp_served(device):
    server = udp_server("127.0.0.1", 0)
    return Served(device, server, connect_udp(*server.address))


def pty_served(device):
    master, slave = pty_pair()   # the slave end stays open (never read) so the master sees no hang-up
    return Served(device, master, connect_pty(slave.name), slave)


def assert_same(a, b):
    for name in a.table.dtype.names:
        if name != "rtt":
            assert np.array_equal(a.table[name], b.table[name]), name


class SimulatedLink:
    """The host's transport to a real-time device through the link emulator, everything on one
    simulated clock in one thread, so `run_realtime` (the host loop, unchanged) runs
    deterministically whatever the machine's load. The device is stepped as hil.serve steps it:
    input is handled as soon as it has arrived (and again before each tick), tick k is due at
    (k + 1) / rate and none is skipped; its watchdog reads the same clock. Time moves only while
    the host waits in `recv`, to the next event (a tick, an arrival, the end of the wait); a
    poll that would not wait costs POLL_COST (the host loop's final spin must end)."""

    POLL_COST = 1e-5   # s of simulated time per non-blocking poll

    def __init__(self, device: Device, imp: Impairments, seed: int = 0) -> None:
        self.clock = VirtualClock()
        self.host, ea = queue_pair()
        eb, self.dev_end = queue_pair()
        self.emu = LinkEmulator(ea, eb, imp, clock=self.clock, seed=seed)
        self.device = device
        # a device in lockstep ticks only on LOCKSTEP (inside feed), as hil.serve runs it
        self.next_tick = math.inf if device.lockstep else device.dt
        if not device.lockstep:
            device.clock = self.clock.now

    def send(self, data: bytes) -> int:
        n = self.host.send(data)
        self._settle()
        return n

    def recv(self, timeout: float = 0.0) -> bytes:
        end = self.clock.now() + max(timeout, self.POLL_COST)
        while True:
            self._settle()
            data = self.host.recv(0.0)
            if data or self.clock.now() >= end:
                return data
            events = [t for t in (self.next_tick, self.emu.next_event(), end) if t is not None]
            self.clock.t = max(self.clock.now(), min(events))

    def _settle(self) -> None:
        """Deliver what has arrived by now, let the device answer it, run the ticks due."""
        self.emu.pump()
        self._device_input()
        while self.clock.now() >= self.next_tick:
            self._device_input()
            for m in self.device.tick():
                self.dev_end.send(self.device.pack(m))
            self.next_tick += self.device.dt
            self.emu.pump()

    def _device_input(self) -> None:
        while data := self.dev_end.recv(0.0):
            for m in self.device.feed(data):
                self.dev_end.send(self.device.pack(m))
        self.emu.pump()

    def close(self) -> None:
        self.host.close()


@pytest.mark.parametrize("served", [udp_served, pty_served], ids=["udp", "pty"])
def test_lockstep_over_the_link_equals_the_direct_run(model, config, lockstep_ref, direct, served):
    with served(Device(model, config, lockstep=True)) as s:
        run = run_lockstep(s.client, lockstep_ref, timeout=1.0)
    n = len(lockstep_ref.refs.t)
    assert len(run.table) == len(direct.table) == n
    assert_same(run, direct)  # bit for bit: the doubles survive the encoding
    assert run.summary.lost == 0 and run.summary.sent == 2 * n
    # every step's round trip was measured (how long it took is a figure:
    # stewart_sim.closed_loop.link_figures)
    assert np.all(np.isfinite(run.table["rtt"])) and np.all(run.table["rtt"] > 0)
    assert s.device.counters.setpoints_accepted == n and s.device.counters.lockstep_refused == 0
    assert np.array_equal(run.table["step"], np.arange(n))


def test_lockstep_resends_after_loss(model, config, direct, lockstep_ref):
    """With 20 % of the packets lost both ways, timeouts and resends give the same run. On the
    simulated clock (SimulatedLink) a timeout is one only for a lost packet, never for a late
    reply, so the resends are those the loss asks for."""
    link = SimulatedLink(Device(model, config, lockstep=True), Impairments(loss=0.2), seed=5)
    run = run_lockstep(Client(link, clock=link.clock.now), lockstep_ref, timeout=0.01,
                       retries=50)
    exchanges = link.emu.ab.stats.packets_in      # setpoint + LOCKSTEP: one datagram a try
    assert exchanges == len(lockstep_ref.refs.t) + run.summary.lost + 1   # + the arm command
    assert run.summary.lost > 10 and link.emu.ab.stats.packets_lost > 0
    assert link.emu.ba.stats.packets_lost > 0
    assert_same(run, direct)


@pytest.mark.parametrize("feedforward", ["kane", "constant_load", "none"])
def test_lockstep_over_udp_equals_the_in_process_loop(model, config, feedforward):
    """The controller of controller.cosim run in process, and its references sent over UDP to
    the device in lockstep (the device runs the same servo loops): the same leg lengths to
    1e-12, for every feedforward (the device adds R i + L di/dt + Ke ldot from F and dF/dt, and
    hands the integral over bumplessly when the feedforward stream begins). Row k of the link
    run is the state after step k, i.e. row k + 1 of the in-process table."""
    cfg = dataclasses.replace(config, feedforward=feedforward)
    traj = run_reference(model, cfg, 0.2)
    loop = run_closed_loop(model, cfg, traj).table
    with udp_served(Device(model, cfg, lockstep=True)) as s:
        run = run_lockstep(s.client, link_reference(model, cfg, traj), timeout=1.0).table
    n = len(traj.t)
    assert len(run) == n
    for i in range(1, 7):
        a, b = loop[f"l{i}"][1:], run[f"l{i}"][:n - 1]
        assert np.ptp(a) > 1e-3                                   # the legs move millimetres
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), (i, np.max(np.abs(a - b)))


def test_commands_and_parameters_over_udp(model, config):
    """Every request waits up to WAIT for its reply: a bound, not a figure (a reply that came
    after a shorter wait would make the client send again and then take the late reply of one
    request for the reply of the next)."""
    with udp_served(Device(model, config)) as s:
        c = s.client
        params = c.params(timeout=WAIT)
        assert set(params) == set(s.device.params)
        assert c.get_param("SR_LEG_STATE", timeout=WAIT) == 100.0
        assert c.set_param("SR_LEG_STATE", 250.0, timeout=WAIT) == 250.0
        assert s.device.rates["LEG_STATE"] == 250.0
        assert c.set_param("SR_LEG_STATE", -1.0, timeout=WAIT) == 250.0  # refused, unchanged
        assert c.home(timeout=WAIT) is False  # disarmed: refused
        assert c.arm(timeout=WAIT) and s.device.armed
        assert c.home(timeout=WAIT)
        assert c.disarm(timeout=WAIT) and not s.device.armed
        assert c.ping(timeout=WAIT) is not None
        # what the device said, in the order of the requests (each said right after its reply)
        texts = c.counters.statustexts
        i = texts.index("home refused: disarmed")
        assert "".join(texts[:i]).startswith("SR_LEG_STATE -1 refused")   # a long text: chunks
        assert texts[i:] == ["home refused: disarmed", "armed", "homing", "disarmed: holding"]


# ------------------------------------------------------------------------ real time

@pytest.fixture(scope="module")
def realtime_ref(model, config):
    """0.5 s: out and back (0.2 s each) by a fifth of the demo amplitudes, legs up to ~6 mm at
    up to ~60 mm/s."""
    return link_reference(model, config, move_and_hold(model, config.rate, 0.2, 0.05, back=True,
                                                       fraction=0.2))


def test_realtime_over_udp_tracks(realtime_ref):
    """The device as its own process (as `run --link` starts it), setpoints and states at 1 kHz
    over UDP on the wall clock."""
    with device_process(SCENE, "udp") as first:
        client = Client(connect_device("udp", first)[0])
        try:
            run = run_realtime(client, realtime_ref)
        finally:
            client.close()
    sm = run.summary
    print(f"\nreal time over UDP: RMS {sm.rms * 1e3:.3f} mm, max {sm.max * 1e3:.3f} mm, "
          f"{sm.samples} states, {sm.lost} lost, wall {sm.wall_time:.3f} s")
    # Only what is deterministic: every setpoint went out, states came back and the statistics
    # are figures. How well it tracks depends on the machine's load (wall clock): that figure
    # is measured by benchmarks/bench_realtime_link.py, not asserted here.
    assert sm.sent == len(realtime_ref.refs.t)
    assert sm.samples > 0 and sm.received >= sm.samples
    assert np.isfinite(sm.rms) and np.isfinite(sm.max) and sm.wall_time > 0
    # the host's deadline statistics are counted and reported (their values depend on load)
    print(f"host send lateness p50/p99/p99.9/max (us): "
          f"{'/'.join(f'{x * 1e6:.0f}' for x in sm.send_late)}, {sm.deadline_misses} misses")
    assert len(sm.send_late) == 4 and all(np.isfinite(x) and x >= 0 for x in sm.send_late)
    assert 0 <= sm.deadline_misses <= sm.sent


def _simulated_realtime(model, config, ref, latency):
    link = SimulatedLink(Device(model, config), Impairments(latency=latency))
    return run_realtime(Client(link, clock=link.clock.now), ref, every=2).summary


def test_realtime_error_grows_with_latency(model, config, realtime_ref):
    """The real-time loop through the link emulator on a simulated clock (deterministic; the
    wall-clock figure is `python -m stewart_sim.closed_loop.link_figures`): with 5 ms each way the
    setpoints reach the device 5 ms late and its states come back 5 ms late, so in host time
    the legs lag the reference and the error grows."""
    base = _simulated_realtime(model, config, realtime_ref, 0.0)
    late = _simulated_realtime(model, config, realtime_ref, 0.005)
    print(f"\nreal time, emulated link, simulated clock: RMS {base.rms * 1e3:.4f} mm without "
          f"latency, {late.rms * 1e3:.4f} mm with 5 ms each way")
    n = len(realtime_ref.refs.t)
    for s in (base, late):
        assert s.sent == len(range(0, n, 2)) and s.lost == 0 and s.deadline_misses == 0
        assert s.samples >= n - 1
    assert math.isfinite(base.rms) and late.rms > 1.5 * base.rms


# ------------------------------------------------------------------------ the command

@pytest.mark.parametrize("link,mode", [("udp", "lockstep"), ("serial", "lockstep"), ("udp", "realtime")])
def test_cli_run_over_the_link(tmp_path, capsys, link, mode):
    from stewart_sim.cli import main

    out = tmp_path / f"{link}-{mode}"
    assert main(["run", str(SCENE), "--link", link, "--mode", mode, "--out", str(out),
                 "--duration", "0.2"]) == 0
    text = capsys.readouterr().out
    assert "## Tracking" in text and f"mode {mode}" in text and (out / "summary.md").is_file()
    header = (out / "run.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["time", "step", "l_ref1"] and "e6" in header
    assert (out / "run_link.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_run_mode_needs_link(tmp_path, capsys):
    from stewart_sim.cli import main

    assert main(["run", str(SCENE), "--mode", "realtime", "--out", str(tmp_path)]) == 2
    assert "--link" in capsys.readouterr().err


# ------------------------------------------------------------------------ figures

def test_rate_table_is_computed_from_the_dialect_sizes():
    from hil.bandwidth import frame_sizes, loop_rate, rate_table
    from hil.framing import frame_length

    t = rate_table()
    sizes = t["sizes"]
    # header 10 + payload + CRC 2, the payloads from the generated classes
    assert sizes["LEG_SETPOINT"] == frame_length(ms.MAVLink_leg_setpoint_message.unpacker.size) == 217
    assert sizes["LEG_STATE"] == frame_length(ms.MAVLink_leg_state_message.unpacker.size) == 168
    assert sizes["DRIVE_STATUS"] == frame_length(ms.MAVLink_drive_status_message.unpacker.size)
    assert sizes["HEARTBEAT"] == 21 and frame_sizes(signed=True)["HEARTBEAT"] == 34
    for baud in (115200, 921600):
        for name, size in sizes.items():
            assert t["rates"][baud][name] == pytest.approx(baud / 10 / size)
        rt, ls = t["loop"][baud]
        assert ls < rt == pytest.approx(loop_rate(baud, sizes))
        # at that rate the setpoints fill no more than the wire, and the states too
        assert rt * sizes["LEG_SETPOINT"] * 10 <= baud * (1 + 1e-12)
        assert (rt * (sizes["LEG_STATE"] + sizes["DRIVE_STATUS"] / 10) + sizes["HEARTBEAT"]) * 10 \
            <= baud * (1 + 1e-12)
    assert t["loop"][115200][0] == pytest.approx(53.1, abs=0.5)   # the setpoint direction limits
    assert t["loop"][921600][0] == pytest.approx(424.7, abs=1)


def test_realtime_rates_fit_the_line():
    """UDP runs at the controller rate; a 921600 baud UART carries 424 setpoints a second (217 B
    frames with force and force rate), so a 1 kHz loop sends every third sample."""
    from hil.bandwidth import SERIAL_BAUD, frame_sizes, loop_rate, realtime_rates

    assert realtime_rates("udp", 1000.0) == (1, 1000.0)
    every, state_rate = realtime_rates("serial", 1000.0)
    fits = loop_rate(SERIAL_BAUD, frame_sizes())
    assert (every, state_rate) == (3, 1000.0 / 3) and 1000.0 / 3 <= fits < 500.0
    assert realtime_rates("serial", 1000.0, baud=115200)[0] == math.ceil(
        1000.0 / loop_rate(115200, frame_sizes()))


def test_link_figures_report_end_to_end(tmp_path, model, config):
    """`python -m stewart_sim.closed_loop.link_figures` on a small grid: the rate table, measured
    round trips over the
    pty and UDP, and tracking against latency and loss, all finite, with the plot."""
    from stewart_sim.closed_loop.link_figures import report

    path = report(tmp_path, model, config, n=30, latencies=(0.0, 0.005), losses=(0.3,),
                  repeats=1)
    text = path.read_text()
    assert "| LEG_SETPOINT |" in text and "921600 baud:" in text
    rows = [ln for ln in text.splitlines() if ln.startswith("| ") and "---" not in ln]
    latency_rows = [r for r in rows if r.split("|")[1].strip() in ("serial", "udp")]
    assert len(latency_rows) >= 4
    numbers = [float(x) for r in latency_rows for x in r.split("|")[3:6]]
    assert all(math.isfinite(x) and x > 0 for x in numbers)
    tracking = [r for r in rows if r.split("|")[1].strip() in ("0", "5")]
    assert len(tracking) == 3 and all(math.isfinite(float(r.split("|")[3])) for r in tracking)
    assert (tmp_path / "tracking_vs_link.png").read_bytes()[:4] == b"\x89PNG"


def test_the_client_numbers_its_frames_per_link():
    """Every frame the host sends carries the next MAVLink sequence number (mod 256), one and
    several per send alike, each client (link) counting from 0 on its own, so the device sees a
    lost one."""
    from hil.framing import Receiver

    a, b = queue_pair()
    c, d = queue_pair()
    host, other = Client(a), Client(c)
    hb = ms.MAVLink_heartbeat_message(ms.MAV_TYPE_GCS, ms.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
    for _ in range(200):
        host.send(hb)
    for _ in range(30):
        host.send_together(hb, hb)
    other.send(hb, hb, hb)
    rx = Receiver(ms)
    seqs = [m.get_seq() for data in iter(lambda: b.recv(0.0), b"") for m in rx.feed(data)]
    assert seqs == [k % 256 for k in range(260)]
    assert [m.get_seq() for data in iter(lambda: d.recv(0.0), b"") for m in rx.feed(data)] == [0, 1, 2]
    assert host.counters.sent == 260
