"""The feasibility engine (stewart_fmu.reach, native/src/reach.c) and the frames (frames.c)
against independent computations: obstacles' distances by a bounded scalar minimisation of
numpy signed distances, leg rates and rack forces by the Python kinematics and dynamics, frames
by numpy matrix products; travel ends where the margins change sign."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from stewart_fmu import inverse_dynamics, inverse_kinematics
from stewart_fmu.errors import TrajectoryError
from stewart_fmu.frames import from_platform, to_platform
from stewart_fmu.reach import NAMES, DriveBounds, Engine, axis_ranges
from stewart_fmu.reach_params import ClearanceParams, Obstacle
from stewart_fmu.scene import read_scene_dict, scene_from_dict

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"
EPS = np.finfo(float).eps


def rot(th) -> np.ndarray:
    cx, sx = np.cos(th[0]), np.sin(th[0])
    cy, sy = np.cos(th[1]), np.sin(th[1])
    cz, sz = np.cos(th[2]), np.sin(th[2])
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
            @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


def micro(**tables):
    data = read_scene_dict(MICRO)
    data.update(tables)
    return scene_from_dict(data, str(MICRO))


def random_poses(model, n, seed, tilt=0.25):
    rng = np.random.default_rng(seed)
    return model.home + rng.uniform(-1, 1, (n, 6)) * [0.02, 0.02, 0.02, tilt, tilt, tilt]


# --- frames ----------------------------------------------------------------------------------

FRAMES = {"pivot": [0.01, -0.02, 0.05], "user": [0.1, -0.2, 0.3, 0.1, -0.2, 0.3],
          "tool": [0.02, 0.01, 0.04, -0.3, 0.2, 0.1], "default": "tool"}


@pytest.mark.parametrize("frame", ["platform", "pivot", "tool", "user"])
def test_frames_round_trip(frame):
    """q -> frame -> q within 1e-15 of the pose's scale (its and the frames' largest
    coordinate) for the positions, 1e-15 rad for the angles (|angles| < pi/2)."""
    model = micro(frames=FRAMES)
    q = random_poses(model, 2000, 3, tilt=1.0)
    back = to_platform(model, from_platform(model, q, frame), frame)
    scale = max(np.max(np.abs(q[:, :3])), 0.3)
    err_pos = np.max(np.abs(back[:, :3] - q[:, :3])) / scale
    err_ang = np.max(np.abs(back[:, 3:] - q[:, 3:]))
    print(f"{frame}: position {err_pos:.3g} relative, angles {err_ang:.3g} rad")
    assert err_pos <= 1e-15 and err_ang <= 1e-15


def test_frames_mean_what_they_say():
    """The tool frame's pose in the user frame is T_user^-1 T_C T_tool (numpy products); the
    pivot's is x + R pivot with C's angles, exactly."""
    model = micro(frames=FRAMES)
    q = random_poses(model, 50, 4)
    tool, user = np.array(FRAMES["tool"]), np.array(FRAMES["user"])
    f = from_platform(model, q, "user")
    piv = from_platform(model, q, "pivot")
    for k in range(len(q)):
        R = rot(q[k, 3:])
        Rm = R @ rot(tool[3:])
        Ru = rot(user[3:])
        pos = Ru.T @ (q[k, :3] + R @ tool[:3] - user[:3])
        assert np.allclose(f[k, :3], pos, rtol=0, atol=1e-15)
        assert np.allclose(rot(f[k, 3:]), Ru.T @ Rm, rtol=0, atol=4 * EPS)
        assert np.array_equal(piv[k, 3:], q[k, 3:])
        assert np.allclose(piv[k, :3], q[k, :3] + R @ np.array(FRAMES["pivot"]), rtol=0, atol=1e-16)


# --- obstacles ---------------------------------------------------------------------------------

def sdf(shape, x, h):
    if shape == "sphere":
        return np.linalg.norm(x) - h[0]
    if shape == "box":
        d = np.abs(x) - h
        return np.linalg.norm(np.maximum(d, 0)) + min(max(d), 0.0)
    d = np.array([np.hypot(x[0], x[1]) - h[0], abs(x[2]) - h[2]])
    return np.linalg.norm(np.maximum(d, 0)) + min(max(d), 0.0)


OBSTACLES = [
    {"shape": "box", "body": "platform", "center": [0.0, 0.0, 0.03], "size": [0.05, 0.04, 0.03],
     "angles": [0.1, 0.2, 0.3]},
    {"shape": "cylinder", "body": "base", "center": [0.0, 0.0, 0.02], "radius": 0.03,
     "length": 0.04, "angles": [0.0, 0.3, 0.0]},
    {"shape": "sphere", "body": "base", "center": [0.12, 0.05, 0.06], "radius": 0.01},
]


def reference_obstacle(model, o, q, leg_radius):
    """min over legs of the signed distance (bounded scalar minimisation along the leg) less
    the leg's radius."""
    R = rot(q[3:])
    Ro = rot(o.get("angles", [0, 0, 0]))
    c = np.array(o["center"])
    if o["body"] == "platform":
        cw, Rw = q[:3] + R @ c, R @ Ro
    else:
        cw, Rw = c, Ro
    h = {"box": np.array(o.get("size", [0, 0, 0])) / 2,
         "cylinder": np.array([o.get("radius", 0), o.get("radius", 0), o.get("length", 0) / 2]),
         "sphere": np.array([o.get("radius", 0)] * 3)}[o["shape"]]
    best = np.inf
    for i in range(6):
        a = Rw.T @ (model.base_joints[i] - cw)
        b = Rw.T @ (q[:3] + R @ model.platform_joints[i] - cw)
        f = lambda t: sdf(o["shape"], a + t * (b - a), h)   # noqa: E731
        res = minimize_scalar(f, bounds=(0.0, 1.0), method="bounded",
                              options={"xatol": 1e-12, "maxiter": 500})
        # fminbound stops within sqrt(eps) |t| of the minimum: a fine grid about it (1e-9 of
        # the leg apart) finishes the search at a kink of the signed distance
        grid = np.clip(res.x + np.linspace(-1e-7, 1e-7, 201), 0.0, 1.0)
        best = min(best, res.fun, f(0.0), f(1.0), min(f(t) for t in grid))
    return best - leg_radius


def test_obstacle_margins_agree_with_a_scalar_minimisation():
    """Boxes, cylinders and spheres on either body, placed about the legs (some poses put a
    leg inside, some keep it clear: the model is built past the scene's home check), one at a
    time: the engine's margin within 1e-9 m of the minimisation's."""
    base = micro()
    rng = np.random.default_rng(5)
    inside = outside = 0
    worst = 0.0
    for k in range(24):
        shape = ("box", "cylinder", "sphere")[k % 3]
        body = ("base", "platform")[(k // 3) % 2]
        leg = rng.integers(6)
        at = rng.uniform(0.2, 0.8)
        point = base.base_joints[leg] + at * (base.home[:3] + base.platform_joints[leg]
                                              - base.base_joints[leg])
        center = point + rng.uniform(-0.02, 0.02, 3)
        if body == "platform":
            center = center - base.home[:3]
        o = {"shape": shape, "body": body, "center": list(center),
             "angles": list(rng.uniform(-1, 1, 3)), "size": list(rng.uniform(0.005, 0.03, 3)),
             "radius": rng.uniform(0.004, 0.015), "length": rng.uniform(0.01, 0.04)}
        obstacle = Obstacle(shape, body, tuple(center), tuple(o["angles"]),
                            tuple(o["size"]) if shape == "box" else None,
                            o["radius"] if shape != "box" else None,
                            o["length"] if shape == "cylinder" else None)
        model = replace(base, clearance=ClearanceParams(0.002, (obstacle,)))
        q = random_poses(model, 25, k)
        res = Engine(model).check(q)
        ref = np.array([reference_obstacle(model, o, qk, 0.002) for qk in q])
        worst = max(worst, float(np.max(np.abs(res["obstacle"] - ref))))
        inside += int(np.sum(ref < 0))
        outside += int(np.sum(ref > 0))
    print(f"obstacle margins: {inside} poses touching, {outside} clear; largest difference "
          f"{worst:.3g} m")
    assert worst <= 1e-9
    assert inside > 50 and outside > 50


# --- drives ----------------------------------------------------------------------------------

def test_drive_margins_are_the_leg_rates_and_forces():
    """Speed and acceleration margins from the Python kinematics' leg rates, the force margin
    from the inverse dynamics (drive included), each the least over the legs."""
    model = micro()
    rng = np.random.default_rng(6)
    q = random_poses(model, 100, 6, tilt=0.1)
    qd, qdd = rng.normal(0, 0.1, (100, 6)), rng.normal(0, 2.0, (100, 6))
    bounds = DriveBounds(speed=0.3, acceleration=6.0, force=40.0)
    res = Engine(model, bounds).check(q, qd, qdd)
    kin = inverse_kinematics(model, q, qd, qdd, with_cond=False)
    sigma = inverse_dynamics(model, q, qd, qdd)
    assert np.allclose(res["speed"], 0.3 - np.max(np.abs(kin.rates), axis=1), rtol=0, atol=1e-12)
    assert np.allclose(res["acceleration"], 6.0 - np.max(np.abs(kin.accelerations), axis=1),
                       rtol=0, atol=1e-10)
    assert np.allclose(res["force"], 40.0 - np.max(np.abs(sigma), axis=1), rtol=0, atol=1e-9)
    assert np.array_equal(res["force_at"], np.argmax(np.abs(sigma), axis=1))
    binding = [NAMES[b] if b >= 0 else "" for b in res["binding"]]
    assert {"speed", "acceleration", "force"} & set(binding)


def test_without_rates_the_drives_are_absent():
    names = [lim.name for lim in Engine(micro(), DriveBounds(1.0, 1.0, 1.0)).present()]
    assert names == ["stroke_min", "stroke_max", "cond"]


def test_non_finite_pose_names_its_row():
    model = micro()
    q = np.tile(model.home, (3, 1))
    q[2, 4] = np.nan
    with pytest.raises(TrajectoryError, match="pose row 3"):
        Engine(model).check(q)


# --- travel ----------------------------------------------------------------------------------

def test_travel_ends_where_the_margins_change_sign():
    """Along random directions from home: the pose at the step is inside every limit, the pose
    2e-9 further is outside the limit named (the engine's own margins, at single poses)."""
    model = micro(joints={"base_cone": 0.5, "platform_cone": 0.5},
                  clearance={"leg_radius": 0.003, "obstacles": OBSTACLES[:1]})
    eng = Engine(model)
    rng = np.random.default_rng(7)
    for _ in range(40):
        d = rng.normal(size=6) * [1, 1, 1, 5, 5, 5]
        d /= np.linalg.norm(d)
        t = eng.travel(model.home, d)
        assert t.limit is not None and t.inside
        inside = eng.check(model.home + t.step * d)
        beyond = eng.check(model.home + (t.step + 2e-9) * d)
        assert inside["feasible"][0]
        assert not beyond["feasible"][0] and NAMES[beyond["binding"][0]] == t.limit


def test_ranges_of_a_symmetric_machine_are_symmetric():
    """The micro-manipulator is symmetric under y -> -y (the joints mirror about the x axis):
    its y, thx and thz ranges are too, to the bisection's 1e-9."""
    model = micro(joints={"base_cone": 0.5, "platform_cone": 0.5})
    rows = {r.axis: r for r in axis_ranges(Engine(model))}
    for axis in ("y", "thx", "thz"):
        assert abs(rows[axis].plus + rows[axis].minus) <= 2e-9, rows[axis]


def test_binding_alone_is_checks_binding():
    """Engine.binding (margins computed only where their sign is in doubt) names the same
    binding limit as Engine.check, on poses that cross every geometric limit and cond(J): a
    model with cones (first in order), one without where obstacles and cond(J) bind."""
    rng = np.random.default_rng(8)
    coned = micro(joints={"base_cone": 0.5, "platform_cone": 0.5},
                  clearance={"leg_radius": 0.003, "obstacles": OBSTACLES[:1]})
    box = Obstacle("box", "platform", (0.0, 0.0, -0.02), (0.0, 0.0, 0.3), (0.09, 0.09, 0.02))
    bare = replace(micro(), clearance=ClearanceParams(0.004, (box,) + coned.clearance.obstacles))
    seen = set()
    # the default cond limit (100): its bound ||J||_F ||J^-1||_F (at least 6) spares the SVD
    # on most poses; 3 (2.4 at home): cond(J) binds often, the bound never spares it
    for model, limit in ((coned, 100.0), (bare, 100.0), (micro(), 3.0)):
        q = model.home + rng.uniform(-1, 1, (20000, 6)) * [0.06, 0.06, 0.1, 0.6, 0.6, 1.2]
        eng = Engine(model, cond_limit=limit)
        full = eng.check(q)["binding"]
        assert np.array_equal(eng.binding(q), full)
        seen |= {NAMES[b] for b in set(full.tolist()) if b >= 0}
    assert seen == {"stroke_min", "stroke_max", "base_cone", "platform_cone", "leg_clearance",
                    "obstacle", "cond"}, seen


def test_verdict_of_one_pose_is_checks_row():
    model = micro(joints={"base_cone": 0.5, "platform_cone": 0.5},
                  clearance={"leg_radius": 0.003, "obstacles": OBSTACLES[:1]})
    eng = Engine(model)
    q = random_poses(model, 200, 9, tilt=0.5)
    res = eng.check(q)
    for k in range(len(q)):
        v = eng.verdict(q[k])
        b = int(res["binding"][k])
        assert v.limit == (NAMES[b] if b >= 0 else None)
        for lim in eng.present():
            assert v.margins[lim.index] == res[lim.name][k]
    with pytest.raises(TrajectoryError):
        eng.verdict(np.full(6, np.nan))
