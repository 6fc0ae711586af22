"""hil.framing (robust MAVLink 2 receive path) and hil.link (transports, link emulator)."""
from __future__ import annotations

import os
import random
import threading
import time

import pytest

pytest.importorskip("pymavlink")
from pymavlink.dialects.v20 import common as dialect  # noqa: E402

from hil.errors import LinkError  # noqa: E402
from hil.framing import Receiver, crc16, max_frame_length  # noqa: E402
from hil.link import (  # noqa: E402
    Impairments,
    LinkEmulator,
    VirtualClock,
    WallClock,
    message_rates,
    pty_pair,
    queue_pair,
    udp_pair,
    wire_time,
)

TYPES = ("HEARTBEAT", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "STATUSTEXT")
# s: the longest wait for bytes that must come (a bound against a hang, never a pass/fail figure)
WAIT = 10.0


def make_msg(i: int):
    """Message i of a repeating mix of the four types; i is recoverable from its fields."""
    k = i % 4
    if k == 0:
        return dialect.MAVLink_heartbeat_message(1, 2, 3, i, 4, 3)
    if k == 1:
        return dialect.MAVLink_attitude_quaternion_message(i, 1.0, 0.0, 0.0, 0.0, 0.1, 0.2, 0.3,
                                                           [1.0, 0.0, 0.0, 0.0])
    if k == 2:
        return dialect.MAVLink_local_position_ned_message(i, 0.001 * i, 0.2, 0.3, 0.4, 0.5, 0.6)
    return dialect.MAVLink_statustext_message(6, b"frame %d" % i, 0, 0)


def msg_index(m) -> int:
    """Inverse of make_msg."""
    t = m.get_type()
    if t == "HEARTBEAT":
        return m.custom_mode
    if t == "STATUSTEXT":
        return int(m.text.split()[1])
    return m.time_boot_ms


def frames(n: int, start: int = 0) -> list[bytes]:
    """n packed MAVLink 2 frames (sysid 1, compid 1)."""
    mav = dialect.MAVLink(None, 1, 1)
    return [bytes(make_msg(i).pack(mav)) for i in range(start, start + n)]


def feed_chunks(rx: Receiver, data: bytes, size: int = 17) -> list:
    """Feed `data` in chunks of `size` bytes, then flush; all messages."""
    out = []
    for k in range(0, len(data), size):
        out += rx.feed(data[k:k + size])
    return out + rx.flush()


def pymavlink_parse(data: bytes, size: int = 17) -> tuple[int, int]:
    """(good known messages, UNKNOWN_* messages) from pymavlink's own robust parser."""
    p = dialect.MAVLink(None)
    p.robust_parsing = True
    good = unknown = 0
    for k in range(0, len(data), size):
        for m in p.parse_buffer(data[k:k + size]) or []:
            if isinstance(m, dialect.MAVLink_unknown):
                unknown += 1
            elif not isinstance(m, dialect.MAVLink_bad_data):
                good += 1
    return good, unknown


def check_invariant(rx: Receiver) -> None:
    s = rx.stats
    assert s.bytes_in == s.bytes_ok + s.bytes_skipped + rx.pending


# ------------------------------------------------------------------------------ framing

def test_garbage_bursts_recover_every_frame(capsys):
    rng = random.Random(5)
    stream = bytearray()
    fr = frames(1000)
    for f in fr:
        stream += rng.randbytes(rng.randint(1, 64)) + f
    rx = Receiver(dialect)
    msgs = feed_chunks(rx, bytes(stream))
    got = [msg_index(m) for m in msgs]
    ours = len(set(got) & set(range(1000))) / 10.0
    theirs, unknown = pymavlink_parse(bytes(stream))
    with capsys.disabled():
        print(f"\n[framing] garbage bursts: ours {ours:.1f}% of 1000 frames, pymavlink "
              f"{theirs / 10:.1f}% (+{unknown} unchecked UNKNOWN_*); {rx.stats}")
    assert ours >= 99.0
    assert got == sorted(got)  # in order, no duplicates, no false frames
    assert {m.get_type() for m in msgs} == set(TYPES)
    assert theirs < 0.9 * len(msgs)  # the difference this module exists for
    check_invariant(rx)


def test_truncated_and_bitflipped_frames_rejected_and_next_recovered():
    rng = random.Random(7)
    fr = frames(600)
    stream, clean, flipped, truncated = bytearray(), [], 0, 0
    for i, f in enumerate(fr):
        kind = i % 3
        if kind == 1:  # one bit flipped after the header: only the CRC can catch it
            b = bytearray(f)
            bit = rng.randrange(10 * 8, len(b) * 8)
            b[bit >> 3] ^= 1 << (bit & 7)
            stream += b
            flipped += 1
        elif kind == 2:  # cut inside payload or CRC
            stream += f[:rng.randrange(11, len(f))]
            truncated += 1
        else:
            stream += f
            clean.append(i)
    rx = Receiver(dialect)
    msgs = feed_chunks(rx, bytes(stream), 23)
    assert [msg_index(m) for m in msgs] == clean
    assert rx.stats.frames_ok == len(clean)
    assert rx.stats.crc_errors >= flipped + truncated
    check_invariant(rx)


def test_random_bytes_give_no_false_frames(capsys):
    data = random.Random(11).randbytes(1 << 20)
    rx = Receiver(dialect)
    t0 = time.perf_counter()
    msgs = feed_chunks(rx, data, 4096)
    dt = time.perf_counter() - t0
    theirs, unknown = pymavlink_parse(data, 4096)
    with capsys.disabled():
        print(f"\n[framing] 1 MiB random: ours {len(msgs)} frames in {dt * 1e3:.0f} ms "
              f"{rx.stats}; pymavlink {theirs} known + {unknown} UNKNOWN_* (unchecked)")
    assert msgs == [] and rx.stats.frames_ok == 0
    assert rx.pending == 0
    check_invariant(rx)


def test_forged_headers_only_crc_stands_between():
    """Valid HEARTBEAT headers with random payload+CRC: the false-accept rate is ~2**-16."""
    rng = random.Random(3)
    n = 20000
    head = bytes([0xFD, 9, 0, 0, 0, 1, 1, 0, 0, 0])
    stream = b"".join(head + rng.randbytes(11) for _ in range(n))
    rx = Receiver(dialect)
    msgs = rx.feed(stream) + rx.flush()
    assert len(msgs) <= 5  # expectation n / 65536 ~ 0.3
    assert rx.stats.crc_errors >= n - 5


def test_unknown_id_dropped_and_counted():
    mid, payload = 44000, b"\x01\x02\x03"
    body = bytes([len(payload), 0, 0, 0, 1, 1, mid & 0xFF, (mid >> 8) & 0xFF, mid >> 16]) + payload
    c = crc16(bytes([42]), crc16(body))
    unknown = b"\xfd" + body + bytes([c & 0xFF, c >> 8])
    good = frames(2)
    rx = Receiver(dialect)
    msgs = rx.feed(good[0] + unknown + good[1]) + rx.flush()
    assert [msg_index(m) for m in msgs] == [0, 1]
    assert rx.stats.unknown_ids == 1
    p = dialect.MAVLink(None)
    assert any(m.get_type().startswith("UNKNOWN") for m in p.parse_buffer(unknown) or [])


def test_signed_frames_are_framed():
    mav = dialect.MAVLink(None, 1, 1)
    mav.signing.secret_key = bytes(range(32))
    mav.signing.link_id = 0
    mav.signing.sign_outgoing = True
    mav.signing.timestamp = 1
    signed = [bytes(make_msg(i).pack(mav)) for i in range(8)]
    assert all(f[2] & 0x01 for f in signed)
    garbage = random.Random(1).randbytes(20)
    rx = Receiver(dialect)
    msgs = feed_chunks(rx, b"".join(garbage + f for f in signed), 7)
    assert [msg_index(m) for m in msgs] == list(range(8))
    assert rx.stats.bytes_ok == sum(len(f) for f in signed)


# ------------------------------------------------------------------------------ transports

def _roundtrip(tx, rx_end, n: int = 200, timeout: float = 5.0) -> list:
    fr = frames(n)
    for f in fr:
        assert tx.send(f) == len(f)
    rx, msgs, deadline = Receiver(dialect), [], time.monotonic() + timeout
    while len(msgs) < n and time.monotonic() < deadline:
        msgs += rx.feed(rx_end.recv(0.05))
    return msgs


@pytest.mark.parametrize("make", [pty_pair, udp_pair], ids=["pty", "udp"])
def test_frames_cross_transport_both_ways(make):
    a, b = make()
    try:
        assert [msg_index(m) for m in _roundtrip(a, b)] == list(range(200))
        assert [msg_index(m) for m in _roundtrip(b, a)] == list(range(200))
        assert a.stats.bytes_dropped == 0 and b.stats.bytes_dropped == 0
    finally:
        a.close()
        b.close()
    with pytest.raises(LinkError):
        a.send(b"x")


def test_pty_write_drops_instead_of_blocking(capsys):
    master, slave = pty_pair()
    try:
        chunk, t0, total = b"\x55" * 4096, time.monotonic(), 0
        while master.stats.bytes_dropped == 0 and total < 64 << 20:
            master.send(chunk)
            total += len(chunk)
        dt = time.monotonic() - t0
        with capsys.disabled():
            print(f"\n[pty] reader stalled: accepted {master.stats.bytes_sent} B, first drop "
                  f"after {total} B offered, {dt * 1e3:.1f} ms")
        # a write that blocked would never have returned short: the drop is the proof (how
        # long the loop took is only printed)
        assert master.stats.bytes_dropped > 0 and not os.get_blocking(master.fd)
        got = 0
        while data := slave.recv(0.05):  # the reader resumes and the link still works
            got += len(data)
        assert 0 < got <= master.stats.bytes_sent
        assert master.send(b"ok") == 2 and slave.recv(1.0) == b"ok"
    finally:
        master.close()
        slave.close()


# ------------------------------------------------------------------------------ emulator

def test_baud_timing_is_exact_on_virtual_clock():
    clock = VirtualClock()
    host, emu_a = queue_pair()
    emu_b, dev = queue_pair()
    link = LinkEmulator(emu_a, emu_b, Impairments(baud=115200), clock=clock)
    host.send(bytes(1000))
    link.pump()
    t_wire = 1000 * 10 / 115200
    assert t_wire == pytest.approx(0.0868055555)
    assert link.next_event() == t_wire
    clock.advance(t_wire * (1 - 1e-9))
    link.pump()
    assert dev.recv() == b""
    clock.t = t_wire
    link.pump()
    assert dev.recv() == bytes(1000)
    # ten 100-byte packets queue behind each other on the wire: same total time
    for _ in range(10):
        host.send(bytes(100))
    link.pump()
    assert link.ab.queue[-1][0] == pytest.approx(2 * t_wire, abs=1e-12)


def test_message_rates_helper(capsys):
    sizes = {n: max_frame_length(getattr(dialect, f"MAVLink_{n.lower()}_message")) for n in TYPES}
    assert sizes == {"HEARTBEAT": 21, "ATTITUDE_QUATERNION": 60, "LOCAL_POSITION_NED": 40,
                     "STATUSTEXT": 66}
    for baud in (115200, 921600):
        rates = message_rates(baud, sizes)
        for n, s in sizes.items():
            assert rates[n] == baud / (10 * s)
            assert wire_time(s, baud) * rates[n] == pytest.approx(1.0)
        with capsys.disabled():
            print(f"\n[rates] {baud} baud: " + ", ".join(f"{n} ({sizes[n]} B) {r:.0f}/s"
                                                        for n, r in rates.items()))
    assert message_rates(115200, {"x": 60})["x"] == 192.0


def _run_virtual(seed: int, imp: Impairments, n: int = 2000):
    clock = VirtualClock()
    host, emu_a = queue_pair()
    emu_b, dev = queue_pair()
    link = LinkEmulator(emu_a, emu_b, imp, clock=clock, seed=seed)
    rx, msgs = Receiver(dialect), []
    for f in frames(n):
        host.send(f)
        link.pump()
        clock.advance(0.001)
        link.pump()
        while data := dev.recv():
            msgs += rx.feed(data)
    while (t := link.next_event()) is not None:
        clock.t = max(clock.t, t)
        link.pump()
    while data := dev.recv():
        msgs += rx.feed(data)
    return link, rx, msgs + rx.flush()


def test_bit_errors_rejected_by_crc_and_counted_deterministically():
    imp = Impairments(baud=921600, bit_error_rate=1e-4)
    link, rx, msgs = _run_virtual(1, imp)
    st = link.ab.stats
    assert st.packets_corrupted > 50
    assert rx.stats.frames_ok == st.packets_out - st.packets_corrupted  # every clean one, no more
    assert rx.stats.crc_errors >= 0.8 * st.packets_corrupted
    idx = [msg_index(m) for m in msgs]
    assert idx == sorted(idx)
    link2, rx2, _ = _run_virtual(1, imp)
    assert link2.ab.stats == st and rx2.stats == rx.stats  # seeded: identical counters


def test_loss_latency_jitter_on_virtual_clock():
    imp = Impairments(baud=115200, latency=0.005, jitter=0.002, loss=0.1)
    link, rx, msgs = _run_virtual(2, imp, 1000)
    st = link.ab.stats
    assert 50 < st.packets_lost < 150
    assert rx.stats.frames_ok == st.packets_out == 1000 - st.packets_lost
    idx = [msg_index(m) for m in msgs]
    assert idx == sorted(idx)
    # arrival = end of wire time + latency + jitter, never earlier
    clock = VirtualClock()
    host, emu_a = queue_pair()
    emu_b, dev = queue_pair()
    link = LinkEmulator(emu_a, emu_b, Impairments(baud=115200, latency=0.005), clock=clock)
    host.send(bytes(60))
    link.pump()
    assert link.next_event() == pytest.approx(60 * 10 / 115200 + 0.005, abs=1e-15)


def test_backlog_overflow_drops_at_sender():
    # 60-byte frames every 1 ms need 5.2 ms each at 115200 baud: the wire cannot keep up
    link, rx, msgs = _run_virtual(3, Impairments(baud=115200, max_backlog=0.05), 400)
    st = link.ab.stats
    assert st.packets_overflow > 0
    assert st.packets_out == 400 - st.packets_overflow == rx.stats.frames_ok
    assert link.ab.wire_free_at <= 0.4 + 0.05 + wire_time(66, 115200)


def test_invalid_impairments_raise_link_error():
    with pytest.raises(LinkError):
        Impairments(baud=0)
    with pytest.raises(LinkError):
        Impairments(loss=1.5)
    with pytest.raises(LinkError):
        LinkEmulator(*queue_pair(), Impairments()).start()


def test_wall_clock_emulator_between_two_pty_pairs():
    h_master, h_slave = pty_pair()  # host writes h_master; the emulator owns h_slave
    d_master, d_slave = pty_pair()  # the emulator owns d_master; the device reads d_slave
    link = LinkEmulator(h_slave, d_master, Impairments(baud=921600, latency=0.002,
                                                       bit_error_rate=1e-4),
                        clock=WallClock(), seed=4)
    rx, msgs, n = Receiver(dialect), [], 300
    st = link.ab.stats
    deadline = time.monotonic() + WAIT

    def read(timeout: float) -> None:
        assert time.monotonic() < deadline, f"the emulator did not deliver within {WAIT} s"
        msgs.extend(rx.feed(d_slave.recv(timeout)))

    try:
        link.start()
        for i, f in enumerate(frames(n)):
            h_master.send(f)
            if i % 20 == 19:   # paced by content: the next 20 once the emulator took these
                while st.bytes_in < h_master.stats.bytes_sent:
                    read(0.001)
        # the end by content, not by a quiet spell: all taken, none in flight, all read
        while not (st.bytes_in == h_master.stats.bytes_sent and link.next_event() is None
                   and rx.stats.bytes_in == st.bytes_out):
            read(0.01)
        link.stop()    # joined: a delivery under way when the loop ended has finished
        while data := d_slave.recv(0.05):
            msgs += rx.feed(data)
        msgs += rx.flush()
    finally:
        link.stop()
        for t in (h_master, h_slave, d_master, d_slave):
            t.close()
    idx = [msg_index(m) for m in msgs]
    assert idx == sorted(idx) and len(set(idx)) == len(idx)
    assert len(msgs) >= 0.8 * n
    assert st.packets_corrupted == 0 or rx.stats.rejected > 0
    assert rx.stats.bytes_in == st.bytes_out  # everything the emulator sent was read
    assert h_master.stats.bytes_dropped == 0
    assert not any(t.name == "hil-link-emulator" for t in threading.enumerate())
