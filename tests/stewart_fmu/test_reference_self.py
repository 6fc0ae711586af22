"""Physics self-checks of the independent Newton-Euler reference (tests/reference/newton_euler.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from tests.reference.newton_euler import reference_inverse_dynamics

G = 9.81
HOME = np.array([0.0, 0.0, 0.12, 0.0, 0.0, 0.0])


def hexapod_scene() -> dict:
    """Symmetric hexapod (3-fold + mirror symmetric) with legs, drive and friction, as tomllib gives it."""
    base_deg = [-10.0, 10.0, 110.0, 130.0, 230.0, 250.0]
    plat_deg = [-50.0, 50.0, 70.0, 170.0, 190.0, 290.0]
    ring = lambda r, degs: [[r * math.cos(math.radians(d)), r * math.sin(math.radians(d)), 0.0] for d in degs]
    return {
        "name": "test-hexapod",
        "gravity": [0.0, 0.0, -G],
        "geometry": {"base_joints": ring(0.1, base_deg), "platform_joints": ring(0.06, plat_deg),
                     "home": HOME.tolist()},
        "platform": {"mass": 0.5, "inertia": [6e-4, 6e-4, 1.1e-3]},
        "legs": {"lower_mass": 0.065, "lower_com": 0.04, "lower_inertia": [3e-5, 1e-6],
                 "upper_mass": 0.065, "upper_com": 0.04, "upper_inertia": [3e-5, 1e-6]},
        "drive": {"gear_ratio": 20.0, "rotor_inertia": 1e-6, "pinion_radius": 0.005},
        "friction": {"viscous": 5.0, "coulomb": 0.3},
    }


def variant(name: str) -> dict:
    """Scene variants: full, or with one table left out, or with an odd gravity vector."""
    s = hexapod_scene()
    if name in ("legs", "drive", "friction"):
        del s[name]
    elif name == "bare":
        for k in ("legs", "drive", "friction", "gravity"):
            del s[k]
    elif name == "tilted_gravity":
        s["gravity"] = [1.3, -0.7, -9.6]
    return s


VARIANTS = ["full", "legs", "drive", "friction", "bare", "tilted_gravity"]


def random_samples(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Random poses near home with random rates and accelerations."""
    rng = np.random.default_rng(seed)
    scale_q = np.array([0.01, 0.01, 0.01, 0.1, 0.1, 0.1])
    scale_qd = np.array([0.1, 0.1, 0.1, 1.0, 1.0, 1.0])
    scale_qdd = np.array([5.0, 5.0, 5.0, 20.0, 20.0, 20.0])
    return [(HOME + scale_q * rng.uniform(-1, 1, 6), scale_qd * rng.uniform(-1, 1, 6),
             scale_qdd * rng.uniform(-1, 1, 6)) for _ in range(n)]


@pytest.mark.parametrize("name", [v for v in VARIANTS if v != "tilted_gravity"])
def test_static_symmetric_load(name: str) -> None:
    """(a) At rest, level, symmetric: equal forces; sum(sigma u_z) = platform weight + legs' share (1e-12 rel)."""
    scene = variant(name)
    out = reference_inverse_dynamics(scene, HOME, np.zeros(6), np.zeros(6))
    sigma, l = out["sigma"], out["l"]
    assert np.ptp(sigma) <= 1e-12 * np.abs(sigma).max()
    assert np.ptp(l) <= 1e-15
    a = np.asarray(scene["geometry"]["base_joints"])
    p = np.asarray(scene["geometry"]["platform_joints"])
    uz = ((HOME[:3] + p - a) / l[:, None])[:, 2]
    # Legs' share, by hand: B's weight along the leg, plus the platform joint's share of each leg's
    # transverse weight (moment about the base joint: (mA cA + mB (l - cB)) g sqrt(1-uz^2) / l).
    legs = scene.get("legs")
    if legs:
        moment_arm = legs["lower_mass"] * legs["lower_com"] + legs["upper_mass"] * (l - legs["upper_com"])
        share = G * np.sum(legs["upper_mass"] * uz**2 + moment_arm * (1 - uz**2) / l)
    else:
        share = 0.0
    expected = scene["platform"]["mass"] * G + share
    assert abs(np.sum(sigma * uz) - expected) <= 1e-12 * expected
    assert out["energy_rate"] == 0.0 and out["friction_power"] == 0.0 and out["kinetic"] == 0.0


@pytest.mark.parametrize("name", VARIANTS)
def test_power_balance(name: str) -> None:
    """(b) sum(sigma ldot) = d/dt(T + V) + friction power to 1e-10 relative, random states near home."""
    scene = variant(name)
    worst = 0.0
    for q, qd, qdd in random_samples(200, seed=VARIANTS.index(name)):
        out = reference_inverse_dynamics(scene, q, qd, qdd)
        terms = out["sigma"] * out["ldot"]
        scale = np.abs(terms).sum() + abs(out["energy_rate"]) + abs(out["friction_power"])
        resid = abs(terms.sum() - out["energy_rate"] - out["friction_power"]) / scale
        worst = max(worst, resid)
    assert worst <= 1e-10, worst


def test_jets_match_finite_differences() -> None:
    """Jet kinematics and energy rate agree with central differences along q(t) = q + qd t + qdd t^2/2 (1e-6 rel)."""
    scene = variant("full")
    h = 1e-5  # observed error ~2e-8 relative, shrinking as h^2
    for q, qd, qdd in random_samples(20, seed=7):
        q_at = lambda t: q + qd * t + 0.5 * qdd * t * t
        qd_at = lambda t: qd + qdd * t
        o0 = reference_inverse_dynamics(scene, q, qd, qdd)
        op = reference_inverse_dynamics(scene, q_at(h), qd_at(h), qdd)
        om = reference_inverse_dynamics(scene, q_at(-h), qd_at(-h), qdd)
        ldot_fd = (op["l"] - om["l"]) / (2 * h)
        lddot_fd = (op["l"] - 2 * o0["l"] + om["l"]) / h**2
        e = lambda o: o["kinetic"] + o["potential"]
        erate_fd = (e(op) - e(om)) / (2 * h)
        assert np.allclose(o0["ldot"], ldot_fd, rtol=0, atol=1e-6 * np.abs(o0["ldot"]).max())
        assert np.allclose(o0["lddot"], lddot_fd, rtol=0, atol=1e-3 * np.abs(o0["lddot"]).max())
        assert abs(o0["energy_rate"] - erate_fd) <= 1e-6 * max(abs(o0["energy_rate"]), 1e-3)


def test_angular_velocity_matches_euler_rate_map() -> None:
    """Platform omega and alpha from the jets equal E(theta) thetadot and its derivative (1e-12 abs)."""
    scene = variant("full")
    for q, qd, qdd in random_samples(20, seed=3):
        out = reference_inverse_dynamics(scene, q, qd, qdd)
        _, thy, thz = q[3:]
        def e_mat(thy: float, thz: float) -> np.ndarray:
            """omega = thzdot ez + Rz thydot ey + Rz Ry thxdot ex, as a matrix."""
            cy, sy, cz, sz = math.cos(thy), math.sin(thy), math.cos(thz), math.sin(thz)
            return np.array([[cz * cy, -sz, 0.0], [sz * cy, cz, 0.0], [-sy, 0.0, 1.0]])
        e0 = e_mat(thy, thz)
        h = 1e-6
        edot = (e_mat(thy + h * qd[4], thz + h * qd[5]) - e_mat(thy - h * qd[4], thz - h * qd[5])) / (2 * h)
        assert np.allclose(out["omega"], e0 @ qd[3:], rtol=0, atol=1e-12)
        assert np.allclose(out["alpha"], e0 @ qdd[3:] + edot @ qd[3:], rtol=0, atol=1e-7)


@pytest.mark.parametrize("name", ["full", "legs", "tilted_gravity"])
def test_lagrange_generalized_forces(name: str) -> None:
    """Lagrange's equations in pose coordinates, by differences of T and V, equal sum (sigma - mu) dl/dq (1e-8 rel).

    Unlike the power balance this also sees forces that do no work (gyroscopic, Coriolis).
    Observed difference-error floor ~1e-10; flipping the platform's gyroscopic term gives ~5e-6.
    """
    scene = variant(name)
    fr = scene.get("friction", {"viscous": 0.0, "coulomb": 0.0})
    run = lambda q, qd: reference_inverse_dynamics(scene, q, qd, np.zeros(6))
    eye = np.eye(6)

    def dT_dqd(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Gradient of T in qd; central differences are exact as T is quadratic in qd."""
        return np.array([(run(q, qd + 1e-2 * e)["kinetic"] - run(q, qd - 1e-2 * e)["kinetic"]) / 2e-2 for e in eye])

    for q, qd, qdd in random_samples(5, seed=11):
        out = reference_inverse_dynamics(scene, q, qd, qdd)
        ht, hq = 1e-6, 1e-5
        ddt = (dT_dqd(q + qd * ht + 0.5 * qdd * ht**2, qd + qdd * ht)
               - dT_dqd(q - qd * ht + 0.5 * qdd * ht**2, qd - qdd * ht)) / (2 * ht)
        grad = lambda key: np.array([(run(q + hq * e, qd)[key] - run(q - hq * e, qd)[key]) / (2 * hq) for e in eye])
        gen_force = ddt - grad("kinetic") + grad("potential")
        jac = np.array([(run(q, qd + e)["ldot"] - run(q, qd - e)["ldot"]) / 2 for e in eye])  # dl_i/dq_k = dldot_i/dqd_k
        mu = fr["viscous"] * out["ldot"] + fr["coulomb"] * np.sign(out["ldot"])
        actuator = jac @ (out["sigma"] - mu)
        assert np.abs(gen_force - actuator).max() <= 1e-8 * np.abs(actuator).max()
