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
    """(N, 3, 3) Rz(thz) Ry(thy) Rx(thx) as products of the three elementary rotations."""
    n = len(th)
    c, s = np.cos(th), np.sin(th)
    one, zero = np.ones(n), np.zeros(n)
    rx = np.stack([one, zero, zero, zero, c[:, 0], -s[:, 0], zero, s[:, 0], c[:, 0]], 1)
    ry = np.stack([c[:, 1], zero, s[:, 1], zero, one, zero, -s[:, 1], zero, c[:, 1]], 1)
    rz = np.stack([c[:, 2], -s[:, 2], zero, s[:, 2], c[:, 2], zero, zero, zero, one], 1)
    return rz.reshape(n, 3, 3) @ ry.reshape(n, 3, 3) @ rx.reshape(n, 3, 3)


def legs(base, top, q):
    """Platform joints in N (N, 6, 3), leg vectors (N, 6, 3), R (N, 3, 3)."""
    R = rotation(q[:, 3:])
    P = q[:, None, :3] + np.einsum("nij,kj->nki", R, top)
    return P, P - base[None], R


def point_segment(p, a, b):
    """Distances (N,) of points p to segments a-b (N, 3): the projection clamped."""
    d = b - a
    t = np.clip(np.sum((p - a) * d, -1) / np.sum(d * d, -1), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * d), axis=-1)


def segment_distance(a1, b1, a2, b2) -> np.ndarray:
    """Distances (N,) between segments a1-b1 and a2-b2 (N, 3): the least of the four
    end-to-segment distances and the lines' interior critical point where both parameters
    fall in [0, 1] (Cramer's rule on the 2 x 2 normal equations)."""
    d1, d2, r = b1 - a1, b2 - a2, a1 - a2
    a, b, e = np.sum(d1 * d1, -1), np.sum(d1 * d2, -1), np.sum(d2 * d2, -1)
    c, f = np.sum(d1 * r, -1), np.sum(d2 * r, -1)
    best = np.minimum(np.minimum(point_segment(a1, a2, b2), point_segment(b1, a2, b2)),
                      np.minimum(point_segment(a2, a1, b1), point_segment(b2, a1, b1)))
    det = a * e - b * b
    ok = det > 1e-14 * a * e
    safe = np.where(ok, det, 1.0)
    s, t = (b * f - c * e) / safe, (a * f - b * c) / safe
    ok &= (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    inner = np.linalg.norm((a1 + s[:, None] * d1) - (a2 + t[:, None] * d2), axis=-1)
    return np.where(ok, np.minimum(best, inner), best)


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
        return min(float(segment_distance(self.base[None, i], P[:, i], self.base[None, j],
                                          P[:, j])[0]) for i, j in combinations(range(6), 2))

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
        n = len(q)
        out["leg_clearance"] = np.min([
            segment_distance(np.broadcast_to(self.base[i], (n, 3)), P[:, i],
                             np.broadcast_to(self.base[j], (n, 3)), P[:, j])
            for i, j in combinations(range(6), 2)], axis=0) - 2.0 * self.radius
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


def test_map_volume_agrees_with_monte_carlo(tmp_path, capsys):
    """--map's volume of the micro-manipulator with cones (which keep the legs from folding
    below the base: one connected workspace) against a Monte Carlo estimate with the numpy
    limits: uniform positions in the box --map searched, at home's angles. The two differ by
    less than four standard deviations of the estimate plus the map's grid error (its change
    from a 6 mm to a 3 mm grid)."""
    scene_file, ref = with_limits(MICRO, tmp_path)
    volumes = {}
    for h in (0.006, 0.003):
        out = tmp_path / f"map{h}"
        assert cli.main(["workspace", str(scene_file), "--map", "--out", str(out),
                         "--resolution", str(h)]) == 0
        text = capsys.readouterr().out
        volumes[h] = float(re.search(r"frame: ([0-9.]+) litres", text).group(1)) * 1e-3
        assert (out / "slices.png").stat().st_size > 0 and (out / "tilt.png").stat().st_size > 0
        with (out / "map.csv").open(newline="") as fh:
            runs = np.array([[float(v) for v in row.values()] for row in csv.DictReader(fh)])
        assert np.all(runs[:, 3] > runs[:, 2])
        # the volume is printed to six digits
        assert abs(np.sum(runs[:, 3] - runs[:, 2]) * h * h - volumes[h]) <= 1e-5 * volumes[h]
    scene = tomllib_load(scene_file)
    g = scene["geometry"]
    base, top = np.array(g["base_joints"]), np.array(g["platform_joints"])
    lo = np.max(base - top - g["leg_max"], axis=0)    # at zero angles R = I
    hi = np.min(base - top + g["leg_max"], axis=0)
    rng = np.random.default_rng(11)
    n = 200_000
    q = np.zeros((n, 6))
    q[:, :3] = lo + rng.uniform(0, 1, (n, 3)) * (hi - lo)
    m = ref.margins(q)
    inside = np.all(np.array([m[k] >= 0 for k in m]), axis=0)
    box = float(np.prod(hi - lo))
    p = inside.mean()
    estimate, sd = p * box, box * math.sqrt(p * (1 - p) / n)
    grid = abs(volumes[0.003] - volumes[0.006])
    print(f"\nmap {volumes[0.003] * 1e3:.4f} l (6 mm: {volumes[0.006] * 1e3:.4f} l), Monte Carlo "
          f"{estimate * 1e3:.4f} +- {sd * 1e3:.4f} l")
    assert abs(volumes[0.003] - estimate) <= 4 * sd + grid


def test_map_tilts_end_at_their_limit(tmp_path, capsys):
    """--map's orientation workspace: each azimuth's largest tilt ends where the numpy margins
    change sign (the pose at the tilt inside, 2e-9 rad further outside the limit named)."""
    scene_file, ref = with_limits(MICRO, tmp_path)
    out = tmp_path / "map"
    assert cli.main(["workspace", str(scene_file), "--map", "--out", str(out),
                     "--resolution", "0.01"]) == 0
    home = np.array(tomllib_load(scene_file)["geometry"]["home"], dtype=float)
    with (out / "tilt.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 72
    for r in rows:
        phi, tilt = float(r["azimuth"]), float(r["tilt"])
        d = np.array([0, 0, 0, math.cos(phi), math.sin(phi), 0.0])
        inside = ref.margins((home + tilt * d)[None])
        beyond = ref.margins((home + (tilt + 2e-9) * d)[None])
        assert min(float(v[0]) for v in inside.values()) >= -1e-12, r
        assert float(beyond[r["limit"]][0]) < 1e-12, r


def test_check_with_rates_bounds_the_drives(tmp_path, capsys):
    """Poses with their rates and accelerations (the trajectory's columns): the micro-
    manipulator's drives bound leg speed (no-load speed), acceleration (peak force over the
    constant load) and rack force (Kf I_max), each margin the least over the legs of the
    kinematics' leg rates and the inverse dynamics' forces."""
    from controller.drive import axis_model
    from stewart_fmu import inverse_dynamics, inverse_kinematics
    from stewart_sim.scene.load import load

    scene = load(MICRO)
    model = scene.model
    axis = axis_model(model, scene.controller.motor, scene.controller.load_mass)
    rng = np.random.default_rng(12)
    n = 200
    q = model.home + rng.uniform(-1, 1, (n, 6)) * [0.01, 0.01, 0.01, 0.05, 0.05, 0.05]
    qd, qdd = rng.normal(0, 0.1, (n, 6)), rng.normal(0, 3.0, (n, 6))
    poses = tmp_path / "poses.csv"
    names = POSE + [f"d{c}" for c in POSE] + [f"dd{c}" for c in POSE]
    with poses.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        w.writerows(np.hstack([q, qd, qdd]).tolist())
    out = tmp_path / "V.csv"
    assert cli.main(["workspace", str(MICRO), "--check", str(poses), "--out", str(out)]) == 0
    header, rows = read_v(out)
    assert header[-4:] == ["speed", "acceleration", "force", "where"]
    kin = inverse_kinematics(model, q, qd, qdd, with_cond=False)
    sigma = inverse_dynamics(model, q, qd, qdd)
    speed = axis.no_load_speed - np.max(np.abs(kin.rates), axis=1)
    accel = axis.peak_acceleration - np.max(np.abs(kin.accelerations), axis=1)
    force = axis.peak_force - np.max(np.abs(sigma), axis=1)
    got = np.array([[float(r["speed"]), float(r["acceleration"]), float(r["force"])] for r in rows])
    assert np.allclose(got, np.c_[speed, accel, force], rtol=0, atol=1e-9)
    limits = {r["limit"] for r in rows}
    assert {"speed", "acceleration"} & limits, limits


def test_check_in_a_frame_is_the_check_of_the_converted_poses(tmp_path):
    """Poses given in the user frame (tool frame seen from a tilted user frame): V.csv repeats
    them as given, and its margins are those of the same poses converted to C's by numpy
    (T_C = T_user T_f T_tool^-1) and checked in the platform frame."""
    user, tool = [0.1, -0.05, 0.02, 0.05, -0.1, 0.3], [0.01, 0.0, 0.03, 0.2, 0.0, -0.1]
    scene_file = tmp_path / "framed.toml"
    scene_file.write_text(MICRO.read_text() + f"\n[frames]\nuser = {user}\ntool = {tool}\n"
                          "default = \"user\"\n")
    rng = np.random.default_rng(13)
    home = np.array(tomllib_load(MICRO)["geometry"]["home"], dtype=float)
    q = home + rng.uniform(-1, 1, (300, 6)) * [0.02, 0.02, 0.02, 0.2, 0.2, 0.2]
    Ru, Rt = rotation(np.array([user[3:]]))[0], rotation(np.array([tool[3:]]))[0]
    R = rotation(q[:, 3:])
    pos = np.einsum("ji,nj->ni", Ru, q[:, :3] + np.einsum("nij,j->ni", R, tool[:3]) - user[:3])
    Rf = np.einsum("ji,njk,kl->nil", Ru, R, Rt)
    ang = np.c_[np.arctan2(Rf[:, 2, 1], Rf[:, 2, 2]),
                np.arctan2(-Rf[:, 2, 0], np.hypot(Rf[:, 0, 0], Rf[:, 1, 0])),
                np.arctan2(Rf[:, 1, 0], Rf[:, 0, 0])]
    framed = np.c_[pos, ang]
    write_poses(tmp_path / "framed.csv", framed)
    write_poses(tmp_path / "plain.csv", q)
    assert cli.main(["workspace", str(scene_file), "--check", str(tmp_path / "framed.csv"),
                     "--out", str(tmp_path / "V1.csv")]) == 0          # the scene's default
    assert cli.main(["workspace", str(scene_file), "--check", str(tmp_path / "plain.csv"),
                     "--out", str(tmp_path / "V2.csv"), "--frame", "platform"]) == 0
    _, a = read_v(tmp_path / "V1.csv")
    _, b = read_v(tmp_path / "V2.csv")
    assert [[float(r[c]) for c in POSE] for r in a] == framed.tolist()
    for ra, rb in zip(a, b):
        assert ra["limit"] == rb["limit"]
        for name in ("stroke_min", "stroke_max"):
            assert abs(float(ra[name]) - float(rb[name])) <= 1e-12


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
                                    "shape = \"box\"\nbody = \"platform\"\n"
                                    "center = [0.0, 0.0, 0.1]\n"),
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


@pytest.mark.parametrize("name, label", [("micro_manipulator", "micro-manipulator, "),
                                         ("motion_simulator", "motion simulator, ")])
def test_readme_ranges_are_what_the_command_prints(name, label, capsys):
    """The README's datasheet tables (beside each machine's volume) are `--ranges`' own lines."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme[readme.index(label):]
    block = block[block.index("```text\n") + len("```text\n"):]
    stated = block[:block.index("```")].splitlines()
    assert cli.main(["workspace", str(ROOT / "scenes" / f"{name}.toml"), "--ranges"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert len(stated) == 7 and stated == printed[1:8]
