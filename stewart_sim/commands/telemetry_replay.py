"""`stewart-sim telemetry-replay MOTION.csv --to udp://127.0.0.1:PORT [--format native|outsim]
[--rate HZ] [--loop] [--duration S] [--remote]`: a recorded vehicle motion streamed as telemetry
datagrams in real time (stewart_sim.live.replay), so that `cue-live` runs on one machine."""
from __future__ import annotations

import argparse

from stewart_sim.shell.argtypes import positive_rate, positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `telemetry-replay` on the command line's subparsers."""
    p = sub.add_parser(
        "telemetry-replay", help=help_text,
        description="Send a vehicle motion (CSV t,fx,fy,fz,wx,wy,wz, as `cue` reads it; "
                    "scenes/motions/ has examples) as telemetry datagrams over UDP at its own "
                    "times: the native format (60 bytes, stewart_sim/live/vehicle_datagrams.py) or "
                    "Live for Speed's OutSim packet (64 bytes). Telemetry times start at 0.")
    p.add_argument("motion", metavar="MOTION.csv", help="vehicle motion file")
    p.add_argument("--to", required=True, metavar="udp://127.0.0.1:PORT",
                   help="where to send (loopback unless --remote)")
    p.add_argument("--format", choices=("native", "outsim"), default="native",
                   help="datagram format (default: %(default)s)")
    p.add_argument("--rate", type=positive_rate, metavar="HZ",
                   help="send at this rate, the motion interpolated linearly (default: the "
                        "motion's own)")
    p.add_argument("--loop", action="store_true",
                   help="start again after the end, times continuing, until Ctrl-C or --duration")
    p.add_argument("--duration", type=positive_seconds, metavar="S",
                   help="stop after this many seconds")
    p.add_argument("--remote", action="store_true",
                   help="allow a non-loopback address in --to (telemetry leaves this machine)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Stream until the motion ends (or --duration, or Ctrl-C: exit 130)."""
    import math
    from pathlib import Path

    from stewart_fmu.budget import BudgetError
    from stewart_sim.cueing.motion import read_motion
    from stewart_sim.cueing.study import CueError
    from stewart_sim.live.address import telemetry_address
    from stewart_sim.live.replay import Replay, UdpSink, stream

    host, port = telemetry_address(args.to, remote=args.remote, listen=False)
    motion = read_motion(Path(args.motion))
    try:
        replay = Replay(motion, args.format, args.rate, args.loop)
    except (CueError, BudgetError) as exc:     # the motion resampled at --rate: too few, too many
        if args.rate is None:
            raise
        raise CueError(f"--rate {args.rate:g} Hz: {exc}") from None
    sink = UdpSink(host, port)
    print(f"telemetry-replay: {args.motion} to udp://{host}:{port}, {args.format}, "
          f"{1 / replay.period:g} Hz" + (", looping" if args.loop else ""), flush=True)
    try:
        stats = stream(replay, sink, duration=args.duration or math.inf)
    finally:
        sink.close()
    print(f"telemetry-replay: {stats.sent} datagrams sent in {stats.seconds:.3f} s"
          + (f", {stats.dropped} dropped by the socket" if stats.dropped else ""))
