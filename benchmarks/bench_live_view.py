"""The live view's update rate as a browser sees it, with the device moving in real time.

    python benchmarks/bench_live_view.py [--seconds S] [--runs N]

Each run starts `stewart-sim device SCENE --udp 127.0.0.1:0 --view 0` (as `python -m stewart_sim`),
arms it and streams setpoints at 100 Hz along a slow sine (z and thz) over UDP from a thread,
opens the view in headless Chromium (Debian's `chromium` through Playwright) and counts, inside
the page, how often the frame it shows changes (window.stewartView.shown().t, sampled every
2 ms) over S seconds: the live update rate. The device's tick lateness over its life (its stop
line) is printed beside it. Wall-clock figures: measured here, never asserted in tests.
"""
from __future__ import annotations

import argparse
import re
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
from playwright.sync_api import sync_playwright

from hil.client import Client, connect_device
from stewart_fmu import load_scene
from stewart_fmu.kinematics import inverse_kinematics

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
LATE_RE = re.compile(r"late p50 (\d+) us, p99 (\d+) us, p99\.9 (\d+) us, max (\d+) us, "
                     r"(\d+) deadline misses of (\d+)")
COUNT_JS = """(seconds) => new Promise(done => {
  let last = null, changes = 0;
  const start = performance.now();
  const timer = setInterval(() => {
    const s = window.stewartView.shown();
    if (s && s.t !== last) { changes += 1; last = s.t; }
    if (performance.now() - start >= 1000 * seconds) { clearInterval(timer); done(changes); }
  }, 2);
})"""


def stream(client: Client, model, stop: threading.Event) -> None:
    """Setpoints at 100 Hz: z +-5 mm and thz +-0.2 rad at 0.5 Hz about home."""
    home = np.asarray(model.home, dtype=float)
    k, t0 = 0, time.monotonic()
    while not stop.is_set():
        t = k * 0.01
        q = home + np.sin(np.pi * t) * np.array([0, 0, 0.005, 0, 0, 0.2])
        client.send(client.setpoint_message(k, t, inverse_kinematics(model, q).lengths,
                                            np.zeros(6)))
        k += 1
        stop.wait(max(0.0, t0 + k * 0.01 - time.monotonic()))


def one_run(browser, model, seconds: float) -> tuple[float, str]:
    proc = subprocess.Popen([sys.executable, "-m", "stewart_sim", "device", str(SCENE), "--udp",
                             "127.0.0.1:0", "--watchdog", "1", "--view", "0"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stop = threading.Event()
    try:
        select.select([proc.stdout], [], [], 60)
        first = proc.stdout.readline().strip()
        url = proc.stdout.readline().strip().split(" ", 1)[1]
        client = Client(connect_device("udp", first)[0])
        sender = threading.Thread(target=stream, args=(client, model, stop), daemon=True)
        try:
            client.arm()
            sender.start()
            page = browser.new_page(viewport={"width": 800, "height": 600})
            page.goto(url)
            page.wait_for_function("() => window.stewartView && window.stewartView.ready",
                                   timeout=60000)
            changes = page.evaluate(COUNT_JS, seconds)
            page.close()
        finally:
            stop.set()
            sender.join(5)
            client.close()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    m = LATE_RE.search(err)
    return changes / seconds, (m.group(0) if m else err.strip()[-300:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    model = load_scene(SCENE)
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        try:
            for _ in range(args.runs):
                rate, late = one_run(browser, model, args.seconds)
                print(f"live view: {rate:.1f} frames/s shown over {args.seconds:g} s; "
                      f"device ticks {late}", flush=True)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
