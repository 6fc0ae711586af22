"""The engine's travel (stewart_reach_travel, conservative advancement) finds the first limit
along a line however narrow the region outside it: against a dense march of an independent
numpy implementation of the limits (stroke, both joint cones, leg clearance, sphere obstacles
on either body, cond(J) by numpy.linalg.cond; frames by numpy matrix products), bisected in
numpy where the march brackets the first violation."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stewart_fmu.reach import NAMES, Engine
from stewart_fmu.reach_params import COND_LIMIT
from stewart_fmu.scene import read_scene_dict, scene_from_dict
from tests.helpers import shipped_scenes

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
TOL = 1e-9
SAMPLES = 4001         # the dense march: poses along [0, reach] (steps of ~5e-4 rad or m)
# Where the engine and numpy disagree on a crossing through rounding alone: their margins
# differ by ~1e-15 of the margins' scale (cond: 1e-13 of 100); over slopes of 1e-2 per unit
# step or more, that is 1e-11 of the step
SLACK = 1e-11
PAIRS = np.array([(i, j) for i in range(6) for j in range(i + 1, 6)]).T
DEG30 = np.radians(30.0)
REPRO_FRAMES = {"user": [0.005, 0.0, 0.12, 0.0, 0.0, DEG30], "tool": [0.0, 0.0, 0.01, 0.0, 0.0,
                                                                      DEG30]}


def rot(th) -> np.ndarray:
    """R = Rz Ry Rx of angles (n, 3): (n, 3, 3)."""
    th = np.atleast_2d(th)
    cx, sx, cy, sy = np.cos(th[:, 0]), np.sin(th[:, 0]), np.cos(th[:, 1]), np.sin(th[:, 1])
    cz, sz, one, zero = np.cos(th[:, 2]), np.sin(th[:, 2]), np.ones(len(th)), np.zeros(len(th))
    rx = np.stack([one, zero, zero, zero, cx, -sx, zero, sx, cx], 1).reshape(-1, 3, 3)
    ry = np.stack([cy, zero, sy, zero, one, zero, -sy, zero, cy], 1).reshape(-1, 3, 3)
    rz = np.stack([cz, -sz, zero, sz, cz, zero, zero, zero, one], 1).reshape(-1, 3, 3)
    return rz @ ry @ rx


class NumpyLimits:
    """Every limit's least margin at poses (n, 6) in a frame, in LIMITS order up to cond
    (inf where not present), vectorised over the poses."""

    def __init__(self, model, data: dict, frame: str = "platform"):
        self.a, self.p = np.asarray(model.base_joints), np.asarray(model.platform_joints)
        self.lo = model.leg_min if model.leg_min is not None else -np.inf
        self.hi = model.leg_max if model.leg_max is not None else np.inf
        self.lc = model.characteristic_length
        joints, clearance = data.get("joints"), data.get("clearance")
        self.cones = None if joints is None else (joints["base_cone"], joints["platform_cone"])
        self.radius = None if clearance is None else clearance["leg_radius"]
        self.spheres = [] if clearance is None else clearance.get("obstacles", [])
        assert all(o["shape"] == "sphere" for o in self.spheres)
        frames = data.get("frames", {}) if frame == "user" else {}
        user, tool = (np.asarray(frames.get(k, np.zeros(6)), dtype=float) for k in ("user", "tool"))
        self.fix, self.rw, self.mov, self.rt = user[:3], rot(user[3:])[0], tool[:3], rot(tool[3:])[0]
        home = np.asarray(model.home, dtype=float)
        P, R = self._platform(home[None])
        u = (P - self.a)[0] / np.linalg.norm((P - self.a)[0], axis=1)[:, None]
        self.base_axes, self.top_axes = u, (R[0].T @ u.T).T   # the joints' axes: u_i at home

    def _platform(self, q):
        """The platform joints in N and R of platform poses (n, 6)."""
        R = rot(q[:, 3:])
        return q[:, None, :3] + np.einsum("nij,kj->nki", R, self.p), R

    def to_platform(self, f):
        """Platform poses of frame poses: R = R_w R(f) R_t^T, x = R_w f + fix - R mov."""
        R = self.rw @ rot(f[:, 3:]) @ self.rt.T
        x = f[:, :3] @ self.rw.T + self.fix - R @ self.mov
        th = np.stack([np.arctan2(R[:, 2, 1], R[:, 2, 2]), np.arcsin(np.clip(-R[:, 2, 0], -1, 1)),
                       np.arctan2(R[:, 1, 0], R[:, 0, 0])], 1)
        return np.concatenate([x, th], 1)

    def margins(self, f) -> np.ndarray:
        q = self.to_platform(np.atleast_2d(f))
        P, R = self._platform(q)
        L = P - self.a
        length = np.linalg.norm(L, axis=2)
        u = L / length[..., None]
        out = np.full((len(q), 7), np.inf)
        out[:, 0] = np.min(length - self.lo, axis=1)
        out[:, 1] = np.min(self.hi - length, axis=1)
        if self.cones is not None:
            cb = np.clip(np.sum(u * self.base_axes, -1), -1, 1)
            top = np.einsum("nij,kj->nki", R, self.top_axes)
            ct = np.clip(np.sum(u * top, -1), -1, 1)
            out[:, 2] = self.cones[0] - np.max(np.arccos(cb), 1)
            out[:, 3] = self.cones[1] - np.max(np.arccos(ct), 1)
        if self.radius is not None:
            out[:, 4] = np.min(self._pair_distance(L), axis=1) - 2 * self.radius
            for o in self.spheres:
                c = np.asarray(o["center"], dtype=float)
                cw = q[:, :3] + R @ c if o["body"] == "platform" else np.broadcast_to(c, q[:, :3].shape)
                d = self._point_segment(cw, L)
                out[:, 5] = np.minimum(out[:, 5], np.min(d, axis=1) - o["radius"] - self.radius)
        J = np.concatenate([u, np.cross(P - q[:, None, :3], u) / self.lc], axis=2)
        out[:, 6] = COND_LIMIT - np.linalg.cond(J)
        return out

    def _point_segment(self, c, L):
        """Distance of points c (n, 3) to each leg's segment a_i + s L_i, s in [0, 1]."""
        r = c[:, None, :] - self.a[None]
        s = np.clip(np.sum(r * L, -1) / np.sum(L * L, -1), 0, 1)
        return np.linalg.norm(r - s[..., None] * L, axis=-1)

    def _pair_distance(self, L):
        """Ericson's clamped closest points of the 15 leg pairs (n, 15)."""
        i, j = PAIRS
        d1, d2, r = L[:, i], L[:, j], self.a[i] - self.a[j]
        a, e = np.sum(d1 * d1, -1), np.sum(d2 * d2, -1)
        b, c, f = np.sum(d1 * d2, -1), np.sum(d1 * r, -1), np.sum(d2 * r[None], -1)
        den = a * e - b * b
        s = np.where(den > 0, np.clip((b * f - c * e) / np.where(den > 0, den, 1), 0, 1), 0)
        t = (b * s + f) / e
        s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
        t = np.clip(t, 0, 1)
        gap = (self.a[i] + d1 * s[..., None]) - (self.a[j] + d2 * t[..., None])
        return np.linalg.norm(gap, axis=-1)


def dense_first(ref: NumpyLimits, q0, d, reach):
    """The dense march's first violation: (last sample inside, first outside) or None, and
    numpy's bisection of that bracket to 1e-12 with the limit it finds there."""
    t = np.linspace(0.0, reach, SAMPLES)
    bad = np.any(ref.margins(q0 + t[:, None] * d) < 0, axis=1)
    if not bad.any():
        return None
    v = int(np.argmax(bad))
    assert v > 0, "the line starts outside"
    lo, hi = t[v - 1], t[v]
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        if np.any(ref.margins(q0 + mid * d) < 0):
            hi = mid
        else:
            lo = mid
    limit = NAMES[int(np.argmax(ref.margins(q0 + hi * d)[0] < 0))]
    return t[v - 1], t[v], lo, limit


def check_line(eng: Engine, ref: NumpyLimits, q0, d, frame: str, counts: dict) -> None:
    """The engine's step is never past the dense march's first outside sample; where the
    march brackets the first violation, the step is numpy's crossing to TOL; where the engine
    stops earlier it stepped into a band the march stepped over, outside by numpy too."""
    tr = eng.travel(q0, d, frame=frame)
    if not tr.inside:   # a scene whose home is outside (near_singular: cond(J))
        assert ref.margins(q0)[0, NAMES.index(tr.limit)] < 0
        counts["start outside"] += 1
        return
    dense = dense_first(ref, q0, d, tr.reach)
    if dense is None:
        assert tr.limit is None and tr.step == tr.reach
        counts["free"] += 1
        return
    before, after, crossing, limit = dense
    assert tr.limit is not None and tr.step <= after
    if tr.step >= before - SLACK:
        assert -SLACK <= crossing - tr.step <= TOL + SLACK, (tr, crossing)
        assert tr.limit == limit
        counts["bracketed"] += 1
    else:   # a band narrower than the march's step, before it
        near = ref.margins(q0 + (tr.step + np.linspace(0, TOL + SLACK, 101))[:, None] * d)
        assert np.any(near[:, NAMES.index(tr.limit)] < 0), tr
        counts["narrow band"] += 1


def scene_data(path: Path, **tables) -> dict:
    data = read_scene_dict(path)
    data.update(tables)
    return data


def test_repro_narrow_cond_band_is_found():
    """The micro-manipulator turning about x in a user frame 30 deg about z, 12 cm up, with a
    tool 1 cm above C: cond(J) passes its limit for ~1.4 deg from 0.9373 rad, and the legs
    reach stroke_max at 1.627 rad; the travel stops at cond(J), where numpy's dense march
    finds it, to 1e-9."""
    data = scene_data(MICRO, frames=REPRO_FRAMES)
    model = scene_from_dict(data, str(MICRO))
    eng, ref = Engine(model), NumpyLimits(model, data, "user")
    from stewart_fmu.frames import from_platform
    q0 = from_platform(model, np.asarray(model.home, dtype=float), "user")
    d = np.array([0, 0, 0, 1.0, 0, 0])
    tr = eng.travel(q0, d, frame="user")
    assert tr.limit == "cond" and abs(tr.step - 0.9373) < 1e-4
    counts = {"free": 0, "bracketed": 0, "narrow band": 0, "start outside": 0}
    check_line(eng, ref, q0, d, "user", counts)
    assert counts["bracketed"] == 1
    band = ref.margins(q0 + np.linspace(tr.step, tr.step + 0.03, 301)[:, None] * d)[:, 6]
    assert np.any(band < 0) and band[-1] > 0   # a band of cond(J) alone, left again


def _lines(seed: int, n: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        d = rng.normal(size=6) * [1, 1, 1, 5, 5, 5]
        yield d / np.linalg.norm(d)


@pytest.mark.parametrize("path", shipped_scenes(), ids=lambda p: p.stem)
def test_travel_never_passes_the_first_violation_on_shipped_scenes(path):
    """Random lines from home on each shipped scene (its stroke and cond(J)), and with joint
    cones of 0.5 rad and legs 3 mm thick added (the micro-manipulator's cones are reached; the
    larger machines' legs are thin for their size), in the platform's frame."""
    counts = {"free": 0, "bracketed": 0, "narrow band": 0, "start outside": 0}
    home_lc = scene_from_dict(scene_data(path), str(path))
    for k, extra in enumerate(({}, {"joints": {"base_cone": 0.5, "platform_cone": 0.5},
                                    "clearance": {"leg_radius": 0.003}})):
        data = scene_data(path, **extra)
        model = scene_from_dict(data, str(path)) if extra else home_lc
        eng, ref = Engine(model), NumpyLimits(model, data)
        for d in _lines(100 + k, 4):
            check_line(eng, ref, np.asarray(model.home, dtype=float), d, "platform", counts)
    print(path.stem, counts)
    assert counts["bracketed"] + counts["narrow band"] >= 1 or counts["start outside"] == 8


def test_travel_in_frames_with_obstacles_on_both_bodies():
    """The micro-manipulator with cones, clearance, a sphere on the base beside the legs and
    one on the platform below it, lines in the repro's user frame (a turned, raised frame and
    a tool off C): every limit reached somewhere, never passed."""
    spheres = [{"shape": "sphere", "body": "base", "center": [0.1, 0.02, 0.05], "radius": 0.008},
               {"shape": "sphere", "body": "platform", "center": [0.0, 0.03, -0.03],
                "radius": 0.01}]
    data = scene_data(MICRO, frames=REPRO_FRAMES,
                      joints={"base_cone": 0.45, "platform_cone": 0.45},
                      clearance={"leg_radius": 0.004, "obstacles": spheres})
    model = scene_from_dict(data, str(MICRO))
    eng = Engine(model)
    from stewart_fmu.frames import from_platform
    counts = {"free": 0, "bracketed": 0, "narrow band": 0, "start outside": 0}
    for frame in ("platform", "user"):
        ref = NumpyLimits(model, data, frame)
        q0 = from_platform(model, np.asarray(model.home, dtype=float), frame)
        for d in _lines(7, 12):
            check_line(eng, ref, q0, d, frame, counts)
    print(counts)
    assert counts["bracketed"] >= 12



def engine_dense_first(eng: Engine, q0, d, reach: float, samples: int):
    """The first violation of a dense march of Engine.check (exact margins) along [0, reach]
    bisected to 1e-12: (first outside sample, crossing) or None."""
    t = np.linspace(0.0, reach, samples)
    bad = ~eng.check(q0 + t[:, None] * d)["feasible"]
    if not bad.any():
        return None
    v = int(np.argmax(bad))
    lo, hi = t[v - 1], t[v]
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        if eng.check(q0 + mid * d)["feasible"][0]:
            lo = mid
        else:
            hi = mid
    return t[v], lo


def test_travel_with_boxes_and_cylinders_against_a_dense_march_of_the_engines_margins():
    """A box on the platform and a cylinder on the base about the legs (test_reach.py holds
    their margins, Engine.check's, against a scalar minimisation): along random lines from home
    the travel ends at the first violation of a dense march of Engine.check (every 1e-4 of the
    reach), bisected, to 1e-9, never past its first outside sample."""
    obstacles = [
        {"shape": "box", "body": "platform", "center": [0.0, 0.0, -0.02],
         "size": [0.09, 0.08, 0.02], "angles": [0.1, 0.2, 0.3]},
        {"shape": "cylinder", "body": "base", "center": [0.0, 0.0, 0.02], "radius": 0.05,
         "length": 0.04, "angles": [0.0, 0.3, 0.0]}]
    model = scene_from_dict(scene_data(MICRO, clearance={"leg_radius": 0.003,
                                                         "obstacles": obstacles}), str(MICRO))
    eng = Engine(model)
    home = np.asarray(model.home, dtype=float)
    hits = 0
    for d in _lines(11, 16):
        tr = eng.travel(home, d)
        dense = engine_dense_first(eng, home, d, tr.reach, 10001)
        if dense is None:
            assert tr.limit is None
            continue
        assert tr.step <= dense[0]
        assert -SLACK <= dense[1] - tr.step <= TOL + SLACK, (tr, dense)
        hits += tr.limit == "obstacle"
    print("obstacle ends", hits)
    assert hits >= 8


def test_a_small_box_a_leg_sweeps_through_is_not_stepped_over():
    """A 1 mm cube beside leg 1's middle, 2 to 8 mm on along x, legs 0.2 mm thick, the platform
    moving along x: the region outside is ~2.5 mm of travel, less than the steps' cap (the
    characteristic length / 16); the travel ends where a dense march (every 1e-6 m) of
    Engine.check first finds the leg in the box, to 1e-9."""
    base = scene_from_dict(scene_data(MICRO), str(MICRO))
    home = np.asarray(base.home, dtype=float)
    a = np.asarray(base.base_joints)[0]
    top = home[:3] + rot(home[3:])[0] @ np.asarray(base.platform_joints)[0]
    u = (top - a) / np.linalg.norm(top - a)
    side = np.array([1.0, 0.0, 0.0]) - u * u[0]
    side /= np.linalg.norm(side)
    d = np.array([1.0, 0, 0, 0, 0, 0])
    for off in np.linspace(0.002, 0.008, 13):
        cube = {"shape": "box", "body": "base", "center": (0.5 * (a + top) + off * side).tolist(),
                "size": [0.001, 0.001, 0.001]}
        model = scene_from_dict(scene_data(MICRO, clearance={"leg_radius": 0.0002,
                                                             "obstacles": [cube]}), str(MICRO))
        eng = Engine(model)
        tr = eng.travel(home, d)
        assert tr.limit == "obstacle" and tr.where == "[0] leg 1", (off, tr)
        first, crossing = engine_dense_first(eng, home, d, 0.02, 20001)
        assert tr.step <= first and -SLACK <= crossing - tr.step <= TOL + SLACK, (off, tr)
