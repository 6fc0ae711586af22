"""One candidate checked against every requirement: its margins, named.

A margin is positive when the requirement is met, in the requirement's unit (`absolute`) and
relative to its scale (`relative`, what the search compares): the workspace's limits over every
required pose (stewart_fmu.reach's engine: stroke_min, stroke_max, the joint cones, leg and
obstacle clearance where the base scene has them, cond(J)), scaled by the stroke, the cone, the
characteristic length and the cond(J) limit; the first resonance (Hz) over the required poses
the engine passes, home included (stewart_fmu.stiffness.modes_map), relative to the required;
the stiffness per axis (N/m, N m/rad) at home and at the pose of the lowest first mode
(stewart_fmu.stiffness.stiffness at C's origin), relative to the required."""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.reach import Engine
from stewart_fmu.scene import scene_from_dict
from stewart_fmu.stiffness import modes_map, stiffness

from .flight import flight_margins, flight_names
from .layout import scene_dict
from .margin import FAILED, UNITS, Margin
from .spec import POSE, DesignSpec, Workspace

GEOMETRIC = ("stroke_min", "stroke_max", "base_cone", "platform_cone", "leg_clearance",
             "obstacle", "cond")
STIFF_UNITS = ("N/m", "N/m", "N/m", "N m/rad", "N m/rad", "N m/rad")


@dataclass(frozen=True)
class Candidate:
    """One geometry's margins on every requirement (names in `requirement_names` order)."""

    values: dict[str, float]
    margins: tuple[Margin, ...]
    first_hz: float           # the lowest first mode over the checked poses (nan: none)
    poses: int                # required poses checked

    @property
    def least(self) -> Margin:
        return min(self.margins, key=lambda m: m.relative)

    @property
    def feasible(self) -> bool:
        return all(m.relative >= 0.0 for m in self.margins)


def requirement_names(spec: DesignSpec) -> tuple[str, ...]:
    """The requirements a candidate of `spec` is checked on, in report order (the geometric
    limits present in every candidate's model: the base scene's tables and the cones asked)."""
    r, clearance = spec.requirements, spec.base.get("clearance") or {}
    present = {"stroke_min", "stroke_max", "cond"}
    present |= {n for n in ("base_cone", "platform_cone") if getattr(r, n) is not None}
    if "leg_radius" in clearance:
        present.add("leg_clearance")
    if clearance.get("obstacles"):
        present.add("obstacle")
    names = [n for n in GEOMETRIC if n in present]
    if spec.requirements.first_resonance is not None:
        names.append("first_resonance")
    names += [f"stiffness_{a}" for a, k in zip(POSE, spec.requirements.stiffness) if k]
    return tuple(names) + flight_names(spec, tuple(present))


def candidate_scene(spec: DesignSpec, values: dict[str, float]) -> dict:
    """A candidate's scene tables: the base scene's with its geometry, payload, cones and
    catalogue drive in place."""
    r, drive = spec.requirements, spec.drive(values)
    return scene_dict(spec.base, values, spec.payload, (r.base_cone, r.platform_cone),
                      None if drive is None else drive.drive_table)


def candidate_model(spec: DesignSpec, values: dict[str, float], check: bool = True):
    """The Model of a candidate (SceneError when its home is outside its stroke or singular;
    check=False: the stroke left out, for a look at the tables only)."""
    d = candidate_scene(spec, values)
    if not check:
        d["geometry"]["leg_min"] = d["geometry"]["leg_max"] = None
        d["geometry"] = {k: v for k, v in d["geometry"].items() if v is not None}
    return scene_from_dict(d, source="candidate")


def workspace_poses(ws: Workspace, home: np.ndarray, points: int) -> np.ndarray:
    """The required poses about home: the ranges' grid (`points` per axis, every combination
    ("box") or one axis at a time ("axes")), then each orientation set held at every position
    of that grid (its angles in place of the grid's)."""
    axes = [POSE.index(a) for a in ws.ranges]
    values = [np.linspace(lo, hi, points) for lo, hi in ws.ranges.values()]
    if ws.combine == "box":
        offsets = np.zeros((points ** len(axes), 6))
        for col, combo in enumerate(itertools.product(*values) if axes else [()]):
            offsets[col, axes] = combo
    else:
        rows = [np.zeros(6)]
        for k, vals in zip(axes, values):
            for v in vals:
                if v != 0.0:
                    row = np.zeros(6)
                    row[k] = v
                    rows.append(row)
        offsets = np.array(rows)
    blocks = [offsets]
    for o in ws.orientations:
        extra = offsets.copy()
        extra[:, 3:] = o
        blocks.append(np.unique(extra, axis=0))
    return home + np.vstack(blocks)


def evaluate(spec: DesignSpec, x: np.ndarray, names: tuple[str, ...],
             points: int | None = None, every: int | None = None) -> Candidate:
    """The candidate of the free parameters x checked on every requirement (`points` per axis
    of the workspace grid, every `every`-th sample of the motions: the search's by default)."""
    values = spec.values(np.asarray(x, dtype=float))
    points = points or spec.workspace.search_points
    try:
        model = candidate_model(spec, values)
    except StewartError:
        return _failed_home(spec, values, names)
    Q = workspace_poses(spec.workspace, model.home, points)
    found = _geometric(spec, model, values, Q)
    feasible = found.pop("_feasible")
    first_hz, modal = _modal(spec, model, Q[feasible])
    found.update(modal)
    if spec.flight is not None:
        found.update(flight_margins(spec, model, values, names, every or spec.flight.every))
    return Candidate(values, tuple(found[n] for n in names), first_hz, len(Q))


def _geometric(spec: DesignSpec, model, values: dict, Q: np.ndarray) -> dict:
    eng = Engine(model, None, spec.requirements.cond_limit)
    res = eng.check(Q)
    scale = margin_scales(spec, model, values)
    out: dict = {"_feasible": res["feasible"]}
    for lim in eng.present():
        col = res[lim.name]
        k = int(np.argmin(col))
        where = _pose_text(Q[k] - model.home)
        out[lim.name] = Margin(lim.name, float(col[k]), UNITS[lim.name],
                               float(col[k]) / scale[lim.name], where)
    return out


def margin_scales(spec: DesignSpec, model, values: dict) -> dict[str, float]:
    """What each geometric margin is divided by to be relative: the stroke, the cone asked,
    the characteristic length, the cond(J) limit."""
    r = spec.requirements
    return {"stroke_min": values["stroke"], "stroke_max": values["stroke"],
            "base_cone": r.base_cone, "platform_cone": r.platform_cone,
            "leg_clearance": model.characteristic_length,
            "obstacle": model.characteristic_length, "cond": r.cond_limit}


def _modal(spec: DesignSpec, model, Q: np.ndarray) -> tuple[float, dict]:
    """The first resonance over the poses (home first) and the stiffness per axis at home and
    at the pose of the lowest first mode."""
    r = spec.requirements
    out: dict = {}
    Q = np.vstack([model.home, Q])
    try:
        m = modes_map(model, Q)
        k = int(np.argmin(m.lowest_hz))
        first, worst = float(m.lowest_hz[k]), Q[k]
        K = np.minimum(stiffness(model, model.home).axis_stiffness,
                       stiffness(model, worst).axis_stiffness)
    except StewartError as exc:   # the legs buckle under the loads at a pose
        first, worst, K = float("nan"), model.home, None
        why = str(exc)[:80]
    if r.first_resonance is not None:
        out["first_resonance"] = Margin("first_resonance", first - r.first_resonance, "Hz",
                                        first / r.first_resonance - 1.0,
                                        _pose_text(worst - model.home)) if K is not None else \
            Margin("first_resonance", float("nan"), "Hz", FAILED, why)
    for a, req, unit, j in zip(POSE, r.stiffness, STIFF_UNITS, range(6)):
        if req:
            name = f"stiffness_{a}"
            out[name] = Margin(name, float(K[j] - req), unit, float(K[j] / req - 1.0)) \
                if K is not None else Margin(name, float("nan"), unit, FAILED, why)
    return first, out


def _failed_home(spec: DesignSpec, values: dict, names: tuple[str, ...]) -> Candidate:
    """A candidate whose home is outside its stroke (or singular): the stroke margins at home,
    FAILED on the rest (the search is steered back by how far home is out)."""
    try:
        model = candidate_model(spec, values, check=False)
        lengths = np.asarray(inverse_kinematics(model, model.home).lengths).ravel()
    except StewartError as exc:    # no pose computed at all (singular at home)
        why = str(exc)[:80]
        return Candidate(values, tuple(Margin(n, float("nan"), UNITS.get(n, ""), FAILED, why)
                                       for n in names), float("nan"), 0)
    lo, hi = values["leg_min"], values["leg_min"] + values["stroke"]
    at_home = {"stroke_min": float(lengths.min() - lo), "stroke_max": float(hi - lengths.max())}
    margins = []
    for n in names:
        if n in at_home:
            a = at_home[n]
            margins.append(Margin(n, a, "m", min(a / values["stroke"], 0.0) + FAILED / 10,
                                  "home"))
        else:
            margins.append(Margin(n, float("nan"), UNITS.get(n, ""), FAILED, "home not reached"))
    return Candidate(values, tuple(margins), float("nan"), 0)


def _pose_text(d: np.ndarray) -> str:
    """A pose offset from home: 'x=+0.025 z=-0.010 thz=+0.100' (zeros left out)."""
    parts = [f"{n}={v:+.4g}" for n, v in zip(POSE, d) if abs(v) > 1e-12]
    return " ".join(parts) or "home"


def evaluate_many(spec: DesignSpec, X: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """The relative margins (N, requirements) of the candidates X (N, free): one Dask task."""
    return np.array([[m.relative for m in evaluate(spec, x, names).margins] for x in X])
