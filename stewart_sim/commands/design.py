"""`stewart-sim design DESIGN.toml --out DIR`: a hexapod's geometry from its requirements: an
NSGA-II search (pymoo) on Dask, the chosen design re-checked densely, written as a scene
(stewart_sim.studies.design; docs/guides/design.md). Exit status 3 when no design meets every
requirement (DIR then holds the report naming the binding requirement, no best.toml)."""
from __future__ import annotations

import argparse

NO_DESIGN = 3   # exit status: the search found no design meeting every requirement


def add_parser(sub, help_text: str) -> None:
    """Register `design` on the command line's subparsers."""
    p = sub.add_parser("design", help=help_text, description=(
        "Search the geometry (radii, joint pair angles and heights, home height, stroke, leg "
        "stiffness, the drive from a catalogue) that meets a design.toml's requirements "
        "(workspace, payload, first resonance, stiffness, cond(J), joint cones, the motions to "
        "fly within the drive's limits); the chosen design re-checked densely and written as "
        "DIR/best.toml. Exit 3: no design meets every requirement (DIR/summary.md says which "
        "binds and by how much)."))
    p.add_argument("design", metavar="DESIGN.toml", help="the requirements (docs/guides/design.md)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="result directory: pareto.csv, candidates.csv, best.toml, front.png, "
                        "margins.png, parameters.png, summary.md")
    p.add_argument("--workers", type=int, metavar="N",
                   help="local Dask worker processes (default: one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://HOST:PORT) instead of a local cluster")
    p.add_argument("--population", type=int, metavar="N",
                   help="candidates per generation, in place of design.toml's search.population")
    p.add_argument("--generations", type=int, metavar="N",
                   help="generations, in place of search.generations")
    p.add_argument("--seed", type=int, metavar="N", help="in place of search.seed")
    p.add_argument("--resume", action="store_true",
                   help="continue the search DIR/design-checkpoint.npz holds (the generations "
                        "evaluated before a Ctrl-C, or a shorter run's: --generations may be "
                        "larger): the same front as one run without a stop")
    p.add_argument("--no-view", action="store_true",
                   help="do not write DIR/view.html (the chosen design at home, its "
                        "constant-orientation workspace and the required poses by margin)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Check the file, search, write the set; the exit status (0, or NO_DESIGN)."""
    from stewart_sim.studies.design import spec as design_spec

    spec = design_spec.load(args.design)    # a bad file fails before the cluster starts
    spec = design_spec.with_search(spec, population=args.population,
                                   generations=args.generations, seed=args.seed)
    if args.workers is not None and not 1 <= args.workers <= 1024:
        raise design_spec.DesignInputError(f"--workers: need 1..1024, got {args.workers}")
    import os

    from stewart_sim.shell.outputs import result_set
    from stewart_sim.studies.design import report, search
    from stewart_sim.studies.sweep.cluster import dask_client

    workers = args.workers or os.cpu_count() or 1
    from stewart_sim.studies.design.checkpoint import open_checkpoint, stopped

    checkpoint = open_checkpoint(args.out, spec, args.resume)
    try:
        with dask_client(args.scheduler, workers) as client:
            if args.scheduler is not None:
                workers = max(1, len(client.scheduler_info().get("workers", {})))
            result = search.run(spec, client, workers, checkpoint=checkpoint)
    except KeyboardInterrupt:
        raise stopped(args.out, checkpoint) from None
    from stewart_sim.studies.design.workspace_view import write_design_view

    view = None
    with result_set(args.out, report.FILES + ("view.html",)) as stage:
        written = report.write(stage, spec, result)
        if not args.no_view:
            view = write_design_view(stage, spec, result)
    print(f"{args.out}: {', '.join(written + (['view.html'] if view else []))}")
    if view:
        print(f"{args.out}/{view}")
    if result.chosen is None:
        print(f"stewart-sim: {report.binding_line(result)} (see {args.out}/summary.md)")
        return NO_DESIGN
    least = result.chosen.least
    drive = spec.drive(result.chosen.values)
    flown = "" if spec.flight is None else \
        f" and every sample of {len(spec.flight.motions)} motions"
    print(f"chosen design re-checked on {result.chosen.poses} poses{flown}: least margin "
          f"{least.name} {least.relative:+.1%}" + ("" if drive is None else
                                                   f"; drive {drive.name}"))
    return 0
