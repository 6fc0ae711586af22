"""What `design` writes: pareto.csv (the front), candidates.csv (every candidate evaluated),
best.toml (the chosen design as a scene, commented with its dense check's margins), front.png,
margins.png, parameters.png and summary.md; or, when no candidate meets every requirement, the
report of the binding ones."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import tomlkit

from stewart_fmu.io import write_csv, write_text
from stewart_fmu.scene import parse_scene_bytes, scene_from_dict

from .candidate import Candidate
from .candidate import candidate_scene
from .search import SearchResult, binding, least_violating, objectives
from .spec import DRIVE, DesignSpec, unit

FILES = ("pareto.csv", "candidates.csv", "best.toml", "front.png", "margins.png",
         "parameters.png", "summary.md")


def candidates_table(spec: DesignSpec, r: SearchResult, rows: np.ndarray) -> np.ndarray:
    """Rows of X: generation, every free parameter, the objectives, every relative margin."""
    F = objectives(spec, r.X[rows], r.margins[rows])
    cols = {"candidate": rows.astype(np.int64), "generation": r.generation[rows].astype(np.int64)}
    for k, p in enumerate(spec.free):
        # the drive: its index in the catalogue's cost order, as the candidate used it
        cols[p.name] = np.floor(r.X[rows, k]).astype(np.int64) if p.name == DRIVE \
            else r.X[rows, k]
    cols["base_radius_m"] = F[:, 0]
    cols["least_margin"] = -F[:, 1]
    if F.shape[1] > 2:
        cols["drive_cost"] = F[:, 2]
    for k, n in enumerate(r.names):
        cols[f"margin_{n}"] = r.margins[rows, k]
    out = np.empty(len(rows), dtype=[(k, v.dtype) for k, v in cols.items()])
    for k, v in cols.items():
        out[k] = v
    return out


def best_text(spec: DesignSpec, c: Candidate, points: int) -> str:
    """The chosen design as a scene (the base scene's tables, the geometry in place), its
    margins in the header; read back and built as any scene before it is returned."""
    doc = tomlkit.document()
    doc.add(tomlkit.comment(f"Designed by `stewart-sim design {Path(spec.source).name}` from "
                            f"the base scene {spec.base.get('name', '')!r}."))
    doc.add(tomlkit.comment(f"Dense check ({c.poses} required poses, {points} per axis): every "
                            "requirement's margin (positive: met)"))
    for m in c.margins:
        doc.add(tomlkit.comment(f"  {m.name:<16} {m.absolute:+.6g} {m.unit:<8} "
                                f"({m.relative:+.1%})  {m.where}".rstrip()))
    doc.add(tomlkit.comment("Parameters: " + ", ".join(
        f"{k} = {_value(spec, k, v)} {unit(k)}".rstrip() for k, v in c.values.items())))
    d = candidate_scene(spec, c.values)
    d["name"] = f"{spec.base.get('name', 'design')}-designed"
    for key, value in d.items():
        doc[key] = value
    text = tomlkit.dumps(doc)
    scene_from_dict(parse_scene_bytes(text.encode(), "best.toml"), source="best.toml")
    return text


def front_png(path: Path, spec: DesignSpec, r: SearchResult) -> None:
    """Every candidate's base radius (mm) against its least relative margin (%), the front
    and the chosen design marked."""
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    F = objectives(spec, r.X, r.margins)
    ok = np.all(r.margins >= 0, axis=1)
    fig = Figure(figsize=(7, 4.5))
    ax = fig.add_subplot()
    ax.scatter(F[~ok, 0] * 1e3, -F[~ok, 1] * 100, s=6, c="0.75", label="infeasible")
    ax.scatter(F[ok, 0] * 1e3, -F[ok, 1] * 100, s=8, c="tab:blue", label="feasible")
    if len(r.front):
        ax.plot(F[r.front, 0] * 1e3, -F[r.front, 1] * 100, "o-", c="tab:orange", ms=4,
                label="Pareto front")
    if r.chosen_index is not None:
        i = r.chosen_index
        ax.plot(F[i, 0] * 1e3, -F[i, 1] * 100, "*", c="tab:red", ms=14, label="chosen")
    ax.axhline(0.0, c="k", lw=0.8)
    ax.set_xlabel("base radius (mm)")
    ax.set_ylabel("least margin over the requirements (% of each)")
    # candidates far outside (a home out of its stroke is -1000 %) are left below the frame
    least = -F[:, 1] * 100
    lo = max(-100.0, float(np.percentile(least, 5)))
    hi = float(least.max())
    ax.set_ylim(lo - 0.05 * (hi - lo), hi + 0.1 * (hi - lo) + 1e-9)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"design: {len(r.X)} candidates, seed {spec.search.seed}")
    fig.tight_layout()
    save_figure(fig, path)


def margins_png(path: Path, r: SearchResult) -> None:
    """Each requirement's relative margin (%) of the chosen design on the search's grid and on
    the dense check's (of the least-violating candidate when none was chosen)."""
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    c = r.chosen if r.chosen is not None else r.closest
    fig = Figure(figsize=(7, 4.5))
    ax = fig.add_subplot()
    y = np.arange(len(r.names))
    dense = np.array([m.relative for m in c.margins]) * 100
    if r.chosen is not None:
        ax.barh(y + 0.2, r.margins[r.chosen_index] * 100, 0.4, color="0.7",
                label="search grid")
        ax.barh(y - 0.2, dense, 0.4, color="tab:blue", label="dense check")
        title = "the chosen design's margins"
    else:
        ax.barh(y, dense, 0.6, color="tab:red", label="search grid")
        title = "no design: the least-violating candidate's margins"
    ax.axvline(0.0, c="k", lw=0.8)
    ax.set_yticks(y, r.names)
    ax.invert_yaxis()
    ax.set_xlabel("margin (% of the requirement: stroke, cone, cond limit, frequency, stiffness)")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def parameters_png(path: Path, spec: DesignSpec, r: SearchResult) -> None:
    """The free parameters of the front's designs and of the chosen one, each on its bounds
    (0: low, 1: high; the bounds in the axis labels with their units)."""
    from matplotlib.figure import Figure

    from stewart_sim.shell.plots import save_figure

    free = spec.free
    lo = np.array([p.low for p in free])
    span = np.array([p.high - p.low for p in free])
    fig = Figure(figsize=(8, 4.5))
    ax = fig.add_subplot()
    k = np.arange(len(free))
    for i in r.front:
        ax.plot(k, (r.X[i] - lo) / span, "-", c="tab:orange", alpha=0.5, lw=1)
    if r.chosen_index is not None:
        ax.plot(k, (r.X[r.chosen_index] - lo) / span, "o-", c="tab:red", lw=2, label="chosen")
    ax.plot([], [], "-", c="tab:orange", label=f"front ({len(r.front)})")
    ax.set_xticks(k, [f"{p.name}\n[{p.low:.3g}, {p.high:.3g}]\n{unit(p.name)}"
                      for p in free], fontsize=7, rotation=20, ha="right")
    ax.set_ylabel("position in its bounds (0: low, 1: high)")
    ax.set_ylim(-0.05, 1.05)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("the free parameters of the front")
    fig.tight_layout()
    save_figure(fig, path)


def summary_text(spec: DesignSpec, r: SearchResult) -> str:
    ok = int(np.sum(np.all(r.margins >= 0, axis=1)))
    lines = [f"# design: {Path(spec.source).name}", "",
             f"{len(r.X)} candidates ({spec.search.population} x {spec.search.generations} "
             f"generations, seed {spec.search.seed}) on {r.workers} Dask workers in "
             f"{r.seconds:.2f} s ({r.seconds / len(r.X) * 1e3:.2f} ms a candidate, wall); "
             f"{ok} feasible, {len(r.front)} on the front.", ""]
    if r.chosen is not None:
        c = r.chosen
        lines += [f"Chosen: candidate {r.chosen_index}, re-checked densely on {c.poses} poses "
                  f"({spec.workspace.check_points} per axis): every requirement met.", "",
                  "| requirement | margin | unit | relative | binds at |", "|---|---|---|---|---|"]
        lines += [f"| {m.name} | {m.absolute:+.6g} | {m.unit} | {m.relative:+.1%} | {m.where} |"
                  for m in c.margins]
        lines += ["", "| parameter | value | unit |", "|---|---|---|"]
        lines += [f"| {k} | {_value(spec, k, v)} | {unit(k)} |" for k, v in c.values.items()]
        if r.dense_failed:
            lines += ["", f"The dense check rejected front candidates {list(r.dense_failed)}."]
    else:
        lines += infeasible_lines(spec, r)
    return "\n".join(lines) + "\n"


def infeasible_lines(spec: DesignSpec, r: SearchResult) -> list[str]:
    """Which requirement binds and by how much: those no candidate met (the best any reached),
    and the least-violating candidate's shortfalls."""
    out = ["**No design found that meets every requirement.**", ""]
    if r.dense_failed:
        out += [f"The dense check rejected every front design tried ({list(r.dense_failed)}).", ""]
    unmet = binding(r.names, r.margins)
    if unmet:
        out += ["Requirements no candidate met (the best margin any reached):", ""]
        out += [f"- {n}: short by {-b:.1%} of the requirement at best" for n, b in unmet]
        out += [""]
    i = least_violating(r.margins)
    out += [f"The least-violating candidate ({i}) falls short on:", ""]
    out += [f"- {m.name}: {m.absolute:+.6g} {m.unit} ({m.relative:+.1%}) {m.where}".rstrip()
            for m in r.closest.margins if m.relative < 0]
    out += ["", "| parameter | value | unit |", "|---|---|---|"]
    out += [f"| {k} | {_value(spec, k, v)} | {unit(k)} |" for k, v in r.closest.values.items()]
    return out


def _value(spec: DesignSpec, name: str, value: float) -> str:
    """A parameter's value as printed: a number, or the catalogue drive's name."""
    if name == DRIVE:
        return f"{spec.drive({DRIVE: value}).name!r} (cost {spec.drive({DRIVE: value}).cost:g})"
    return f"{value:.6g}"


def binding_line(r: SearchResult) -> str:
    """One line for the terminal: the most binding requirement and by how much."""
    unmet = binding(r.names, r.margins)
    if unmet:
        n, b = unmet[0]
        m = next(m for m in r.closest.margins if m.name == n)
        return (f"no geometry meets {n}: the best candidate is short by {-b:.1%} of it (the "
                f"least-violating one by {-m.absolute:.6g} {m.unit})")
    m = r.closest.least
    return (f"no candidate meets every requirement at once: the least-violating one is short "
            f"on {m.name} by {-m.relative:.1%} ({-m.absolute:.6g} {m.unit})")


def write(folder: Path, spec: DesignSpec, r: SearchResult) -> list[str]:
    """The set into `folder` (a result_set's staging directory); the names written."""
    written = []
    write_csv(folder / "candidates.csv", candidates_table(spec, r, np.arange(len(r.X))))
    write_csv(folder / "pareto.csv", candidates_table(spec, r, r.front))
    written += ["candidates.csv", "pareto.csv"]
    if r.chosen is not None:
        write_text(folder / "best.toml", best_text(spec, r.chosen, spec.workspace.check_points))
        written.append("best.toml")
    front_png(folder / "front.png", spec, r)
    margins_png(folder / "margins.png", r)
    parameters_png(folder / "parameters.png", spec, r)
    write_text(folder / "summary.md", summary_text(spec, r))
    return written + ["front.png", "margins.png", "parameters.png", "summary.md"]
