"""A lab script sending poses in the tool frame to the emulated device over MAVLink
(POSE_SETPOINT, docs/guides/device-and-links.md).

The device is started here as `stewart-sim device SCENE --udp` would start it (its first line
says the port); with one already running, connect to its port instead.
"""
import time
from pathlib import Path

from hil.client import Client, connect_udp
from hil.spawn import device_process, parse_udp

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"

with device_process(SCENE, "udp") as first:          # "udp 127.0.0.1:PORT"
    client = Client(connect_udp(*parse_udp(first)))
    print("armed:", client.arm())
    # the tool 2 mm along x and 1 mm up, turned 0.1 rad about z, streamed at 100 Hz for a second
    # (the device's watchdog wants a setpoint at least every few ticks); the micro-manipulator's
    # scene has no [frames], so its tool frame is C (home: z = 0.12 m)
    pose = [0.002, 0.0, 0.121, 0.0, 0.0, 0.1]
    for k in range(100):
        client.send_pose(k + 1, 0.01 * k, pose, frame="tool")
        time.sleep(0.01)
    client.drain()
    state = client.wait_for(lambda m: m.get_type() == "LEG_STATE")
    print("leg lengths (mm):", [round(1e3 * x, 2) for x in state.length])
    # with its rates (m/s, rad/s in the same frame) the legs also get their rate feed-forward
    client.send_pose(101, 1.0, pose, frame="tool", rate=[0.0] * 6)
    # a pose past the stroke: refused, one STATUSTEXT naming the leg
    client.drain()
    client.send_pose(102, 1.01, [0.0, 0.0, 0.5, 0.0, 0.0, 0.0], frame="tool")
    refusal = client.wait_for(lambda m: m.get_type() == "STATUSTEXT")
    print("device:", refusal.text)
    client.close()
