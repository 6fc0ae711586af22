"""The GCS twin under hostile clients: what it answers, and what the device's clock pays.

    python benchmarks/bench_gcs_hostile.py [--seconds S] [--clients N] [--seed K]

The device is served in real time in this process (hil.serve over hil.gcs.tcp_transport) while N clients,
each in a process of its own, send seeded hostile bytes as fast as the server reads them (random
binary, control bytes, overlong lines, floods of unknown commands, absurd numbers, moves and
servo switching on an unreferenced twin; tests/hil/test_gcs.py's generator). Printed: bytes and
lines taken, lines per second, every error code with its count (the codes the lines set, as ERR?
would read them), the device's ticks, overruns and tick lateness, the CPU the device's process
used (all of it, per tick: the lines' cost included; on a loaded machine a process that gets
less CPU than it needs falls behind whatever its loop does), the largest pose change of the
plant (it must not move) and its faults. Wall-clock figures: measured here, never asserted in
tests.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import random
import resource
import socket
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hil.device import Device  # noqa: E402
from hil.gcs import command_set  # noqa: E402
from hil.gcs.tcp_transport import gcs_link  # noqa: E402
from hil.serve import serve_in_thread  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402
from tests.hil.test_gcs import _hostile_lines  # noqa: E402

SCENE = ROOT / "scenes" / "micro_manipulator.toml"


def flood(port: int, seed: int, stop, sent) -> None:
    """One hostile client (its own process: no share of this process's GIL)."""
    rng = random.Random(seed)
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    s.setblocking(False)
    while not stop.is_set():
        pick = rng.random()
        if pick < 0.2:
            data = bytes(rng.randrange(256) for _ in range(rng.randint(1, 300)))
        elif pick < 0.3:
            data = b"MOV X " + b"9" * rng.randint(100, 3000) + b"\n"
        elif pick < 0.4:
            data = bytes([rng.choice([5, 7, 24])])
        else:
            data = b"\n".join(_hostile_lines(rng, 20)) + b"\n"
        view = memoryview(data)
        while view and not stop.is_set():
            try:
                n = s.send(view)
                view = view[n:]
                sent.value += n
            except BlockingIOError:
                time.sleep(0.0005)
        try:
            s.recv(1 << 20)
        except BlockingIOError:
            pass
    s.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--clients", type=int, default=2)
    ap.add_argument("--seed", type=int, default=38)
    args = ap.parse_args()
    model = load_scene(SCENE)
    device = Device(model)
    link = gcs_link(device, "127.0.0.1", 0)
    codes: Counter = Counter()
    run = command_set.execute

    def counting(c, s, text):      # every line's code, as ERR? would read it
        s.error = 0
        out = run(c, s, text)
        codes[s.error] += 1
        return out

    command_set.execute = counting
    import hil.gcs.server as server_module
    server_module.execute = counting
    q0 = np.asarray(device.snapshot().q)
    thread, stop_dev, result = serve_in_thread(device, link)
    stop = mp.Event()
    sent = [mp.Value("q", 0) for _ in range(args.clients)]
    floods = [mp.Process(target=flood, args=(link.server.address[1], args.seed + i, stop,
                                             sent[i]), daemon=True)
              for i in range(args.clients)]
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.monotonic()
    for f in floods:
        f.start()
    moved = 0.0
    while time.monotonic() - t0 < args.seconds:
        time.sleep(0.2)
        moved = max(moved, float(np.max(np.abs(np.asarray(device.snapshot().q) - q0))))
    stop.set()
    for f in floods:
        f.join(5)
    wall = time.monotonic() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    stop_dev.set()
    thread.join(10)
    link.close()
    st, serve_stats = link.server.stats, result[0]
    print(f"{args.clients} hostile clients, {wall:.2f} s, seed {args.seed}")
    print(f"bytes taken       {st.bytes_in}")
    print(f"lines run         {st.lines} ({st.lines / wall:.0f}/s), overlong {st.overlong}")
    print("codes             " + ", ".join(f"{k}: {v}" for k, v in sorted(codes.items())))
    print(f"device ticks      {serve_stats.ticks} (wall {serve_stats.wall:.2f} s), overruns "
          f"{serve_stats.overruns}, {serve_stats.late.text()}")
    print(f"device process    {cpu:.2f} CPU s in {wall:.2f} s wall ({100 * cpu / wall:.0f} % of a "
          f"core), {1e3 * cpu / max(serve_stats.ticks, 1):.3f} CPU ms a tick with its lines "
          f"(under {1e3 * device.dt:g} ms: the loop keeps real time when it gets the CPU)")
    print(f"plant moved       {moved:.3g} (max |dq|, m or rad)")
    c = device.counters
    print(f"device            faults {c.faults}, numeric faults {c.numeric_faults}, armed "
          f"{device.armed}, internal errors {link.controller.internal_errors}")


if __name__ == "__main__":
    main()
