"""`stewart-sim workspace SCENE`: what the mechanism can reach (stewart_sim.studies.workspace, the
feasibility engine of stewart_fmu.reach).

    --check POSES.csv --out V.csv   each pose against every limit (the contract's V.csv)
    --reach --direction D [--from Q]  the largest step along D before the first limit
    --ranges [--out RANGES.csv]     per-axis travel from home, both ways, and what ends it
    --map --out DIR [--resolution H] [--no-view]  the constant-orientation workspace: volume,
                                    runs, slices, tilts, the 3D view of its surface
    --load --accel A --out DIR [--payload P]  where the rack force binds over that workspace
"""
from __future__ import annotations

import argparse

from stewart_sim.commands.frame_option import add_frame


def add_parser(sub, help_text: str) -> None:
    """Register `workspace` on the command line's subparsers."""
    p = sub.add_parser("workspace", help=help_text,
                       description="What the mechanism reaches: every limit's margin at poses, "
                                   "the travel along a direction, the per-axis ranges.")
    p.add_argument("scene", metavar="SCENE", help="scene file (TOML)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--check", metavar="POSES.csv",
                      help="poses (columns x,y,z,thx,thy,thz; with dx..dthz and ddx..ddthz the "
                           "drives' limits too) checked against every limit: --out V.csv")
    what.add_argument("--reach", action="store_true",
                      help="the largest step from --from along --direction before a limit")
    what.add_argument("--ranges", action="store_true",
                      help="travel from home along each axis, both ways (the datasheet table)")
    what.add_argument("--map", action="store_true",
                      help="the constant-orientation workspace at --from's angles (default "
                           "home's): its volume, DIR/map.csv (x, y, z_low, z_high of each run "
                           "of a column) and DIR/slices.png; the orientation workspace at "
                           "--from's position: DIR/tilt.csv and DIR/tilt.png (the largest "
                           "tilt per azimuth); --out DIR")
    what.add_argument("--load", action="store_true",
                      help="over --map's grid (the constant-orientation workspace at --from's "
                           "angles, x-y step --resolution, z every step in each run), the least "
                           "rack-force margin over the 12 signed axis corners of --accel, at "
                           "rest, with the scene's [payload] or --payload: DIR/load.csv (x, y, "
                           "z, margin_n, leg, corner) and DIR/load.png (x-y and x-z slices through "
                           "--from's position); --out DIR")
    p.add_argument("--accel", metavar="ax,ay,az,alx,aly,alz",
                   help="--load: the acceleration envelope's half-widths, m/s^2 (C's linear "
                        "acceleration) and rad/s^2 (the angles' second derivatives)")
    p.add_argument("--payload", metavar="MASS|FILE|KEYS",
                   help="--load: a payload in place of the scene's, as `modes --payload` takes "
                        "it: a mass in kg (a point mass at C's origin), a TOML file ([payload] "
                        "mass, com, inertia) or those keys inline")
    p.add_argument("--out", metavar="FILE", help="V.csv of --check (required there); the "
                   "ranges as CSV with --ranges")
    add_frame(p, "poses are given in (POSES.csv, --from, --direction, the maps' grids)")
    p.add_argument("--from", dest="start", metavar="x,y,z,thx,thy,thz",
                   help="--reach: the start pose (default: home, in the frame)")
    p.add_argument("--direction", metavar="dx,dy,dz,dthx,dthy,dthz",
                   help="--reach: the direction (the step is in its units: m or rad along a "
                        "unit axis)")
    p.add_argument("--no-view", action="store_true",
                   help="--map: leave out DIR/view.html (the mechanism at --from with the "
                        "workspace's surface)")
    p.add_argument("--resolution", type=float, metavar="H",
                   help="--map: the x-y grid step, m (default: the characteristic length / 30)")
    p.set_defaults(run=run)


def _six(text: str | None, what: str):
    import numpy as np

    from stewart_fmu.errors import StewartError

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 6 or not all(np.isfinite(values)):
        raise StewartError(f"{what} {text!r}: need six finite numbers separated by commas")
    return np.array(values)


def run(args: argparse.Namespace) -> None:
    """Answer the query asked; print what was written or found."""
    from pathlib import Path

    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame, from_platform
    from stewart_sim.scene.load import load
    from controller.capability import engine

    scene = load(args.scene)
    if args.load:
        _load(args, scene)
        return
    frame = chosen_frame(scene.model, args.frame)   # an unknown frame name: one line, exit 2
    eng = engine(scene.model, scene.controller)
    if args.check:
        if not args.out:
            raise StewartError("--check needs --out V.csv")
        from stewart_fmu.io import write_csv
        from stewart_sim.studies.workspace.check import check_table, read_poses, summary

        q, qd, qdd = read_poses(Path(args.check))
        table = check_table(eng, q, qd, qdd, frame)
        write_csv(args.out, table)
        present = [lim.name for lim in eng.present(qd is not None, qdd is not None)]
        print(f"wrote {args.out}: {summary(table, present)}")
    elif args.reach:
        from stewart_sim.studies.workspace.ranges import reach_text

        if args.direction is None:
            raise StewartError("--reach needs --direction dx,dy,dz,dthx,dthy,dthz")
        d = _six(args.direction, "--direction")
        q0 = from_platform(scene.model, scene.model.home, frame) if args.start is None \
            else _six(args.start, "--from")
        print(reach_text(eng.travel(q0, d, frame=frame), q0, d, frame))
    elif args.map:
        _map(args, scene, eng, frame)
    else:
        from stewart_fmu.io import write_csv
        from stewart_fmu.reach import axis_ranges
        from stewart_sim.studies.workspace.ranges import ranges_table, ranges_text

        rows = axis_ranges(eng, frame)
        print(ranges_text(rows, frame))
        if args.out:
            write_csv(args.out, ranges_table(rows))
            print(f"wrote {args.out}")


def _grid_step(args: argparse.Namespace, model) -> float:
    """--resolution, checked (default: the characteristic length / 30)."""
    import math

    from stewart_fmu.errors import StewartError

    h = args.resolution if args.resolution is not None else model.characteristic_length / 30
    if not (math.isfinite(h) and h > 0):
        raise StewartError(f"--resolution {args.resolution!r}: must be a finite step > 0 (m)")
    return h


def _start_map(args: argparse.Namespace, model, eng, frame: str):
    """The start pose (--from, default home) and the constant-orientation map at its angles."""
    import numpy as np

    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import from_platform
    from stewart_sim.studies.workspace.maps import MAX_CELLS, constant_orientation, position_box

    h = _grid_step(args, model)
    start = from_platform(model, model.home, frame) if args.start is None \
        else _six(args.start, "--from")
    lo, hi = position_box(eng, start[3:], frame)
    cells = float(np.prod((hi - lo) / h))
    if not cells <= MAX_CELLS:
        raise StewartError(f"--resolution {h!r}: {cells:.3g} grid cells in the box searched, "
                           f"more than {MAX_CELLS:.0e}: give a coarser step")
    return start, constant_orientation(eng, start, frame, h)


def _load(args: argparse.Namespace, scene) -> None:
    """--load: the load map's CSV and PNG written together (a result set), the summary printed."""
    import numpy as np

    from stewart_fmu.errors import StewartError
    from stewart_fmu.frames import chosen_frame
    from stewart_fmu.io import write_csv
    from stewart_sim.shell.outputs import result_set
    from stewart_sim.studies.modes.study import payload_from, with_payload
    from stewart_sim.studies.workspace.rack_force import load_figure, load_map, load_table
    from controller.capability import engine

    if not args.out:
        raise StewartError("--load needs --out DIR")
    if args.accel is None:
        raise StewartError("--load needs --accel ax,ay,az,alx,aly,alz")
    accel = _six(args.accel, "--accel")
    if np.any(accel < 0):
        raise StewartError(f"--accel {args.accel!r}: the envelope's half-widths must be >= 0")
    model = scene.model
    if args.payload is not None:
        model = with_payload(model, payload_from(args.payload, model))
    frame = chosen_frame(model, args.frame)
    eng = engine(model, scene.controller)
    start, m = _start_map(args, model, eng, frame)
    lm = load_map(eng, m, accel)
    p = model.payload
    what = "no payload" if p is None else \
        f"payload {p.mass:.6g} kg at ({', '.join(f'{v:.4g}' for v in p.com)}) m"
    envelope = ", ".join(f"{v:.6g}" for v in accel)
    with result_set(args.out, known=("load.csv", "load.png")) as stage:
        write_csv(stage / "load.csv", load_table(lm))
        load_figure(lm, m, start[:3], stage / "load.png",
                    f"least rack-force margin over the 12 corners +-({envelope}) (m/s^2, "
                    f"rad/s^2), at rest\n{what}; {frame} frame, angles "
                    f"{', '.join(f'{a:.3g}' for a in m.angles)} rad")
    print(f"rack force over the constant-orientation workspace ({frame} frame, angles "
          f"{', '.join(f'{a:.6g}' for a in m.angles)} rad; {len(lm.margin)} grid positions, "
          f"step {m.h * 1e3:.4g} mm), {what}, envelope +-({envelope}) m/s^2 and rad/s^2 on "
          f"each axis alone, at rest:")
    if len(lm.margin):
        k = int(np.argmin(lm.margin))
        x, y, z = lm.points[k]
        print(f"binds on {lm.binding_fraction * 100:.4g} % of the reachable volume; least "
              f"margin {lm.margin[k]:.6g} N at ({x * 1e3:.3f}, {y * 1e3:.3f}, {z * 1e3:.3f}) "
              f"mm, leg {lm.leg[k]}, corner {lm.corner[k]}")
    print(f"wrote {args.out}/load.csv and load.png")


def _map(args: argparse.Namespace, scene, eng, frame: str) -> None:
    """--map: the volume printed, map.csv, slices.png, the tilt files and view.html written
    together (a result set)."""
    import numpy as np

    from stewart_fmu.errors import StewartError
    from stewart_fmu.io import named_array, write_csv
    from stewart_sim.shell.outputs import result_set
    from pathlib import Path

    from stewart_sim.studies.workspace.maps import slices, tilt_figure, tilts

    if not args.out:
        raise StewartError("--map needs --out DIR")
    model = scene.model
    start, m = _start_map(args, model, eng, frame)
    h = m.h
    tilt = tilts(eng, start, frame)
    known = ("map.csv", "slices.png", "tilt.csv", "tilt.png", "view.html")
    with result_set(args.out, known=known) as stage:
        write_csv(stage / "map.csv", named_array({"x": m.runs[:, 0], "y": m.runs[:, 1],
                                                  "z_low": m.runs[:, 2], "z_high": m.runs[:, 3]}))
        slices(eng, m, start[:3], stage / "slices.png")
        table = np.empty(len(tilt.azimuth), dtype=[("azimuth", "f8"), ("tilt", "f8"),
                                                   ("limit", object), ("where", object)])
        table["azimuth"], table["tilt"] = tilt.azimuth, tilt.tilt
        table["limit"], table["where"] = tilt.limit, tilt.where
        write_csv(stage / "tilt.csv", table)
        tilt_figure(tilt, stage / "tilt.png")
        if not args.no_view:
            from stewart_sim.studies.workspace.map_view import write_map_view

            view_line = write_map_view(stage, scene, m, start, Path(args.scene).name)
    print(f"constant-orientation workspace at angles ({', '.join(f'{a:.6g}' for a in m.angles)})"
          f" rad, {frame} frame: {m.volume * 1e3:.6g} litres ({len(m.runs)} runs of "
          f"{len(np.unique(m.runs[:, :2], axis=0))} columns; x-y grid {h * 1e3:.4g} mm, z by "
          f"bisection to 1e-9 m; {m.seconds:.2f} s)")
    k = int(np.argmin(tilt.tilt))
    least = f"{tilt.limit[k]} {tilt.where[k]}".strip() or "no limit"
    print(f"orientation workspace at ({', '.join(f'{v:.6g}' for v in start[:3])}) m: tilt "
          f"{np.degrees(tilt.tilt.min()):.3f} to {np.degrees(tilt.tilt.max()):.3f} deg over "
          f"{len(tilt.tilt)} azimuths (least at {np.degrees(tilt.azimuth[k]):.0f} deg: {least})")
    if args.no_view:
        print(f"wrote {args.out}/map.csv, slices.png, tilt.csv and tilt.png")
    else:
        print(f"wrote {args.out}/map.csv, slices.png, tilt.csv, tilt.png and {view_line}")
