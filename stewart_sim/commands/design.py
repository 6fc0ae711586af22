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
    with dask_client(args.scheduler, workers) as client:
        if args.scheduler is not None:
            workers = max(1, len(client.scheduler_info().get("workers", {})))
        result = search.run(spec, client, workers)
    with result_set(args.out, report.FILES) as stage:
        written = report.write(stage, spec, result)
    print(f"{args.out}: {', '.join(written)}")
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
