"""`stewart-sim device SCENE [--udp 127.0.0.1:PORT | --pty] [--gcs 127.0.0.1:PORT] [--watchdog S]
[--lockstep] [--signing-key HEX] [--truth TRUE.toml] [--view [PORT]]` (one link at least): the
emulated micro-manipulator (hil.spawn.serve_device) until SIGINT or SIGTERM (exit status 0)."""
from __future__ import annotations

import argparse

from stewart_sim.commands.constants import literals
from stewart_sim.shell.argtypes import port, positive_seconds


def add_parser(sub, help_text: str) -> None:
    """Register `device` on the command line's subparsers."""
    (watchdog,) = literals("hil.spawn", "WATCHDOG")
    p = sub.add_parser("device", help=help_text,
                       description="Run the scene's plant and drive servo loops at the "
                                   "controller rate as an emulated device speaking MAVLink 2 "
                                   "(our dialect, hil/message_definitions/stewart.xml) over UDP "
                                   "on loopback or a pseudo-terminal, and/or PI's GCS 2.0 over "
                                   "TCP (--gcs), until interrupted (Ctrl-C exits 0). The first "
                                   "line printed is the pseudo-terminal's path, or the UDP "
                                   "address listened on; with --gcs the GCS address follows.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML) with a [controller] table")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--udp", metavar="127.0.0.1:PORT",
                       help="listen on this loopback UDP port (0: any free port) and answer "
                            "whoever sends to it")
    where.add_argument("--pty", action="store_true",
                       help="open a pseudo-terminal and print its path on the first line")
    p.add_argument("--gcs", metavar="127.0.0.1:PORT",
                   help="also (or, without --udp and --pty, only) speak PI's GCS 2.0 over TCP "
                        "on this loopback port (PI's is 50000; 0: any free port), so that "
                        "PIPython drives the same device as a hexapod: axes X Y Z (mm) and "
                        "U V W (deg), referencing, moves, the data recorder (hil/gcs); real "
                        "time only. Its line 'gcs 127.0.0.1:PORT' follows the MAVLink one")
    p.add_argument("--watchdog", type=positive_seconds, default=watchdog, metavar="SECONDS",
                   help="safe stop (hold) after this long without a valid setpoint while armed "
                        f"(default {watchdog:g} s)")
    p.add_argument("--lockstep", action="store_true",
                   help="advance time only on LOCKSTEP messages (deterministic runs)")
    p.add_argument("--signing-key", metavar="HEX",
                   help="MAVLink 2 signing key, 64 hex digits: unsigned or badly signed frames "
                        "are rejected and counted")
    p.add_argument("--truth", metavar="TRUE.toml",
                   help="the machine: build the plant and the sensors ([sensors]) from this "
                        "hidden true scene (the geometry, gravity and drive ratio of SCENE; its "
                        "masses, inertias, frictions and rotor inertia may differ) while the "
                        "drive loops and their feed-forward keep SCENE's")
    p.add_argument("--view", nargs="?", const=0, type=port, metavar="PORT",
                   help="serve a live 3D view of the device in the browser on 127.0.0.1:PORT "
                        "(no PORT or 0: any free port); the second line printed is its address")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    """Serve until SIGINT or SIGTERM, then return. With --view the live view
    (stewart_sim.view.live_server) listens on loopback from before the device starts (a taken port
    fails at once) until the device stops; its address is the line after the device's own."""
    from hil.spawn import serve_device  # pymavlink: only for this command
    from stewart_sim.scene.load import load

    if args.udp is None and not args.pty and args.gcs is None:
        from hil.errors import LinkError
        raise LinkError("device: give a link: --udp 127.0.0.1:PORT, --pty or "
                        "--gcs 127.0.0.1:PORT")
    scene = load(args.scene)
    model, config = scene.model, scene.require_controller()
    machine = load(args.truth) if args.truth is not None else scene   # what the device is
    # the device checks the truth against the scene (hil.truth) before it serves
    hidden = {"truth": machine.model if args.truth is not None else None,
              "sensors": machine.sensors}
    if args.view is None:
        serve_device(model, config, args.udp, args.watchdog, args.lockstep, args.signing_key,
                     gcs=args.gcs, pty=args.pty, **hidden)
        return
    from hil.observe import Latest
    from stewart_sim.view.live_server import LiveView, live_page

    latest = Latest()
    with LiveView(live_page(model, config), latest, args.view) as view:
        def ready() -> None:
            view.start()
            print(f"view: {view.url}", flush=True)
        serve_device(model, config, args.udp, args.watchdog, args.lockstep, args.signing_key,
                     observer=latest, ready=ready, gcs=args.gcs, pty=args.pty, **hidden)
