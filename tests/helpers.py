"""Shared helpers of the tests (imported as `helpers`: tests/ is on pytest's pythonpath): the two
scenes as TOML dicts and Models, their model levels (tables dropped from the dict), smooth random
trajectories near home, scene-dict edits, the record of worst residuals, FMU exports without
their Windows binary, and the documentation's pages (the one place a test looks up what the docs
state)."""
from __future__ import annotations

import copy
import functools
import tomllib
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from controller.trajectory import quintic_step
from stewart_fmu import Model, scene_from_dict
from stewart_sim.cueing.motion import VehicleMotion

ROOT = Path(__file__).resolve().parents[1]
SCENES_DIR = ROOT / "scenes"
SCENE_FILES = {"micro": SCENES_DIR / "micro_manipulator.toml",
               "sim": SCENES_DIR / "motion_simulator.toml"}
DOCS_DIR = ROOT / "docs"
# folders of scenes/ that hold other inputs than scenes: sweep grids, design requirements
NOT_SCENES = ("sweeps", "design")


def shipped_scenes() -> list[Path]:
    """Every scene file shipped under scenes/ (the grids and requirements beside them left out)."""
    return sorted(p for p in SCENES_DIR.rglob("*.toml") if not set(NOT_SCENES) & set(p.parts))


# Model levels: the tables dropped from the scene dict. "platform_friction" is the variant with
# friction but no drive (and no legs), so friction is seen without any leg or drive inertia.
LEVELS = {
    "full": (),
    "no_drive": ("drive",),
    "no_drive_no_friction": ("drive", "friction"),
    "platform_only": ("legs", "drive", "friction"),
    "platform_friction": ("legs", "drive"),
}

# Per-scene amplitude bound of the smooth trajectories about home: metres for x, y, z, radians
# for the angles (roll, pitch and yaw peak together at 0.3-0.5 rad). The tests check that the
# trajectories they use stay inside the stroke.
TRAJ_SCALE = {
    "micro": np.array([0.006, 0.006, 0.008, 0.5, 0.5, 0.5]),
    "sim": np.array([0.08, 0.08, 0.08, 0.4, 0.4, 0.4]),
}


@functools.lru_cache(maxsize=None)
def _parsed(name: str) -> dict:
    with SCENE_FILES[name].open("rb") as fh:
        return tomllib.load(fh)


def scene_dict(name: str) -> dict:
    """A fresh deep copy of the parsed TOML of scene `name` ("micro" or "sim")."""
    return copy.deepcopy(_parsed(name))


def level_dict(data: dict, level: str) -> dict:
    """A deep copy of a scene dict with the tables of `level` (a key of LEVELS) dropped."""
    out = copy.deepcopy(data)
    for table in LEVELS[level]:
        out.pop(table, None)
    return out


@functools.lru_cache(maxsize=None)
def level_model(name: str, level: str) -> Model:
    """The Model of scene `name` at `level` (built once; Models are immutable)."""
    return scene_from_dict(level_dict(_parsed(name), level), source=f"{name}:{level}")


def smooth_trajectory(name: str, seed: int, n_terms: int = 3, scale: np.ndarray | None = None):
    """A random smooth trajectory near home as analytic functions of t.

    Each coordinate is home + sum_k A_k sin(w_k t + phi_k), k < n_terms (at most 3), with
    random signs and phases: one dominant slow term and smaller faster ones (below). Returns a
    function t -> (q, qd, qdd) that accepts a scalar or an array of times ((6,) or (N, 6)).
    """
    rng = np.random.default_rng(seed)
    home = level_model(name, "full").home
    scale = TRAJ_SCALE[name] if scale is None else np.asarray(scale, dtype=float)
    # One dominant slow term (0.7-0.8 of scale) and smaller faster ones (0.05-0.1 of scale each),
    # so each coordinate peaks near `scale` and stays below it.
    rel = np.vstack([rng.uniform(0.7, 0.8, (1, 6)), rng.uniform(0.05, 0.1, (n_terms - 1, 6))])
    amp = rel * rng.choice([-1.0, 1.0], (n_terms, 6)) * scale
    omega = np.vstack([rng.uniform(2.0, 6.0, (1, 6)), rng.uniform(6.0, 15.0, (n_terms - 1, 6))])
    phase = rng.uniform(0.0, 2.0 * np.pi, (n_terms, 6))

    def at(t):
        t = np.asarray(t, dtype=float)
        arg = omega * t[..., None, None] + phase                        # (..., n_terms, 6)
        q = home + np.sum(amp * np.sin(arg), axis=-2)
        qd = np.sum(amp * omega * np.cos(arg), axis=-2)
        qdd = -np.sum(amp * omega**2 * np.sin(arg), axis=-2)
        return q, qd, qdd

    return at


def case(name: str, level: str) -> tuple[dict, object]:
    """(scene dict, Model) of a scene at a level; level 'full+coulomb' is the full micro scene
    with a Coulomb friction of 0.2 N (its file has coulomb = 0; the simulator's has 150 N)."""
    if level == "full+coulomb":
        d = scene_dict(name)
        d["friction"]["coulomb"] = 0.2
        return d, scene_from_dict(d)
    return level_dict(scene_dict(name), level), level_model(name, level)


def trajectory_samples(name: str, seeds, n: int, duration: float = 2.0):
    """Samples of the smooth random trajectories `seeds`, n per trajectory over [0, duration]."""
    rows = [smooth_trajectory(name, s)(np.linspace(0.0, duration, n)) for s in seeds]
    return tuple(np.concatenate(c) for c in zip(*rows))


RATE_SCALE = {"micro": np.array([0.1, 0.1, 0.1, 2.0, 2.0, 2.0]),
              "sim": np.array([0.5, 0.5, 0.5, 0.8, 0.8, 0.8])}
ACC_SCALE = {"micro": np.array([3.0, 3.0, 3.0, 40.0, 40.0, 40.0]),
             "sim": np.array([4.0, 4.0, 4.0, 4.0, 4.0, 4.0])}


def random_states(name: str, n: int, seed: int, max_cond: float = 50.0):
    """n random (q, qd, qdd) rows: poses uniform within TRAJ_SCALE of home (kept only inside the
    stroke and with cond(J) < max_cond), rates and accelerations uniform within RATE_SCALE and
    ACC_SCALE. Returns three (n, 6) arrays."""
    from stewart_fmu import inverse_kinematics

    rng = np.random.default_rng(seed)
    model = level_model(name, "full")
    rows = []
    while len(rows) < n:
        q = model.home + TRAJ_SCALE[name] * rng.uniform(-1.0, 1.0, 6)
        kin = inverse_kinematics(model, q)
        if (np.all((kin.lengths > model.leg_min) & (kin.lengths < model.leg_max))
                and kin.cond < max_cond):
            rows.append((q, RATE_SCALE[name] * rng.uniform(-1.0, 1.0, 6),
                         ACC_SCALE[name] * rng.uniform(-1.0, 1.0, 6)))
    q, qd, qdd = (np.array(c) for c in zip(*rows))
    return q, qd, qdd


# --- independent numpy geometry (the contract's conventions, not the plant's code) ------------

def rotation(th) -> np.ndarray:
    """R = Rz(thz) @ Ry(thy) @ Rx(thx) for th = (thx, thy, thz)."""
    cx, sx = np.cos(th[0]), np.sin(th[0])
    cy, sy = np.cos(th[1]), np.sin(th[1])
    cz, sz = np.cos(th[2]), np.sin(th[2])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


def rate_matrix(th) -> np.ndarray:
    """E(theta): omega = E thetadot; columns Rz Ry e_x, Rz e_y, e_z."""
    cy, sy, cz, sz = np.cos(th[1]), np.sin(th[1]), np.cos(th[2]), np.sin(th[2])
    return np.array([[cz * cy, -sz, 0.0], [sz * cy, cz, 0.0], [-sy, 0.0, 1.0]])


def rate_matrix_dot(th, thd) -> np.ndarray:
    """dE/dt along thetadot (analytic)."""
    cy, sy, cz, sz = np.cos(th[1]), np.sin(th[1]), np.cos(th[2]), np.sin(th[2])
    dy, dz = thd[1], thd[2]
    return np.array([[-sz * dz * cy - cz * sy * dy, -cz * dz, 0.0],
                     [cz * dz * cy - sz * sy * dy, -sz * dz, 0.0],
                     [-cy * dy, 0.0, 0.0]])


def leg_geometry(data: dict, q):
    """Independent leg geometry of pose q from a scene dict: r_i = R p_i, L_i, l_i, u_i and the
    Jacobian J (rows [u_i, r_i x u_i], ldot = J (v, omega))."""
    a = np.asarray(data["geometry"]["base_joints"], dtype=float)
    p = np.asarray(data["geometry"]["platform_joints"], dtype=float)
    r = p @ rotation(q[3:]).T
    L = q[:3] + r - a
    l = np.linalg.norm(L, axis=1)
    u = L / l[:, None]
    return r, L, l, u, np.hstack([u, np.cross(r, u)])


# --- residual log: every physics test records its worst residual and tolerance ----------------
# Run with STEWART_RESIDUALS=1 to print the table at the end of the session.
RESIDUALS: dict[str, tuple[float, float]] = {}


def setting(path: str, value):
    """A mutation that sets the dotted key `path` of the scene dict to `value`."""
    def apply(d):
        *tables, key = path.split(".")
        node = d
        for t in tables:
            node = node[t]
        node[key] = value
    return apply


def deleting(path: str):
    """A mutation that removes the dotted key (or table) `path`."""
    def apply(d):
        *tables, key = path.split(".")
        node = d
        for t in tables:
            node = node[t]
        del node[key]
    return apply


def record(name: str, worst: float, tol: float) -> None:
    """Keep the worst residual of check `name` (and its tolerance) for the session summary."""
    prev = RESIDUALS.get(name, (0.0, tol))[0]
    RESIDUALS[name] = (max(prev, float(worst)), tol)


def smooth_step(t: np.ndarray, t0: float, width: float) -> np.ndarray:
    """0 before t0, 1 after t0 + width, C^2 in between (the project's one quintic)."""
    return quintic_step(t, t0, width)[0]


def vehicle_motion(t: np.ndarray, f_dev=None, w=None, g: float = 9.81):
    """A VehicleMotion from the specific force's deviation from rest and the angular velocity."""
    f = np.zeros((t.size, 3)) if f_dev is None else np.array(f_dev, dtype=float)
    f[:, 2] += g
    return VehicleMotion(t, f, np.zeros((t.size, 3)) if w is None else np.asarray(w, float))


# Relative: two independent roundings of one quantity (the C core's and numpy's) differ by far
# less, so a sample this close to a limit may fall on either side of it on another machine.
ROUNDING_BAND = 1e-9


def runs_mask(runs, n: int) -> np.ndarray:
    """The samples (n,) covered by (first sample, length) runs."""
    mask = np.zeros(n, dtype=bool)
    for first, length in runs:
        mask[first:first + length] = True
    return mask


def agrees_at_limit(flagged: np.ndarray, values: np.ndarray, limit: float,
                    above: bool = True) -> bool:
    """Whether `flagged` (the samples the code under test found past `limit`) is exactly the
    samples whose `values` (the test's own computation) lie past it, above or below, on every
    sample farther than ROUNDING_BAND from the limit; those within it may go either way."""
    past = values > limit if above else values < limit
    far = np.abs(values - limit) > ROUNDING_BAND * abs(limit)
    return bool(np.array_equal(flagged[far], past[far]))


def near_peak(values: np.ndarray) -> set[tuple[int, ...]]:
    """The indices of |values| within ROUNDING_BAND of its largest: a symmetric motion has
    twins there, and either may be the peak after another rounding."""
    a = np.abs(values)
    return {tuple(int(i) for i in k) for k in np.argwhere(a >= a.max() * (1 - ROUNDING_BAND))}


@contextmanager
def host_binary_only():
    """export_fmu builds the host's binary only, as on a machine without mingw-w64 (one line on
    stderr says so): for the tests that import an FMU here and never look at its Windows DLL,
    whose cross-compilation is over half of an export's CPU time. The DLL is tested in
    tests/stewart_fmu/test_windows_fmu.py."""
    import pytest

    from stewart_fmu.fmu import windows

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(windows, "MINGW_CC", "no-mingw-in-this-test")
        yield


_FMI2_LOGGERS: list = []   # every logger handed to fmpy's proxy stays alive (see below)


def fmi2_logging_callbacks(log):
    """FMI 2.0 callbacks whose logger calls log(status, category, message) (str category and
    message). fmpy's logger proxy (addLoggerProxy) keeps one Python logger in a process-global
    of its native library, and the last one installed there receives the messages of every FMU
    of the process that logs after it, those on fmpy's default callbacks too: a test that reads
    an FMU's messages installs its own, and none is ever freed (a freed one crashed a later
    FMU's first message)."""
    import ctypes

    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy

    def logger(_env, _instance, status, category, message):
        log(status, (category or b"").decode(), message.decode())

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(logger)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(ctypes.byref(cb))
    _FMI2_LOGGERS.append((logger, cb))
    return cb


def doc_pages() -> dict[str, str]:
    """The documentation's Markdown pages (docs/, not the built site): the path from docs/ (as
    "guides/closed-loop.md") -> the page's text."""
    return {p.relative_to(DOCS_DIR).as_posix(): p.read_text(encoding="utf-8")
            for p in sorted(DOCS_DIR.rglob("*.md")) if "_build" not in p.parts}


def doc_page_with(text: str) -> tuple[str, str]:
    """The one documentation page that holds `text`: (its path from docs/, its text). A test that
    checks a figure or a word the documentation states finds the page here, wherever the text
    moves; no page, or two, is a failure that names the text."""
    found = [(name, page) for name, page in doc_pages().items() if text in page]
    assert len(found) == 1, (f"{len(found)} pages of docs/ hold {text[:80]!r}: "
                             f"{[name for name, _ in found]}")
    return found[0]
