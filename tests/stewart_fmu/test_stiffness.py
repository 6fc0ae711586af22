"""Stiffness and modes (stiffness.c): against the static wrench of the full nonlinear model, a
closed form, an independent generalized eigenproblem, and the free vibration of the nonlinear
forward simulation."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from stewart_fmu import scene_from_dict
from stewart_fmu import stiffness as S
from stewart_fmu.errors import SceneError, UnstablePoseError
from stewart_fmu.kane_terms import drive_inertia, mass_matrix
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.native import core
from tests.helpers import record, scene_dict
from tests.stewart_fmu.stiffness_checks import NonlinearStatics, moved, rotation

# Per scene: its characteristic length (the rotation columns' scale) and a payload off C
# with products of inertia.
SCALE = {"micro": 0.06, "sim": 1.3}
PAYLOAD = {"micro": {"mass": 2.0, "com": [0.018, -0.012, 0.03],
                     "inertia": [1e-3, 2e-3, 2.5e-3, 1e-4, -2e-4, 3e-4]},
           "sim": {"mass": 500.0, "com": [0.39, -0.26, 0.65],
                   "inertia": [100.0, 120.0, 150.0, 10.0, -5.0, 3.0]}}
LEGS = [2e7, 2.1e7, 1.9e7, 2e7, 2.2e7, 1.8e7]


def _model(name: str, stiffness: dict | None = None, payload: bool = True, drop=(), **tables):
    d = scene_dict(name)
    d["stiffness"] = stiffness or {"leg": LEGS}
    if payload:
        d["payload"] = PAYLOAD[name]
    for t in drop:
        d.pop(t, None)
    d.update(tables)
    return scene_from_dict(d)


def _pose(name: str) -> np.ndarray:
    """A pose off home, turned about every axis (no symmetry hides a term)."""
    c = SCALE[name]
    home = np.array(scene_dict(name)["geometry"]["home"])
    return home + np.array([0.1 * c, -0.05 * c, 0.03 * c, 0.05, -0.08, 0.1])


def _scaled_error(name: str, A: np.ndarray, B: np.ndarray) -> float:
    """||A - B|| / ||B|| with the rotation rows and columns in metres (divided by the scale)."""
    D = np.diag([1, 1, 1, *[1 / SCALE[name]] * 3])
    return float(np.linalg.norm(D @ (A - B) @ D) / np.linalg.norm(D @ B @ D))


@pytest.mark.parametrize("name,bending,soft", [("micro", None, 1.0), ("micro", 50.0, 1.0),
                                               ("micro", None, 1e-3), ("sim", None, 1.0),
                                               ("sim", 2e5, 1.0), ("sim", 2e5, 1e-2)])
def test_stiffness_is_the_nonlinear_static_wrench_derivative(name, bending, soft):
    """K = -dW/dchi of the full nonlinear model (Kane's gravity forces of the platform and leg
    parts, the payload's weight, legs as springs about the equilibrium lengths, the flexures'
    exact bending angles) by central differences, <= 1e-7 relative, with stiff and soft legs;
    the static leg forces are those that make W vanish; J^T k J alone misses the loads'
    geometric term (and the joints') by 50 times the tolerance or more."""
    stiff = {"leg": [k * soft for k in LEGS]} | ({"joint_bending": bending} if bending else {})
    model = _model(name, stiff, transmission=None)
    q = _pose(name)
    s = S.stiffness(model, q)
    ns = NonlinearStatics(model, q)
    assert np.allclose(-ns._spring_force_needed(), s.leg_forces, rtol=1e-12, atol=1e-9 * np.abs(s.leg_forces).max())
    # in equilibrium to the rounding of k (l - l0): k l eps
    eps = np.finfo(float).eps
    assert np.abs(ns.wrench(q)).max() <= 10 * max(LEGS) * soft * ns.l0.max() * eps
    c = SCALE[name]
    K_fd = ns.stiffness_fd(1e-5 * c, 1e-5)
    err = _scaled_error(name, s.matrix, K_fd)
    record("stiffness vs nonlinear statics (rel)", err, 1e-7)
    assert err <= 1e-7
    J = inverse_kinematics(model, q, with_cond=False).jacobian
    plain = J.T @ np.diag(model.stiffness.leg_legs) @ J
    assert _scaled_error(name, plain, K_fd) > 50 * 1e-7
    assert np.array_equal(s.matrix, s.matrix.T)


def test_transmission_acts_in_series_with_the_strut():
    """A [transmission] of stiffness k_t makes each leg's rate k k_t / (k + k_t): the stiffness
    equals the strut-only model's with those rates (the same statics)."""
    d = scene_dict("micro")
    kt = 3e7
    d["transmission"] = {"stiffness": kt, "damping": 10.0}
    d["stiffness"] = {"leg": LEGS}
    with_t = scene_from_dict(d)
    d.pop("transmission")
    d["stiffness"] = {"leg": [k * kt / (k + kt) for k in LEGS]}
    series = scene_from_dict(d)
    q = _pose("micro")
    assert np.allclose(S.stiffness(with_t, q).matrix, S.stiffness(series, q).matrix,
                       rtol=1e-13, atol=1e-13 * np.abs(S.stiffness(series, q).matrix).max())
    # the motors held: the drives' inertia stays out of the modes' mass matrix
    assert np.allclose(S.mass_matrix(with_t, q), S.mass_matrix(_model("micro", drop=("drive",), payload=False), q),
                       rtol=1e-14, atol=1e-15)


def test_compliance_at_the_pivot_is_the_inverse_stiffness_moved_there():
    """A force F at the pivot p (in C) and a moment M move the pivot by dx + dtheta x R p:
    Cp = T^T K^-1 T; checked by solving K chi = (F, M + R p x F) for unit loads."""
    model = _model("sim")
    q = _pose("sim")
    pivot = np.array([0.3, -0.2, 0.8])
    s = S.stiffness(model, q, pivot)
    rho = rotation(q) @ pivot
    for k in range(6):
        load = np.eye(6)[k]
        F, M = load[:3], load[3:]
        chi = np.linalg.solve(s.matrix, np.r_[F, M + np.cross(rho, F)])
        moved_by = np.r_[chi[:3] + np.cross(chi[3:], rho), chi[3:]]
        assert np.allclose(s.compliance[:, k], moved_by, rtol=1e-9, atol=1e-9 * np.abs(moved_by).max())
    assert np.all(s.axis_stiffness > 0)


def _symmetric(torsion: float | None, friction: float | None = None):
    """A hexapod of exact mirror and 3-fold symmetry (the micro-manipulator's pattern from its
    angles: base joints at 120 k -+ 10 deg, radius 0.1 m; platform joints at 120 k -+ 50 deg,
    radius 0.06 m, 1 cm below C), massless legs, no drive, no gravity (no preload), equal springs."""
    d = scene_dict("micro")
    for t in ("legs", "drive", "friction"):
        d.pop(t)
    base = [120 * k + s for k in range(3) for s in (-10, 10)]
    top = [120 * k + s for k in range(3) for s in (-50, 50)]
    rad = np.radians
    d["geometry"]["base_joints"] = [[0.1 * np.cos(rad(a)), 0.1 * np.sin(rad(a)), 0.0] for a in base]
    d["geometry"]["platform_joints"] = [[0.06 * np.cos(rad(a)), 0.06 * np.sin(rad(a)), -0.01]
                                        for a in top]
    d["gravity"] = [0.0, 0.0, 0.0]
    d["stiffness"] = {"leg": 2e7} | ({"joint_torsion": torsion} if torsion else {})
    if friction:
        d["friction"] = {"viscous": friction, "coulomb": 0.0}
    return scene_from_dict(d)


@pytest.mark.parametrize("torsion", [None, 40.0])
def test_symmetric_platform_vertical_and_torsion_modes_closed_form(torsion):
    """A symmetric platform on massless legs: the vertical mode w^2 = k sum u_z^2 / m and the
    torsion mode w^2 = (k sum ((r x u)_z)^2 + k_t / 2 sum u_z^2) / I_zz, each a pure z (thz)
    twist, 1e-12 relative."""
    model = _symmetric(torsion)
    q = model.home
    kin = inverse_kinematics(model, q, with_cond=False)
    u, r = kin.unit_vectors, model.platform_joints @ rotation(q).T
    k = 2e7
    vertical = k * np.sum(u[:, 2] ** 2) / model.platform_mass
    torsion_w2 = (k * np.sum(np.cross(r, u)[:, 2] ** 2)
                  + (torsion or 0.0) / 2 * np.sum(u[:, 2] ** 2)) / model.platform_inertia[2]
    m = S.modes(model, q)
    for w2, axis in ((vertical, 2), (torsion_w2, 5)):
        j = int(np.argmin(np.abs(m.omega2 - w2)))
        err = abs(m.omega2[j] - w2) / w2
        record("modes closed form (rel)", err, 1e-12)
        assert err <= 1e-12
        shape = m.shapes[j] / np.abs(m.shapes[j]).max()
        assert np.allclose(shape, np.eye(6)[axis], atol=1e-9)


@pytest.mark.parametrize("name", ["micro", "sim"])
def test_modes_are_the_generalized_eigenproblem_of_an_independent_mass_matrix(name):
    """The mass matrix is the Python reference's leg-space [m] + [m_d] (kane_terms, Eq. 7, the
    payload a body of its own) in twist coordinates, J^T ([m] + [m_d]) J (1e-12); the modes
    are scipy.linalg.eigh(K, M)'s: frequencies 1e-10 relative, each shape K v = w^2 M v and
    v^T M v = 1."""
    model = _model(name)
    q = _pose(name)
    J = inverse_kinematics(model, q, with_cond=False).jacobian
    M_ref = J.T @ (mass_matrix(model, q) + drive_inertia(model)) @ J
    M = S.mass_matrix(model, q)
    err_m = np.linalg.norm(M - M_ref) / np.linalg.norm(M_ref)
    record("modes mass matrix vs kane_terms (rel)", err_m, 1e-12)
    assert err_m <= 1e-12
    K = S.stiffness(model, q).matrix
    w2_ref = scipy.linalg.eigh(K, M_ref, eigvals_only=True)
    m = S.modes(model, q)
    err = np.max(np.abs(m.omega2 - w2_ref) / w2_ref)
    record("modes vs scipy eigh (rel)", err, 1e-10)
    assert err <= 1e-10
    for j in range(6):
        v = m.shapes[j]
        assert np.linalg.norm(K @ v - m.omega2[j] * M @ v) <= 1e-9 * np.linalg.norm(K @ v)
        assert abs(v @ M @ v - 1.0) <= 1e-12
    assert np.allclose(m.leg_rates, m.shapes @ J.T)


def test_damping_ratios_are_the_damped_systems_eigenvalues():
    """With per-leg viscous friction unequal (damping not proportional: it couples the close
    modes 4 and 5 of the motion simulator, where the modal projection v^T D v / 2w errs by
    13 %), the damping ratios are those of the quadratic eigenproblem solved independently by
    scipy's QZ on the symmetric linearization [[D, M], [M, 0]] z' = [[-K, 0], [0, M]] z
    (1e-9); a symmetric platform with equal friction, massless legs and no preload has
    proportional damping, D = (c / k) K: zeta = c w / 2k (1e-12)."""
    model = _model("sim", {"leg": 5.0e7}, payload=False,
                   friction={"viscous": [2000.0, 8000.0, 1500.0, 2200.0, 5800.0, 2000.0], "coulomb": 0.0})
    q = model.home + np.array([0.05, -0.03, 0.04, 0.03, -0.02, 0.05])
    m = S.modes(model, q)
    M, K = S.mass_matrix(model, q), S.stiffness(model, q).matrix
    J = inverse_kinematics(model, q, with_cond=False).jacobian
    D = J.T @ np.diag(model.friction.viscous_legs) @ J
    Z = np.zeros((6, 6))
    lam = scipy.linalg.eig(np.block([[-K, Z], [Z, M]]), np.block([[D, M], [M, Z]]), right=False)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    err = np.max(np.abs(m.damping + lam.real / np.abs(lam)) / m.damping)
    record("damping ratios vs scipy QZ (rel)", err, 1e-9)
    assert err <= 1e-9
    modal = np.array([v @ D @ v for v in m.shapes]) / (2 * np.sqrt(m.omega2))
    assert np.max(np.abs(modal - m.damping) / m.damping) > 0.1    # the coupling is there
    sym = _symmetric(None, friction=300.0)
    ms = S.modes(sym, sym.home)
    expected = 300.0 * np.sqrt(ms.omega2) / (2 * 2e7)
    err = np.max(np.abs(ms.damping - expected) / expected)
    record("damping ratios closed form (rel)", err, 1e-12)
    assert err <= 1e-12


def _free_vibration(model, q0, modes, M, h: float, n: int) -> np.ndarray:
    """The nonlinear forward dynamics (the core's, Kane's equations) with each leg a spring
    about its equilibrium length, from q0 moved by a small twist along every mode, by RK4 of
    step h: the modal coordinates v_j^T M chi(t) of n samples."""
    zero = np.zeros(6)
    k = model.stiffness.leg_legs
    l0 = core.leg_state(model.native, q0, zero)[0] + S.stiffness(model, q0).leg_forces / k

    def acc(q, qd):
        l = core.leg_state(model.native, q, zero)[0]
        qdd, st = core.forward_dynamics(model.native, q, qd, -k * (l - l0))
        assert st == core.OK
        return qdd

    q, qd = moved(q0, 1e-6 * modes.shapes.sum(axis=0) / np.abs(modes.shapes).max()), np.zeros(6)
    R0, P, out = rotation(q0), modes.shapes @ M, np.empty((n, 6))
    for i in range(n):
        R = rotation(q) @ R0.T
        chi = np.r_[q[:3] - q0[:3], 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])]
        out[i] = P @ chi
        a1 = acc(q, qd)
        a2 = acc(q + 0.5 * h * qd, qd + 0.5 * h * a1)
        a3 = acc(q + 0.5 * h * (qd + 0.5 * h * a1), qd + 0.5 * h * a2)
        a4 = acc(q + h * (qd + 0.5 * h * a2), qd + h * a3)
        q = q + h * qd + h * h / 6 * (a1 + a2 + a3)
        qd = qd + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    return out


def _peak(x: np.ndarray, h: float) -> float:
    """The spectral peak of x (Hann window, 16x zero padding, parabolic interpolation of the
    log magnitude), Hz."""
    n = len(x)
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), 16 * n))
    i = int(np.argmax(spec))
    a, b, c = np.log(spec[i - 1:i + 2])
    return (i + 0.5 * (a - c) / (a - 2 * b + c)) / (16 * n * h)


@pytest.mark.parametrize("drop,payload", [(("drive", "friction"), False), (("friction",), False),
                                          (("drive", "friction"), True)])
def test_free_vibration_of_the_nonlinear_simulation_peaks_at_the_modes(drop, payload):
    """After a small kick along every mode, the nonlinear simulation's modal coordinates each
    peak at their computed frequency within 0.5 % (massive legs, per-leg springs, a pose off
    home; with and without the drives' inertia, with a payload off C; frictionless, so the
    spectrum is the modes')."""
    d = scene_dict("micro")
    for t in drop:
        d.pop(t)
    if payload:
        d["payload"] = PAYLOAD["micro"]
    d["stiffness"] = {"leg": [2e5, 2.2e5, 1.9e5, 2.1e5, 1.8e5, 2e5]}
    model = scene_from_dict(d)
    q0 = _pose("micro")
    m = S.modes(model, q0)
    h = 0.05 / m.frequency_hz[-1]
    out = _free_vibration(model, q0, m, S.mass_matrix(model, q0), h, 4096)
    for j in range(6):
        err = abs(_peak(out[:, j], h) / m.frequency_hz[j] - 1.0)
        record("free vibration peak vs mode (rel)", err, 5e-3)
        assert err <= 5e-3, (j, m.frequency_hz[j])


def test_bad_input_is_refused_naming_the_key():
    """Zero or negative stiffness, a payload inertia that is not positive definite or no rigid
    body's, a wrong count: SceneKeyError naming the key."""
    cases = [({"stiffness": {"leg": 0.0}}, "stiffness.leg", "> 0"),
             ({"stiffness": {"leg": [1e7] * 5 + [-1.0]}}, "stiffness.leg", "> 0"),
             ({"stiffness": {"leg": [1e7] * 5}}, "stiffness.leg", "six"),
             ({"stiffness": {"leg": 1e7, "joint_bending": 0.0}}, "stiffness.joint_bending", "> 0"),
             ({"stiffness": {"leg": 1e7, "spring": 1.0}}, "stiffness.spring", "unknown"),
             ({"payload": {"mass": 0.0, "com": [0, 0, 0], "inertia": [1, 1, 1]}}, "payload.mass", "> 0"),
             ({"payload": {"mass": 1.0, "com": [0, 0, 0], "inertia": [1, 1, -1]}}, "payload.inertia",
              "positive definite"),
             ({"payload": {"mass": 1.0, "com": [0, 0, 0], "inertia": [1, 1, 1, 2, 0, 0]}},
              "payload.inertia", "positive definite"),
             ({"payload": {"mass": 1.0, "com": [0, 0, 0], "inertia": [1, 1, 3]}}, "payload.inertia",
              "rigid body"),
             ({"payload": {"mass": 1.0, "com": [0, 0, 0], "inertia": [1, 1]}}, "payload.inertia", "3"),
             ({"payload": {"mass": 1.0, "com": [0, 0], "inertia": [1, 1, 1]}}, "payload.com", "shape"),
             ({"payload": {"mass": 1.0, "inertia": [1, 1, 1]}}, "payload.com", "missing")]
    for tables, key, words in cases:
        d = scene_dict("micro") | tables
        with pytest.raises(SceneError) as err:
            scene_from_dict(d)
        assert err.value.key == key and words in str(err.value), (tables, str(err.value))


def test_no_stiffness_table_and_a_buckling_load_are_refused():
    """Modes without [stiffness]: a SceneError naming it; a payload heavy enough that its
    weight's geometric stiffness outweighs soft legs: UnstablePoseError, never a NaN."""
    with pytest.raises(SceneError) as err:
        S.modes(scene_from_dict(scene_dict("micro")), _pose("micro"))
    assert err.value.key == "stiffness"
    d = scene_dict("micro")
    d["stiffness"] = {"leg": 1e3}
    d["payload"] = {"mass": 50.0, "com": [0.0, 0.0, 0.5], "inertia": [1.0, 1.0, 1.0]}
    model = scene_from_dict(d)
    with pytest.raises(UnstablePoseError):
        S.modes(model, model.home)


def test_map_is_the_single_pose_results():
    """modes_map over poses: each pose's lowest frequency and weakest translational stiffness
    as the single-pose calls give them."""
    model = _model("sim")
    rng = np.random.default_rng(7)
    Q = model.home + rng.uniform(-1, 1, (20, 6)) * np.array([0.1, 0.1, 0.1, 0.05, 0.05, 0.05])
    mp = S.modes_map(model, Q)
    for k in range(20):
        assert mp.lowest_hz[k] == pytest.approx(S.modes(model, Q[k]).frequency_hz[0], rel=1e-13)
        C = S.stiffness(model, Q[k]).compliance[:3, :3]
        lam, vec = np.linalg.eigh(C)
        assert mp.weakest[k] == pytest.approx(1 / lam[-1], rel=1e-10)
        assert abs(abs(vec[:, -1] @ mp.weakest_direction[k]) - 1) <= 1e-8


def test_static_forces_are_the_inverse_dynamics_at_rest_plus_the_payloads_weight():
    """static_forces without a payload: inverse_dynamics at rest (1e-15); with one, the
    difference balances the payload's weight and moment through J^T; no [stiffness] needed."""
    from stewart_fmu import inverse_dynamics

    d = scene_dict("sim")
    plain = scene_from_dict(d)
    d["payload"] = PAYLOAD["sim"]
    loaded = scene_from_dict(d)
    q = _pose("sim")
    zero = np.zeros(6)
    s0 = S.static_forces(plain, q)
    assert np.allclose(s0, inverse_dynamics(plain, q, zero, zero), rtol=1e-15, atol=0)
    J = inverse_kinematics(plain, q, with_cond=False).jacobian
    F = PAYLOAD["sim"]["mass"] * plain.gravity
    W = np.r_[F, np.cross(rotation(q) @ np.array(PAYLOAD["sim"]["com"]), F)]
    ds = S.static_forces(loaded, q) - s0
    assert np.allclose(J.T @ ds, -W, rtol=0, atol=1e-10 * np.abs(W).max())
