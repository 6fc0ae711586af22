"""Motions in frames (stewart_fmu.frames.motion_to_platform / motion_from_platform,
native/src/frames.c) by physics: the round trip, finite differences of the converted poses
against the converted rates and accelerations, and the rigid body's point kinematics computed
independently in numpy."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_fmu.errors import StewartError
from stewart_fmu.frames import from_platform, motion_from_platform, motion_to_platform

from .test_reach import FRAMES, micro, rot

ALL = ["platform", "pivot", "tool", "user"]
W = np.array([1.3, 0.7, 2.1, 1.7, 0.9, 1.1])           # rad/s of each coordinate's sine
AMP = np.array([0.02, 0.015, 0.01, 0.6, 0.5, 0.7])       # m, rad


def path(model, t):
    """q, qd, qdd of a smooth motion about home (analytic derivatives), t (N,)."""
    s = np.sin(np.outer(t, W) + 0.3)
    c = np.cos(np.outer(t, W) + 0.3)
    return model.home + AMP * s, AMP * W * c, -AMP * W ** 2 * s


def euler_matrix(th) -> np.ndarray:
    """E with omega (in N) = E thd for R = Rz Ry Rx: columns Rz Ry e_x, Rz e_y, e_z."""
    cy, sy, cz, sz = np.cos(th[1]), np.sin(th[1]), np.cos(th[2]), np.sin(th[2])
    return np.array([[cy * cz, -sz, 0.0], [cy * sz, cz, 0.0], [-sy, 0.0, 1.0]])


def scale(*arrays) -> np.ndarray:
    """Each column's largest magnitude over the arrays (and the frames' coordinates, 0.3)."""
    return np.maximum(np.max(np.abs(np.concatenate(arrays)), axis=0), 1e-300)


@pytest.mark.parametrize("frame", ALL)
def test_motion_round_trip(frame):
    """platform -> frame -> platform: positions, angles and each one's rates and accelerations
    within 1e-15 relative to the largest value of that group in either frame (positions: at
    least 0.3 m, the frames' coordinates; random states, tilts up to 1 rad)."""
    model = micro(frames=FRAMES)
    rng = np.random.default_rng(11)
    n = 2000
    q = model.home + rng.uniform(-1, 1, (n, 6)) * [0.02, 0.02, 0.02, 1.0, 1.0, 1.0]
    qd = rng.uniform(-1, 1, (n, 6)) * [0.1, 0.1, 0.1, 2.0, 2.0, 2.0]
    qdd = rng.uniform(-1, 1, (n, 6)) * [1.0, 1.0, 1.0, 20.0, 20.0, 20.0]
    f = motion_from_platform(model, q, qd, qdd, frame)
    back = motion_to_platform(model, *f, frame)
    worst = 0.0
    for name, a, fa, b in zip(("q", "qd", "qdd"), (q, qd, qdd), f, back):
        for part, cols, floor in (("position", slice(0, 3), 0.3), ("angles", slice(3, 6), 0.0)):
            size = max(np.max(np.abs(a[:, cols])), np.max(np.abs(fa[:, cols])), floor)
            err = np.max(np.abs(b[:, cols] - a[:, cols])) / size
            worst = max(worst, err)
            print(f"{frame} {name} {part}: {err:.3g} relative")
    assert worst <= 1e-15
    # poses agree with the pose conversion to the bit
    assert np.array_equal(f.q, from_platform(model, q, frame))


@pytest.mark.parametrize("frame", ["tool", "user", "pivot"])
def test_motion_finite_differences(frame):
    """Central differences of the converted poses match the converted rates and (second
    differences) accelerations to second order: the error falls 4x when h halves."""
    model = micro(frames=FRAMES)
    t0 = np.linspace(0.0, 3.0, 31)
    f = motion_from_platform(model, *path(model, t0), frame)
    errs = []
    for h in (2e-3, 1e-3):
        fp = from_platform(model, path(model, t0 + h)[0], frame)
        fm = from_platform(model, path(model, t0 - h)[0], frame)
        d1 = np.max(np.abs((fp - fm) / (2 * h) - f.qd))
        d2 = np.max(np.abs((fp - 2 * f.q + fm) / h ** 2 - f.qdd))
        errs.append((d1, d2))
    (a1, a2), (b1, b2) = errs
    print(f"{frame}: rates {a1:.3g} -> {b1:.3g}, accelerations {a2:.3g} -> {b2:.3g}")
    # the truncation errors h^2 |f'''| / 6 and h^2 |f''''| / 12 (those derivatives < 50 here),
    # and their order
    assert b1 < 50 * 1e-6 / 6 and b2 < 50 * 1e-6
    assert 3.6 < a1 / b1 < 4.4 and 3.2 < a2 / b2 < 4.8


@pytest.mark.parametrize("frame", ["tool", "user"])
def test_motion_rigid_body(frame):
    """The frame's point moves as a point of the rigid platform: v + w x r, a + alpha x r +
    w x (w x r) seen from the user frame, with omega = E thd and alpha from numpy's own E and
    its derivative (by the product rule); the frame's Euler rates turn it with the same w, alpha."""
    model = micro(frames=FRAMES)
    tool = np.array(FRAMES["tool"])
    Ru = rot(FRAMES["user"][3:]) if frame == "user" else np.eye(3)
    q, qd, qdd = path(model, np.linspace(0.0, 3.0, 40))
    f = motion_from_platform(model, q, qd, qdd, frame)
    for k in range(len(q)):
        th, thd, thdd = q[k, 3:], qd[k, 3:], qdd[k, 3:]
        E = euler_matrix(th)
        cy, sy, cz, sz = np.cos(th[1]), np.sin(th[1]), np.cos(th[2]), np.sin(th[2])
        Ed = np.array([[-sy * thd[1] * cz - cy * sz * thd[2], -cz * thd[2], 0.0],
                       [-sy * thd[1] * sz + cy * cz * thd[2], -sz * thd[2], 0.0],
                       [-cy * thd[1], 0.0, 0.0]])
        w, al = E @ thd, E @ thdd + Ed @ thd
        r = rot(th) @ tool[:3]
        v = qd[k, :3] + np.cross(w, r)
        a = qdd[k, :3] + np.cross(al, r) + np.cross(w, np.cross(w, r))
        assert np.allclose(f.qd[k, :3], Ru.T @ v, rtol=0, atol=1e-15)
        assert np.allclose(f.qdd[k, :3], Ru.T @ a, rtol=0, atol=1e-13)
        # the frame's angles turn with C's angular velocity and acceleration, seen from W
        thf, thdf = f.q[k, 3:], f.qd[k, 3:]
        Ef = euler_matrix(thf)
        assert np.allclose(Ef @ thdf, Ru.T @ w, rtol=0, atol=1e-14)
        dt = 1e-6           # Edot of the frame's angles by the chain rule, numerically
        Edf = (euler_matrix(thf + dt * thdf) - euler_matrix(thf - dt * thdf)) / (2 * dt)
        assert np.allclose(Ef @ f.qdd[k, 3:] + Edf @ thdf, Ru.T @ al, rtol=0, atol=1e-8)


def test_motion_pivot_passes_angles_through():
    """A frame without rotation keeps the angles, their rates and accelerations bit for bit."""
    model = micro(frames=FRAMES)
    q, qd, qdd = path(model, np.linspace(0.0, 2.0, 21))
    f = motion_from_platform(model, q, qd, qdd, "pivot")
    assert np.array_equal(f.q[:, 3:], q[:, 3:]) and np.array_equal(f.qd[:, 3:], qd[:, 3:])
    assert np.array_equal(f.qdd[:, 3:], qdd[:, 3:])


def test_motion_without_accelerations_and_gimbal():
    """qdd None: the rates are those of the full call; the Euler rates at gimbal lock are
    refused naming the sample; an unknown frame is refused naming it."""
    model = micro(frames=FRAMES)
    q, qd, qdd = path(model, np.linspace(0.0, 2.0, 21))
    full = motion_from_platform(model, q, qd, qdd, "user")
    part = motion_from_platform(model, q, qd, None, "user")
    assert part.qdd is None and np.array_equal(part.qd, full.qd)
    # a platform pose whose tool frame, seen from the user frame, has thy = pi/2
    f = np.array([[0.0, 0.0, 0.0, 0.2, np.pi / 2, 0.1]])
    from stewart_fmu.frames import to_platform
    qg = to_platform(model, f, "user")
    with pytest.raises(StewartError, match="sample 0.*gimbal"):
        motion_from_platform(model, qg, np.zeros((1, 6)), None, "user")
    with pytest.raises(StewartError, match="'tcp'"):
        motion_from_platform(model, q, qd, qdd, "tcp")
