"""Physics of the plant's inverse and forward dynamics, checked against physics and against the
independent Newton-Euler reference (tests/reference/newton_euler.py, kinematics by Taylor jets).

Every test states its tolerance in its docstring and asserts it; the worst residual of each check
is recorded (run with STEWART_RESIDUALS=1 to print them). Scenes: the micro-manipulator and the
motion simulator, at the model levels of helpers.LEVELS (tables dropped from the TOML dict).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from stewart_fmu import (
    PARTS,
    check_poses,
    forward_dynamics,
    inverse_dynamics,
    inverse_dynamics_parts,
    inverse_kinematics,
    present_parts,
    scene_from_dict,
)
from tests.helpers import (
    LEVELS,
    case,
    leg_geometry,
    level_dict,
    level_model,
    random_states,
    rate_matrix,
    rate_matrix_dot,
    record,
    rotation,
    scene_dict,
    smooth_trajectory,
    trajectory_samples,
)
from tests.reference.newton_euler import reference_inverse_dynamics

SCENES = ("micro", "sim")
CASES = [(s, lv) for s in SCENES for lv in LEVELS]
CASE_IDS = [f"{s}-{lv}" for s, lv in CASES]
LEVELS_INDEX = {lv: i for i, lv in enumerate(LEVELS)}


# --- 1. power balance --------------------------------------------------------------------------

@pytest.mark.parametrize("name,level", CASES + [("micro", "full+coulomb")],
                         ids=CASE_IDS + ["micro-full+coulomb"])
def test_power_balance_along_smooth_trajectories(name, level):
    """sum_i sigma_i ldot_i = d/dt (T + V) + friction power, to 1e-8 relative.

    sigma from our inverse_dynamics; ldot, the energy rate and the friction power from the
    reference's jets (independent). Relative to sum|sigma_i ldot_i| + |dE/dt| + |P_friction|.
    Trajectories: sums of three sinusoids in all six coordinates, roll/pitch/yaw together up to
    0.3-0.5 rad (asserted), all inside the stroke (asserted). With Coulomb friction, samples where
    some |ldot| < 1e-9 m/s are skipped (sign discontinuity).
    """
    tol = 1e-8
    data, model = case(name, level)
    q, qd, qdd = trajectory_samples(name, seeds=(0, 1, 2), n=40)
    check_poses(model, q)  # inside the stroke, away from singularities (raises otherwise)
    simultaneous = np.abs(q[:, 3:]).min(axis=1).max()
    assert simultaneous >= (0.3 if name == "micro" else 0.25), simultaneous
    coulomb = model.friction is not None and model.friction.coulomb > 0
    sigma = inverse_dynamics(model, q, qd, qdd)
    worst, used = 0.0, 0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])
        if coulomb and np.abs(ref["ldot"]).min() < 1e-9:
            continue
        power = sigma[k] * ref["ldot"]
        scale = np.abs(power).sum() + abs(ref["energy_rate"]) + abs(ref["friction_power"])
        resid = abs(power.sum() - ref["energy_rate"] - ref["friction_power"]) / scale
        worst, used = max(worst, resid), used + 1
    assert used >= 100
    record(f"1 power balance [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


# --- 2. second formulation: the Newton-Euler reference ---------------------------------------

@pytest.mark.parametrize("name,level", CASES + [("micro", "full+coulomb")],
                         ids=CASE_IDS + ["micro-full+coulomb"])
def test_inverse_dynamics_matches_newton_euler(name, level):
    """inverse_dynamics equals reference_inverse_dynamics on random states, to 1e-9 relative to
    max|sigma| of each sample (poses within the stroke, random rates and accelerations)."""
    tol = 1e-9
    data, model = case(name, level)
    q, qd, qdd = random_states(name, 40, seed=100 + LEVELS_INDEX.get(level, 9))
    sigma = inverse_dynamics(model, q, qd, qdd)
    worst = 0.0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])["sigma"]
        worst = max(worst, np.abs(sigma[k] - ref).max() / np.abs(ref).max())
    record(f"2 sigma vs Newton-Euler [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name", SCENES)
def test_leg_terms_alone_match_newton_euler(name):
    """The legs' own contribution, sigma(legs only) - sigma(platform only), equals the reference's
    same difference to 1e-9 relative to the largest leg contribution of the sample: no drive
    inertia (16 kg / 125 kg reflected) and no platform term to hide a leg-term error."""
    tol = 1e-9
    legs_d, legs_m = case(name, "no_drive_no_friction")
    plat_d, plat_m = case(name, "platform_only")
    q, qd, qdd = random_states(name, 40, seed=7)
    ours = inverse_dynamics(legs_m, q, qd, qdd) - inverse_dynamics(plat_m, q, qd, qdd)
    worst = 0.0
    for k in range(len(q)):
        ref = (reference_inverse_dynamics(legs_d, q[k], qd[k], qdd[k])["sigma"]
               - reference_inverse_dynamics(plat_d, q[k], qd[k], qdd[k])["sigma"])
        worst = max(worst, np.abs(ours[k] - ref).max() / np.abs(ref).max())
    record(f"2 leg terms alone vs Newton-Euler [{name}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name,level", CASES + [("micro", "full+coulomb")],
                         ids=CASE_IDS + ["micro-full+coulomb"])
def test_parts_breakdown(name, level):
    """inverse_dynamics_parts: the PARTS keys, each (N, 6); their sum equals sigma to 1e-12
    relative (max|sigma| per sample); 'drives' = m_d lddot and 'friction' = viscous ldot +
    coulomb sign(ldot) with the reference's lddot, ldot, to 1e-10 relative (to m_d max|lddot|,
    viscous max|ldot| + coulomb); 'platform' satisfies J^T f = [m a; I alpha + omega x I omega]
    (reference omega, alpha; J in numpy) to 1e-10 relative. Absent effects are left out of the dict."""
    data, model = case(name, level)
    q, qd, qdd = random_states(name, 30, seed=200 + LEVELS_INDEX.get(level, 9))
    parts = inverse_dynamics_parts(model, q, qd, qdd)
    sigma = inverse_dynamics(model, q, qd, qdd)
    assert tuple(parts) == present_parts(model)
    assert set(parts) <= set(PARTS)
    assert all(v.shape == q.shape for v in parts.values())

    total = sum(parts.values())
    worst_sum = (np.abs(total - sigma).max(axis=1) / np.abs(sigma).max(axis=1)).max()
    record(f"2 parts sum = sigma [{name}-{level}]", worst_sum, 1e-12)
    assert worst_sum <= 1e-12, worst_sum

    # Absent effects are not computed: their parts are left out; present ones are non-zero.
    for part, present in (("lower_legs", model.legs), ("upper_legs", model.legs),
                          ("drives", model.drive), ("friction", model.friction)):
        if present is None:
            assert part not in parts, part
        else:
            assert np.abs(parts[part]).max() > 0.0, part

    md = model.drive.reflected_mass if model.drive else 0.0
    visc = model.friction.viscous if model.friction else 0.0
    coul = model.friction.coulomb if model.friction else 0.0
    mass, inertia = model.platform_mass, np.diag(model.platform_inertia)
    worst_drive = worst_fric = worst_plat = 0.0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])
        if md:
            err = np.abs(parts["drives"][k] - md * ref["lddot"]).max()
            worst_drive = max(worst_drive, err / (md * np.abs(ref["lddot"]).max()))
        if model.friction:
            mu = visc * ref["ldot"] + coul * np.sign(ref["ldot"])
            err = np.abs(parts["friction"][k] - mu).max()
            worst_fric = max(worst_fric, err / (visc * np.abs(ref["ldot"]).max() + coul))
        r, _, _, _, J = leg_geometry(data, q[k])
        R = rotation(q[k, 3:])
        i_n = R @ inertia @ R.T
        om, al = ref["omega"], ref["alpha"]
        wrench = np.r_[mass * qdd[k, :3], i_n @ al + np.cross(om, i_n @ om)]
        got = J.T @ parts["platform"][k]
        worst_plat = max(worst_plat, np.abs(got - wrench).max() / np.abs(wrench).max())
    for label, worst in (("drives = m_d lddot", worst_drive), ("friction = mu(ldot)", worst_fric),
                         ("J^T platform = inertia wrench", worst_plat)):
        record(f"2 parts {label} [{name}-{level}]", worst, 1e-10)
        assert worst <= 1e-10, (label, worst)


# --- 3. inverse <-> forward, and integration ---------------------------------------------------

@pytest.mark.parametrize("name,level", CASES, ids=CASE_IDS)
def test_inverse_then_forward_and_back(name, level):
    """forward(inverse(qdd)) = qdd to 1e-9 relative (translational and rotational parts each
    relative to their largest entry in the sample); inverse(forward(sigma)) = sigma to 1e-9
    relative (max|sigma|); single-sample calls agree with batch calls to 1e-14 relative."""
    tol, tol_single = 1e-9, 1e-14
    _, model = case(name, level)
    q, qd, qdd = random_states(name, 50, seed=300 + LEVELS_INDEX[level])
    sigma = inverse_dynamics(model, q, qd, qdd)
    back = forward_dynamics(model, q, qd, sigma)
    err_t = np.abs(back[:, :3] - qdd[:, :3]).max(axis=1) / np.abs(qdd[:, :3]).max(axis=1)
    err_r = np.abs(back[:, 3:] - qdd[:, 3:]).max(axis=1) / np.abs(qdd[:, 3:]).max(axis=1)
    worst_qdd = max(err_t.max(), err_r.max())

    rng = np.random.default_rng(5)
    sig2 = rng.uniform(-1.0, 1.0, q.shape) * np.abs(sigma).max()
    qdd2 = forward_dynamics(model, q, qd, sig2)
    sig2_back = inverse_dynamics(model, q, qd, qdd2)
    worst_sig = (np.abs(sig2_back - sig2).max(axis=1) / np.abs(sig2).max(axis=1)).max()

    single_inv = np.array([inverse_dynamics(model, q[k], qd[k], qdd[k]) for k in range(len(q))])
    single_fwd = np.array([forward_dynamics(model, q[k], qd[k], sigma[k]) for k in range(len(q))])
    worst_single = max(np.abs(single_inv - sigma).max() / np.abs(sigma).max(),
                       np.abs(single_fwd - back).max() / np.abs(back).max())
    record(f"3 forward(inverse) = qdd [{name}-{level}]", worst_qdd, tol)
    record(f"3 inverse(forward) = sigma [{name}-{level}]", worst_sig, tol)
    record(f"3 single = batch [{name}-{level}]", worst_single, tol_single)
    assert worst_qdd <= tol, worst_qdd
    assert worst_sig <= tol, worst_sig
    assert worst_single <= tol_single, worst_single


@pytest.mark.parametrize("name,level", [("micro", "full"), ("micro", "platform_only"),
                                        ("sim", "full"), ("sim", "no_drive_no_friction")])
def test_integrating_forward_dynamics_reproduces_the_trajectory(name, level):
    """solve_ivp (DOP853, rtol 1e-11, atol 1e-13) of forward_dynamics under the inverse-dynamics
    forces of a smooth trajectory (computed at the integrator's own times from the analytic
    trajectory) reproduces it over 0.5 s: poses to 1e-8 m / rad, rates to 1e-7 m/s / rad/s,
    at 101 times of the dense output."""
    tol_q, tol_qd = 1e-8, 1e-7
    _, model = case(name, level)
    traj = smooth_trajectory(name, 7)

    def rhs(t, y):
        qt, qdt, qddt = traj(t)
        sigma = inverse_dynamics(model, qt, qdt, qddt)
        return np.concatenate([y[6:], forward_dynamics(model, y[:6], y[6:], sigma)])

    q0, qd0, _ = traj(0.0)
    sol = solve_ivp(rhs, (0.0, 0.5), np.concatenate([q0, qd0]), method="DOP853",
                    rtol=1e-11, atol=1e-13, dense_output=True)
    assert sol.success, sol.message
    t = np.linspace(0.0, 0.5, 101)
    y = sol.sol(t).T
    q, qd, _ = traj(t)
    err_q, err_qd = np.abs(y[:, :6] - q).max(), np.abs(y[:, 6:] - qd).max()
    record(f"3 solve_ivp pose error m|rad [{name}-{level}]", err_q, tol_q)
    record(f"3 solve_ivp rate error [{name}-{level}]", err_qd, tol_qd)
    assert err_q <= tol_q, err_q
    assert err_qd <= tol_qd, err_qd


# --- 4. symmetry and statics -------------------------------------------------------------------

def rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


ROT3 = rz(2.0 * np.pi / 3.0)
STEP = [2, 3, 4, 5, 0, 1]     # 120 deg about z takes joint i to joint STEP[i] (base and platform)
MIRROR = [1, 0, 5, 4, 3, 2]   # y -> -y takes joint i to joint MIRROR[i]
FLIP = np.diag([1.0, -1.0, 1.0])


@pytest.mark.parametrize("name", SCENES)
def test_scene_layout_is_three_fold_and_mirror_symmetric(name):
    """The joint layouts: mirror y -> -y exact (0), 120 deg about z to the files' 6-decimal
    rounding (<= 1.5e-6 m); the platform inertia is axisymmetric (Ixx = Iyy)."""
    d = scene_dict(name)
    for key in ("base_joints", "platform_joints"):
        pts = np.asarray(d["geometry"][key])
        assert np.array_equal(pts @ FLIP, pts[MIRROR]), key
        dev = np.abs(pts @ ROT3.T - pts[STEP]).max()
        record(f"4 layout 3-fold deviation m [{name} {key}]", dev, 1.5e-6)
        assert dev <= 1.5e-6, (key, dev)
    assert d["platform"]["inertia"][0] == d["platform"]["inertia"][1]


def symmetrized(data: dict) -> dict:
    """The scene with its joints made exactly D3-symmetric (3-fold about z and mirror y -> -y):
    joints 1, 2 averaged over their images, the others generated by exact rotation. The change
    is below the files' 6-decimal rounding (asserted <= 1e-6 m)."""
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in data.items()}
    out["geometry"] = dict(data["geometry"])
    for key in ("base_joints", "platform_joints"):
        pts = np.asarray(data["geometry"][key], dtype=float)
        seeds = []
        for j in (0, 1):
            seeds.append(np.mean([np.linalg.matrix_power(ROT3.T, k) @ pts[(j + 2 * k) % 6]
                                  for k in range(3)], axis=0))
        first = 0.5 * (seeds[0] + FLIP @ seeds[1])
        pair = (first, FLIP @ first)
        new = np.empty((6, 3))
        for k in range(3):
            for j in (0, 1):
                new[(j + 2 * k) % 6] = np.linalg.matrix_power(ROT3, k) @ pair[j]
        assert np.abs(new - pts).max() <= 1e-6
        out["geometry"][key] = new.tolist()
    return out


@pytest.mark.parametrize("name,level", CASES, ids=CASE_IDS)
def test_pure_heave_gives_six_equal_forces(name, level):
    """Pure heave (z, zdot, zddot only) of the symmetrized scene: six equal forces to 1e-12
    relative (ptp(sigma) <= 1e-12 max|sigma|), at rest and in motion."""
    tol = 1e-12
    data = symmetrized(level_dict(scene_dict(name), level))
    model = scene_from_dict(data)
    rng = np.random.default_rng(11)
    n = 30
    dz = {"micro": 0.02, "sim": 0.3}[name]
    q = np.tile(model.home, (n, 1))
    q[:, 2] += rng.uniform(-dz, dz, n)
    qd, qdd = np.zeros((n, 6)), np.zeros((n, 6))
    qd[1:, 2] = rng.uniform(-1.0, 1.0, n - 1) * (0.1 if name == "micro" else 0.5)
    qdd[1:, 2] = rng.uniform(-5.0, 5.0, n - 1)
    sigma = inverse_dynamics(model, q, qd, qdd)
    worst = (np.ptp(sigma, axis=1) / np.abs(sigma).max(axis=1)).max()
    record(f"4 pure heave equal forces [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


def rotate_state(q, qd, qdd, rot):
    """The state of the platform moved by the rotation `rot` about the world z axis, with the
    platform's frame relabelled so joint p_i goes to p_STEP[i]: x' = rot x, R' = rot R rot^T,
    omega' = rot omega, alpha' = rot alpha; Euler angles and rates recovered in numpy."""
    R = rot @ rotation(q[3:]) @ rot.T
    th = np.array([np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(R[2, 0]), np.arctan2(R[1, 0], R[0, 0])])
    E = rate_matrix(q[3:])
    om = E @ qd[3:]
    al = E @ qdd[3:] + rate_matrix_dot(q[3:], qd[3:]) @ qd[3:]
    E2 = rate_matrix(th)
    thd = np.linalg.solve(E2, rot @ om)
    thdd = np.linalg.solve(E2, rot @ al - rate_matrix_dot(th, thd) @ thd)
    return (np.r_[rot @ q[:3], th], np.r_[rot @ qd[:3], thd], np.r_[rot @ qdd[:3], thdd])


@pytest.mark.parametrize("name,level", CASES, ids=CASE_IDS)
def test_rotating_the_trajectory_by_120_degrees_permutes_the_forces(name, level):
    """On the symmetrized scene, the whole trajectory turned by 120 deg about z gives
    sigma'[STEP[i]] = sigma[i], to 1e-11 relative (max|sigma| per sample)."""
    tol = 1e-11
    data = symmetrized(level_dict(scene_dict(name), level))
    model = scene_from_dict(data)
    q, qd, qdd = trajectory_samples(name, seeds=(3, 4), n=20)
    moved = [rotate_state(*s, ROT3) for s in zip(q, qd, qdd)]
    q2, qd2, qdd2 = (np.array(c) for c in zip(*moved))
    sigma = inverse_dynamics(model, q, qd, qdd)
    sigma2 = inverse_dynamics(model, q2, qd2, qdd2)
    worst = (np.abs(sigma2[:, STEP] - sigma).max(axis=1) / np.abs(sigma).max(axis=1)).max()
    record(f"4 120 deg rotation permutes forces [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name,level", CASES, ids=CASE_IDS)
def test_mirror_image_trajectory_permutes_the_forces(name, level):
    """The files' exact mirror symmetry y -> -y: the state (x, -y, z, -thx, thy, -thz) (and
    its rates) gives sigma'[MIRROR[i]] = sigma[i] to 1e-12 relative (max|sigma| per sample)."""
    tol = 1e-12
    _, model = case(name, level)
    q, qd, qdd = trajectory_samples(name, seeds=(5,), n=40)
    s = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
    sigma = inverse_dynamics(model, q, qd, qdd)
    sigma2 = inverse_dynamics(model, model.home * (1 - s) + q * s, qd * s, qdd * s)
    worst = (np.abs(sigma2[:, MIRROR] - sigma).max(axis=1) / np.abs(sigma).max(axis=1)).max()
    record(f"4 mirror permutes forces [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name,level", CASES, ids=CASE_IDS)
def test_statics_vertical_balance(name, level):
    """At rest in random poses: sum_i sigma_i u_iz = platform weight + the legs' share, to 1e-12
    relative. The legs' share by hand (moment of each leg about its base joint): g sum_i
    [m_B u_iz^2 + (m_A c_A + m_B (l_i - c_B)) (1 - u_iz^2) / l_i]. Also equals the reference."""
    tol = 1e-12
    data, model = case(name, level)
    q, _, _ = random_states(name, 30, seed=400)
    zero = np.zeros_like(q)
    sigma = inverse_dynamics(model, q, zero, zero)
    g = -model.gravity[2]
    assert np.allclose(model.gravity[:2], 0.0)
    worst = worst_ref = 0.0
    for k in range(len(q)):
        _, _, l, u, _ = leg_geometry(data, q[k])
        uz = u[:, 2]
        share = 0.0
        if model.legs is not None:
            lg = model.legs
            share = g * np.sum(lg.upper_mass * uz**2 + (lg.lower_mass * lg.lower_com
                                                         + lg.upper_mass * (l - lg.upper_com))
                               * (1.0 - uz**2) / l)
        expected = model.platform_mass * g + share
        worst = max(worst, abs(sigma[k] @ uz - expected) / expected)
        ref = reference_inverse_dynamics(data, q[k], zero[k], zero[k])["sigma"]
        worst_ref = max(worst_ref, np.abs(sigma[k] - ref).max() / np.abs(ref).max())
    record(f"4 statics vertical balance [{name}-{level}]", worst, tol)
    record(f"4 statics = reference [{name}-{level}]", worst_ref, tol)
    assert worst <= tol, worst
    assert worst_ref <= tol, worst_ref


@pytest.mark.parametrize("name", SCENES)
def test_statics_platform_only_is_minus_j_inverse_transpose_gravity(name):
    """Platform-only model at rest: sigma = -J^-T [m g; 0] (J from inverse_kinematics, solved by
    numpy), to 1e-12 relative, at home and at random poses; the home forces are also equal to
    each other to the files' symmetry (1e-5 relative)."""
    tol = 1e-12
    data, model = case(name, "platform_only")
    q, _, _ = random_states(name, 30, seed=500)
    q = np.vstack([model.home, q])
    zero = np.zeros_like(q)
    sigma = inverse_dynamics(model, q, zero, zero)
    J = inverse_kinematics(model, q).jacobian
    wrench = np.r_[model.platform_mass * model.gravity, 0.0, 0.0, 0.0]
    expected = np.array([-np.linalg.solve(Jk.T, wrench) for Jk in J])
    worst = (np.abs(sigma - expected).max(axis=1) / np.abs(expected).max(axis=1)).max()
    record(f"4 statics -J^-T gravity [{name}]", worst, tol)
    assert worst <= tol, worst
    assert np.ptp(sigma[0]) <= 1e-5 * np.abs(sigma[0]).max()


@pytest.mark.parametrize("name", SCENES)
def test_euler_rate_conversion_at_large_angles(name):
    """Roll, pitch and yaw together up to 1 rad (stroke limits dropped, cond(J) < 200): the
    angular velocity and acceleration the dynamics kernel uses, recovered from its 'friction'
    (= viscous ldot) and 'drives' (= m_d lddot) parts through the leg kinematics, equal the
    reference's jets (omega, alpha) to 1e-10 relative; and for the platform alone in zero gravity
    J^T sigma = [m a; I alpha + omega x I omega] with the reference's omega, alpha (1e-10 rel)."""
    tol = 1e-10
    data = scene_dict(name)
    del data["geometry"]["leg_min"], data["geometry"]["leg_max"]
    data["friction"]["coulomb"] = 0.0
    model = scene_from_dict(data)
    plat = level_dict(data, "platform_only")
    plat["gravity"] = [0.0, 0.0, 0.0]
    plat_model = scene_from_dict(plat)
    rng = np.random.default_rng(600)
    rows = []
    while len(rows) < 30:
        th = rng.uniform(-1.0, 1.0, 3)
        th[rng.integers(3)] = rng.choice([-1.0, 1.0])  # one angle at the full 1 rad
        q = np.r_[model.home[:3], th]
        if inverse_kinematics(model, q).cond < 200:
            rows.append((q, rng.uniform(-1, 1, 6) * np.r_[0.1, 0.1, 0.1, 2, 2, 2],
                         rng.uniform(-1, 1, 6) * np.r_[3, 3, 3, 40, 40, 40]))
    q, qd, qdd = (np.array(c) for c in zip(*rows))
    parts = inverse_dynamics_parts(model, q, qd, qdd)
    ldot = parts["friction"] / model.friction.viscous
    lddot = parts["drives"] / model.drive.reflected_mass
    sigma_p = inverse_dynamics(plat_model, q, qd, qdd)
    mass, inertia = model.platform_mass, np.diag(model.platform_inertia)
    worst_om = worst_al = worst_dyn = 0.0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])
        om, al = ref["omega"], ref["alpha"]
        r, _, l, u, J = leg_geometry(data, q[k])
        v, a = qd[k, :3], qdd[k, :3]
        om_k = np.linalg.lstsq(J[:, 3:], ldot[k] - u @ v, rcond=None)[0]
        vp = v + np.cross(om, r)
        centripetal = np.einsum("ij,ij->i", u, np.cross(om, np.cross(om, r)))
        rhs = lddot[k] - u @ a - centripetal - (np.einsum("ij,ij->i", vp, vp) - ldot[k] ** 2) / l
        al_k = np.linalg.lstsq(J[:, 3:], rhs, rcond=None)[0]
        worst_om = max(worst_om, np.abs(om_k - om).max() / np.abs(om).max())
        worst_al = max(worst_al, np.abs(al_k - al).max() / np.abs(al).max())
        R = rotation(q[k, 3:])
        i_n = R @ inertia @ R.T
        wrench = np.r_[mass * a, i_n @ al + np.cross(om, i_n @ om)]
        worst_dyn = max(worst_dyn, np.abs(J.T @ sigma_p[k] - wrench).max() / np.abs(wrench).max())
    assert np.abs(q[:, 3:]).max() == 1.0
    for label, worst in (("omega", worst_om), ("alpha", worst_al), ("J^T sigma wrench", worst_dyn)):
        record(f"4 Euler rates at 1 rad: {label} [{name}]", worst, tol)
        assert worst <= tol, (label, worst)


@pytest.mark.parametrize("level", ["platform_only", "no_drive_no_friction", "no_drive",
                                   "platform_friction"])
def test_absent_effects_are_not_computed(level):
    """A table the scene leaves out is skipped, not computed as zeros: with NaN written into the
    absent effects' parameter slots, inverse, forward and parts kernels still return the same
    finite forces and accelerations bit for bit (a NaN read anywhere would reach the result)."""
    from stewart_fmu import dynamics as D
    from stewart_fmu.native import core
    from stewart_fmu import model as M

    model = level_model("micro", level)
    q, qd, qdd = trajectory_samples("micro", [11], 50)
    poisoned = model.params.copy()
    slots = {"legs": [*range(M.P_LOWER, M.P_LOWER + 4), *range(M.P_UPPER, M.P_UPPER + 4)],
             "drive": [M.P_DRIVE_MASS], "friction": [M.P_VISCOUS, M.P_COULOMB]}
    for effect, where in slots.items():
        if getattr(model, effect) is None:
            poisoned[where] = np.nan
    sigma = inverse_dynamics(model, q, qd, qdd)
    for p, expect in ((model.params, sigma), (poisoned, sigma)):
        out, index, status = core.inverse_dynamics_batch(p, q, qd, qdd)
        assert (index, status) == (-1, core.OK)
        assert np.array_equal(out, expect)
        acc, index, status = core.forward_dynamics_batch(p, q, qd, sigma)
        assert (index, status) == (-1, core.OK)
        assert np.array_equal(acc, forward_dynamics(model, q, qd, sigma))
        parts, index, status = core.inverse_dynamics_parts_batch(p, q, qd, qdd)
        assert (index, status) == (-1, core.OK)
        for name, value in inverse_dynamics_parts(model, q, qd, qdd).items():
            assert np.array_equal(parts[:, D.PARTS.index(name)], value)
