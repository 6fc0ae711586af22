"""What the live view's hook costs the device's tick: Device.tick() timed one by one, with and
without an observer (hil.observe), in the same process and run.

    python benchmarks/bench_observe.py [--ticks N] [--hz HZ] [--poll HZ]

Two devices of the micro-manipulator scene, one observed at HZ snapshots per second (default
hil.observe.OBSERVE_HZ), tick in alternating blocks of 1000 (so drift of the machine's load
falls on both alike), each following the same slow sine of setpoints, armed. With --poll a
thread reads the newest snapshot and builds /state's JSON at that rate, as the live view's
server does for a polling page (it competes for the GIL like the server thread). Prints the
median, p99 and p99.9 tick time of each and their ratios. Wall-clock figures: measured here,
never asserted in tests.
"""
from __future__ import annotations

import argparse
import json
import threading
import time
from pathlib import Path

import numpy as np

from hil import mavlink_stewart as ms
from hil.device import Device
from hil.observe import OBSERVE_HZ, Latest
from stewart_fmu import load_scene
from stewart_fmu.kinematics import inverse_kinematics
from stewart_sim.view.live_server import state_document

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"
BLOCK = 1000


def _arm(dev: Device) -> None:
    dev.receive(ms.MAVLink_command_long_message(1, 1, ms.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1,
                                                0, 0, 0, 0, 0, 0))


def _setpoint(dev: Device, k: int, lengths: np.ndarray) -> None:
    dev.receive(ms.MAVLink_leg_setpoint_message(k, k & 0xFFFFFFFF, lengths.tolist(), [0.0] * 6,
                                                0, [0.0] * 6))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=60000, help="ticks per device")
    parser.add_argument("--hz", type=float, default=OBSERVE_HZ, help="snapshot rate")
    parser.add_argument("--poll", type=float, default=0.0, help="reader rate, Hz (0: none)")
    args = parser.parse_args()
    model = load_scene(SCENE)
    home = np.asarray(model.home, dtype=float)
    amp = np.array([0.001, 0.001, 0.001, 0.01, 0.01, 0.01])
    plain, observed = Device(model, watchdog=10.0), Device(model, watchdog=10.0)
    latest = Latest()
    observed.observe(latest, args.hz)
    stop = threading.Event()
    reads = [0]

    def reader() -> None:
        while not stop.wait(1.0 / args.poll):
            json.dumps(state_document(latest.latest()))
            reads[0] += 1
    poller = threading.Thread(target=reader, daemon=True) if args.poll > 0 else None
    times = {"plain": [], "observed": []}
    for dev in (plain, observed):
        _arm(dev)
    if poller is not None:
        poller.start()
    clock = time.perf_counter_ns
    for block in range(args.ticks // BLOCK):
        for name, dev in (("plain", plain), ("observed", observed))[:: 1 if block % 2 else -1]:
            out = times[name]
            for _ in range(BLOCK):
                k = dev.k
                q = home + amp * np.sin(2 * np.pi * 0.5 * k * dev.dt)
                _setpoint(dev, k, inverse_kinematics(model, q, with_cond=False).lengths)
                t0 = clock()
                dev.tick()
                out.append(clock() - t0)
    stop.set()
    print(f"{args.ticks} ticks each; snapshots at {args.hz:g} Hz (every "
          f"{max(1, round(observed.rate / args.hz))} ticks, "
          f"{latest.published} published); reader at {args.poll:g} Hz ({reads[0]} reads)")
    print("| device | p50 (us) | p99 (us) | p99.9 (us) | mean (us) |")
    print("|---|---|---|---|---|")
    stats = {}
    for name, t in times.items():
        a = np.array(t) / 1e3
        stats[name] = np.array([np.percentile(a, 50), np.percentile(a, 99),
                                np.percentile(a, 99.9), a.mean()])
        print(f"| {name} | " + " | ".join(f"{x:.1f}" for x in stats[name]) + " |")
    r = stats["observed"] / stats["plain"]
    print("| ratio | " + " | ".join(f"{x:.3f}" for x in r) + " |")


if __name__ == "__main__":
    main()
