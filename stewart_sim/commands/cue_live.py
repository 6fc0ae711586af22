"""`stewart-sim cue-live SCENE --telemetry udp://127.0.0.1:PORT --device udp:HOST:PORT|serial:DEV
[--mode classical|optimal] [--mpc-rate HZ] [--format native|outsim] [--telemetry-rate HZ]
[--view [PORT]] [--duration S] [--record FILE]
[--control udp://127.0.0.1:PORT] [--loss-timeout S] [--remote]`: the live motion simulator
(stewart_sim.live.session): vehicle telemetry in, the washout, the safety envelope, leg
setpoints out to the device at its rate until --duration, `quit`, `estop`, Ctrl-C (which
parks first, then exits 130) or the loss of the device (no LEG_STATE back for the device's
watchdog time: said at once, the session ends, exit 2). A summary of the session at the end."""
from __future__ import annotations

import argparse

from stewart_sim.commands.constants import literals
from stewart_sim.shell.argtypes import port, positive_rate, positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `cue-live` on the command line's subparsers."""
    (loss,) = literals("stewart_sim.live.session", "LOSS_TIMEOUT")
    p = sub.add_parser(
        "cue-live", help=help_text,
        description="Run the scene as a live motion simulator: vehicle telemetry datagrams "
                    "(the native format or Live for Speed's OutSim, "
                    "stewart_sim/live/vehicle_datagrams.py) -> the scene's classical washout, "
                    "one step per sample at the nominal telemetry rate -> the safety "
                    "envelope (stroke with a margin, leg speed and acceleration, rack force, cond(J)) -> leg "
                    "setpoints with force feed-forward to the device over MAVLink at its "
                    "controller rate. No telemetry for --loss-timeout fades the platform to "
                    "neutral. Operator commands, one word per line on a terminal's standard "
                    "input or per datagram on --control: park, resume, estop, quit. Ctrl-C "
                    "parks, then exits 130. A device that sends no state back for its "
                    "watchdog time (WDG_TIMEOUT) is lost: said at once, no more setpoints, "
                    "the session ends with exit status 2.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with [controller] and "
                                                   "[drive] tables ([cueing]: the washout)")
    p.add_argument("--telemetry", required=True, metavar="udp://127.0.0.1:PORT",
                   help="where to listen for telemetry (loopback unless --remote)")
    p.add_argument("--device", required=True, metavar="udp:HOST:PORT|serial:DEV",
                   help="the device: `stewart-sim device SCENE --udp 127.0.0.1:PORT` "
                        "(loopback) or a serial port / pseudo-terminal (`device --pty`)")
    p.add_argument("--mode", choices=("classical", "optimal"), default="classical",
                   help="classical: the washout of the scene's [cueing] table; optimal: the "
                        "MPC of [cueing.optimal] without preview (default: %(default)s)")
    p.add_argument("--mpc-rate", type=positive_rate, metavar="HZ",
                   help="optimal mode: the MPC's step rate (default: the scene's "
                        "[cueing.optimal] rate, at least 50 Hz)")
    p.add_argument("--format", choices=("native", "outsim"), default="native",
                   help="telemetry datagram format (default: %(default)s)")
    p.add_argument("--telemetry-rate", type=positive_rate, default=100.0, metavar="HZ",
                   help="the nominal telemetry rate the washout steps at (default: "
                        "%(default)g Hz); a sender at another rate is resampled onto it")
    p.add_argument("--duration", type=positive_seconds, metavar="S",
                   help="park and end after this many seconds (default: run until stopped)")
    p.add_argument("--record", metavar="FILE",
                   help="write every tick (time, setpoint sequence, mode, telemetry time used, "
                        "leg setpoints, measured legs) to this CSV at the end")
    p.add_argument("--control", metavar="udp://127.0.0.1:PORT",
                   help="also take operator commands as datagrams on this port")
    p.add_argument("--loss-timeout", type=positive_seconds, default=loss, metavar="S",
                   help=f"telemetry loss after this long without a valid sample: fade to "
                        f"neutral (default {loss:g} s)")
    p.add_argument("--view", nargs="?", const=0, type=port, metavar="PORT",
                   help="serve a live 3D view in the browser on 127.0.0.1:PORT (no PORT or 0: "
                        "any free port): the pose sent, the cue's, and the vehicle's and the "
                        "delivered specific force at the pilot's head; its address is printed "
                        "after the first line")
    p.add_argument("--remote", action="store_true",
                   help="allow non-loopback addresses in --telemetry and --control")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Run the session; bad addresses and scenes are refused before the device is touched."""
    import math
    import sys
    import time

    from hil.errors import LinkError
    from stewart_fmu import io as sio
    from stewart_sim.live.address import device_address, telemetry_address
    from stewart_sim.live.control import Control
    from stewart_sim.live.device_out import DeviceOut
    from stewart_sim.live.receiver import TelemetryReceiver, UdpSource
    from stewart_sim.live.session import (PARK_TIMEOUT, RECORD_COLUMNS, Record, make_session,
                                          run_realtime, summary_lines)
    from stewart_sim.scene.load import load
    from stewart_sim.shell import outputs
    from stewart_sim.shell.run_length import MAX_SAMPLES

    scene = load(args.scene)
    controller = scene.require_controller()
    listen = telemetry_address(args.telemetry, remote=args.remote)
    control_at = (telemetry_address(args.control, remote=args.remote)
                  if args.control is not None else None)
    where = device_address(args.device)
    source = UdpSource(*listen)
    control = Control.for_terminal(control_at)
    device = session = view = None
    try:
        receiver = TelemetryReceiver(source, args.format, time.monotonic)
        device = DeviceOut.open(where)
        # the ticks of --duration and of the park after it
        rows = (math.ceil((args.duration + PARK_TIMEOUT) * controller.rate)
                if args.duration else MAX_SAMPLES)
        record = Record(min(MAX_SAMPLES, rows)) if args.record else None
        latest = None
        if args.view is not None:
            from hil.observe import Latest
            from stewart_sim.view.live_server import LiveView, live_page

            latest = Latest()
            # bound now (a taken port fails before the device is armed), served from the start
            view = LiveView(live_page(scene.model, controller), latest, args.view)
        # the optimal mode forks its solver's worker here: before any thread starts
        session = make_session(scene, receiver, device, args.telemetry_rate, control,
                               args.loss_timeout, record, args.mode, mpc_rate=args.mpc_rate,
                               observer=latest)
        device.start(controller.rate)
        banner = (f"cue-live: {scene.model.name}, {args.mode}, telemetry udp://"
                  f"{source.address[0]}:{source.address[1]} ({args.format}, "
                  f"{args.telemetry_rate:g} Hz), device {args.device} at {controller.rate:g} Hz"
                  + (f", control udp://{control.address[0]}:{control.address[1]}"
                     if control.address else "")
                  + "; park, resume, estop, quit")
        interrupted = False

        def ready() -> None:
            print(banner, flush=True)
            if view is not None:
                view.start()
                print(f"view: {view.url}", flush=True)

        try:
            run_realtime(session, args.duration or math.inf, ready=ready)
        except KeyboardInterrupt:
            interrupted = True
        for line in summary_lines(session):
            print(line)
        if record is not None:
            sio.write_csv(args.record, sio.named_array(
                {name: col for name, col in zip(RECORD_COLUMNS, record.table().T)}))
            print(f"wrote {args.record}" + (f" ({record.dropped} rows beyond the memory budget "
                                            "not kept)" if record.dropped else ""))
        sys.stdout.flush()
        if interrupted:
            raise outputs.Interrupted(f"parked ({session.mode.value}); summary above")
        if session.device_lost:
            raise LinkError(f"cue-live: the device was lost at {session.device_lost_at:.3f} s "
                            "(no LEG_STATE back): session ended, summary above")
    finally:
        if view is not None:
            view.close()
        if session is not None:
            session.cue.close()
        if device is not None and not (session is not None and session.device_lost):
            device.hold()        # disarmed whatever happened: the drives hold the legs
            device.close()
        control.close()
        source.close()
