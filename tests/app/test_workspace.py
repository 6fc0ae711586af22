"""`stewart-sim workspace`: its answers against an independent numpy implementation of the
limits (written here, from the contract's definitions, importing nothing of the engine), and
its refusals of bad input.

The numpy side: legs from R = Rz Ry Rx, each joint cone as arccos of the unit vectors' dot
product, the legs' segment distance as the least of the interior critical point of the two
lines (when both parameters fall inside) and the four end-to-segment distances, cond(J) by
numpy's SVD. The engine (native/src/reach.c) uses atan2 angles and Ericson's clamped closest
points, and its own Jacobian rows.
"""
from __future__ import annotations

import csv
import math
import re
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

from stewart_sim import cli

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted([*ROOT.glob("scenes/*.toml"), *ROOT.glob("scenes/machines/*.toml"),
                 *ROOT.glob("scenes/extreme/*.toml"), *ROOT.glob("scenes/stiff/*.toml")])
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
POSE = ["x", "y", "z", "thx", "thy", "thz"]
ORDER = ["stroke_min", "stroke_max", "base_cone", "platform_cone", "leg_clearance", "cond"]
NEAR = 1e-9          # poses with a margin this close to zero are ambiguous: not compared
AGREE = 1e-9         # margins of the two implementations agree to this (m, rad, cond)
CONE = 0.6           # rad (34 deg) in the copies of the scenes
RADIUS_SHARE = 0.9   # 2 x leg radius: this share of the least distance between two legs at home
COND_LIMIT = 100.0   # the engine's default (the device's SP_COND_MAX)
N_POSES = 3000
EPS = np.finfo(float).eps


def tolerance(name: str, margin: float) -> float:
    """AGREE for lengths and angles; cond(J) is known to ~eps cond^2 (the least singular value
    to eps times the largest), so its margin to AGREE plus 4 eps cond^2."""
    if name != "cond":
        return AGREE
    cond = COND_LIMIT - margin
    return AGREE + 4.0 * EPS * cond * cond


# --- the independent implementation ---------------------------------------------------------

def rotation(th: np.ndarray) -> np.ndarray:
    """(N, 3, 3) Rz(thz) Ry(thy) Rx(thx) as matrix products."""
    n = len(th)
    out = np.empty((n, 3, 3))
    for k in range(n):
        cx, sx = math.cos(th[k, 0]), math.sin(th[k, 0])
        cy, sy = math.cos(th[k, 1]), math.sin(th[k, 1])
        cz, sz = math.cos(th[k, 2]), math.sin(th[k, 2])
        rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        out[k] = rz @ ry @ rx
    return out


def legs(base, top, q):
    """Platform joints in N (N, 6, 3), leg vectors (N, 6, 3), R (N, 3, 3)."""
    R = rotation(q[:, 3:])
    P = q[:, None, :3] + np.einsum("nij,kj->nki", R, top)
    return P, P - base[None], R


def point_segment(p, a, b):
    d = b - a
    t = np.clip(np.dot(p - a, d) / np.dot(d, d), 0.0, 1.0)
    return np.linalg.norm(p - (a + t * d))


def segment_distance(a1, b1, a2, b2) -> float:
    """The least of the interior critical point (both parameters in [0, 1]) and the four
    end-to-segment distances."""
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    m = np.array([[d1 @ d1, -(d1 @ d2)], [-(d1 @ d2), d2 @ d2]])
    cands = [point_segment(a1, a2, b2), point_segment(b1, a2, b2),
             point_segment(a2, a1, b1), point_segment(b2, a1, b1)]
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    if det > 1e-14 * m[0, 0] * m[1, 1]:
        s, t = np.linalg.solve(m, [-(d1 @ r), d2 @ r])
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            cands.append(np.linalg.norm((a1 + s * d1) - (a2 + t * d2)))
    return float(min(cands))


def cone_angle(u, axis) -> np.ndarray:
    un = u / np.linalg.norm(u, axis=-1, keepdims=True)
    an = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    return np.arccos(np.clip(np.sum(un * an, axis=-1), -1.0, 1.0))


class Reference:
    """The limits of one scene (its geometry, stroke, cones and leg radius) in numpy."""

    def __init__(self, scene: dict, cone: float, radius: float | None):
        g = scene["geometry"]
        self.base, self.top = np.array(g["base_joints"]), np.array(g["platform_joints"])
        self.leg_min, self.leg_max = g.get("leg_min"), g.get("leg_max")
        self.cone, self.radius = cone, radius
        home = np.array(g["home"], dtype=float)[None]
        _, L, R = legs(self.base, self.top, home)
        self.base_axes = L[0]                      # leg i's direction at home, in N
        self.top_axes = (R[0].T @ L[0].T).T        # and in C
        self.scale = np.mean(np.linalg.norm(self.top, axis=1))

    def home_distance(self, home) -> float:
        P, _, _ = legs(self.base, self.top, np.array(home, dtype=float)[None])
        return min(segment_distance(self.base[i], P[0, i], self.base[j], P[0, j])
                   for i, j in combinations(range(6), 2))

    def margins(self, q: np.ndarray) -> dict[str, np.ndarray]:
        P, L, R = legs(self.base, self.top, q)
        l = np.linalg.norm(L, axis=2)
        out = {}
        if self.leg_min is not None:
            out["stroke_min"] = np.min(l - self.leg_min, axis=1)
        if self.leg_max is not None:
            out["stroke_max"] = np.min(self.leg_max - l, axis=1)
        out["base_cone"] = np.min(self.cone - cone_angle(L, self.base_axes[None]), axis=1)
        u_c = np.einsum("nji,nkj->nki", R, L)     # R^T L_i: the leg in C
        out["platform_cone"] = np.min(self.cone - cone_angle(u_c, self.top_axes[None]), axis=1)
        out["leg_clearance"] = np.array([
            min(segment_distance(self.base[i], P[n, i], self.base[j], P[n, j])
                for i, j in combinations(range(6), 2)) - 2.0 * self.radius
            for n in range(len(q))])
        u = L / l[..., None]
        r = P - q[:, None, :3]
        J = np.concatenate([u, np.cross(r, u) / self.scale], axis=2)
        out["cond"] = COND_LIMIT - np.linalg.cond(J)
        return out


# --- the scenes with cones and clearance -------------------------------------------------------

def tomllib_load(path: Path) -> dict:
    import tomllib
    return tomllib.loads(path.read_text())


def with_limits(path: Path, tmp: Path) -> tuple[Path, Reference]:
    """A copy of a shipped scene with [joints] (cones of CONE) and [clearance] (a leg radius of
    RADIUS_SHARE of the legs' least distance at home) added."""
    scene = tomllib_load(path)
    ref = Reference(scene, CONE, None)
    radius = RADIUS_SHARE * ref.home_distance(scene["geometry"]["home"]) / 2.0
    ref.radius = radius
    text = path.read_text() + (f"\n[joints]\nbase_cone = {CONE!r}\nplatform_cone = {CONE!r}\n"
                               f"\n[clearance]\nleg_radius = {radius!r}\n")
    out = tmp / f"{path.stem}.toml"
    out.write_text(text)
    return out, ref


def random_poses(scene: dict, n: int, seed: int) -> np.ndarray:
    """Poses about home: positions within a third of the stroke, tilts within 0.3 rad, the
    twist thz within 1.2 rad (which brings legs together)."""
    g = scene["geometry"]
    span = (g["leg_max"] - g["leg_min"]) if "leg_max" in g else 0.5
    rng = np.random.default_rng(seed)
    half = np.array([span / 3] * 3 + [0.3, 0.3, 1.2])
    return np.array(g["home"]) + rng.uniform(-1.0, 1.0, (n, 6)) * half


def write_poses(path: Path, q: np.ndarray) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(POSE)
        w.writerows([[repr(float(v)) for v in row] for row in q])


def read_v(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
        fh.seek(0)
        header = next(csv.reader(fh))
    return header, rows


@pytest.mark.parametrize("scene_path", SCENES, ids=lambda p: p.stem)
def test_check_agrees_with_numpy(scene_path, tmp_path, capsys):
    """On random poses of every shipped scene (with cones and clearance added), `workspace
    --check` agrees with the numpy implementation on feasibility, the binding limit and every
    margin (to 1e-9) of every pose whose margins are not within 1e-9 of zero."""
    scene_file, ref = with_limits(scene_path, tmp_path)
    scene = tomllib_load(scene_file)
    q = random_poses(scene, N_POSES, seed=len(scene_path.stem))
    poses, out = tmp_path / "poses.csv", tmp_path / "V.csv"
    write_poses(poses, q)
    assert cli.main(["workspace", str(scene_file), "--check", str(poses), "--out", str(out)]) == 0
    header, rows = read_v(out)
    expected = ref.margins(q)
    names = [n for n in ORDER if n in expected]
    assert header == POSE + ["feasible", "limit"] + names + ["where"]
    compared = 0
    for k, row in enumerate(rows):
        m = {name: float(expected[name][k]) for name in names}
        if any(abs(v) <= NEAR for v in m.values()):
            continue
        compared += 1
        assert [float(row[c]) for c in POSE] == q[k].tolist()
        violated = [name for name in names if m[name] < 0.0]
        assert row["feasible"] == ("0" if violated else "1"), (k, m, row)
        assert row["limit"] == (violated[0] if violated else ""), (k, m, row)
        for name in names:
            assert abs(float(row[name]) - m[name]) <= tolerance(name, m[name]), \
                (k, name, m[name], row[name])
    assert compared >= N_POSES - 5
    # the poses exercise the limits: each geometric limit is crossed on some of them
    crossed = {name: int(np.sum(expected[name] < 0.0)) for name in names}
    for name in ("stroke_max", "base_cone", "platform_cone", "leg_clearance"):
        assert crossed[name] > 0, crossed
    print(f"\n{scene_path.stem}: {compared} of {N_POSES} poses compared; binding: "
          + ", ".join(f"{n} {sum(r['limit'] == n for r in rows)}" for n in names)
          + f", feasible {sum(r['feasible'] == '1' for r in rows)}; crossed: "
          + ", ".join(f"{n} {c}" for n, c in crossed.items()))


# --- travel and ranges -------------------------------------------------------------------------

def test_ranges_end_at_the_limit_they_name(tmp_path, capsys):
    """Each --ranges travel of the micro-manipulator (cones, clearance) ends where the numpy
    margins say: the pose at the travel is inside every limit, the pose 1e-9 beyond it outside
    the limit named."""
    scene_file, ref = with_limits(MICRO, tmp_path)
    out = tmp_path / "ranges.csv"
    assert cli.main(["workspace", str(scene_file), "--ranges", "--out", str(out)]) == 0
    home = np.array(tomllib_load(scene_file)["geometry"]["home"], dtype=float)
    with out.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["axis"] for r in rows] == POSE
    for k, r in enumerate(rows):
        for side in ("minus", "plus"):
            step, limit = float(r[side]), r[f"{side}_limit"]
            assert limit in ORDER, r
            inside, beyond = home.copy(), home.copy()
            inside[k] += step
            beyond[k] += step + math.copysign(2e-9, step)
            m_in, m_out = ref.margins(inside[None]), ref.margins(beyond[None])
            assert min(float(v[0]) for v in m_in.values()) >= -1e-12, (r, side, m_in)
            assert float(m_out[limit][0]) < 1e-12, (r, side, m_out)


def test_reach_prints_the_step_and_the_limit(tmp_path, capsys):
    scene_file, _ = with_limits(MICRO, tmp_path)
    assert cli.main(["workspace", str(scene_file), "--reach", "--direction", "0,0,1,0,0,0"]) == 0
    out = capsys.readouterr().out
    m = re.search(r"largest step ([0-9.e-]+) .* stopped by (\w+) at leg (\d)", out)
    assert m, out
    assert 0.0 < float(m.group(1)) < 0.19


# --- bad input: one line naming the key, exit 2 -----------------------------------------------

BAD_SCENES = {
    "joints.base_cone": "[joints]\nbase_cone = 0.0\nplatform_cone = 0.3\n",
    "joints.platform_cone": "[joints]\nbase_cone = 0.3\nplatform_cone = 1.5708\n",
    "clearance.leg_radius": "[clearance]\nleg_radius = -0.001\n",
    "frames.pivot": "[frames]\npivot = [0.0, 0.0, 10.5]\n",
    "frames.default": "[frames]\ndefault = \"wrist\"\n",
    "clearance.obstacles[0]": ("[clearance]\nleg_radius = 0.002\n[[clearance.obstacles]]\n"
                               "shape = \"sphere\"\nbody = \"base\"\ncenter = [0.098, 0.0, 0.0]\n"
                               "radius = 0.02\n"),
    "clearance.obstacles[0].size": ("[clearance]\nleg_radius = 0.002\n[[clearance.obstacles]]\n"
                                    "shape = \"box\"\nbody = \"platform\"\ncenter = [0.0, 0.0, 0.1]\n"),
    "joints.base_axes": ("[joints]\nbase_cone = 0.3\nplatform_cone = 0.3\nbase_axes = "
                         "[[0,0,1],[0,0,1],[0,0,1],[0,0,1],[0,0,1],[0,0,0]]\n"),
}


@pytest.mark.parametrize("key", sorted(BAD_SCENES))
def test_bad_scene_is_one_line_naming_the_key(key, tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text(MICRO.read_text() + "\n" + BAD_SCENES[key])
    assert cli.main(["workspace", str(scene), "--ranges"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"'{key}'" in err, err


def test_home_outside_a_cone_is_refused_naming_the_limit(tmp_path, capsys):
    """Joint axes tilted 0.5 rad off the legs at home with cones of 0.3: the scene is refused."""
    scene = tmp_path / "tilted.toml"
    axes = "[" + ",".join(["[0.0, 0.0, 1.0]"] * 6) + "]"
    scene.write_text(MICRO.read_text() + f"\n[joints]\nbase_cone = 0.05\nplatform_cone = 0.3\n"
                     f"base_axes = {axes}\n")
    assert cli.main(["workspace", str(scene), "--ranges"]) == 2
    err = capsys.readouterr().err
    assert "'joints.base_cone'" in err and "violates the limit base_cone at leg" in err, err


def test_unknown_frame_and_missing_columns(tmp_path, capsys):
    assert cli.main(["workspace", str(MICRO), "--ranges", "--frame", "wrist"]) == 2
    assert "frame 'wrist': unknown frame" in capsys.readouterr().err
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,z,thx,thy\n0,0,0.12,0,0\n")
    out = tmp_path / "V.csv"
    assert cli.main(["workspace", str(MICRO), "--check", str(poses), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "missing ['thz']" in err, err
    assert not out.exists()
    poses.write_text("x,y,z,thx,thy,thz\n0,0,0.12,0,0,0\n0,0,nan,0,0,0\n")
    assert cli.main(["workspace", str(MICRO), "--check", str(poses), "--out", str(out)]) == 2
    assert "line 3, column 'z'" in capsys.readouterr().err
    assert not out.exists()
