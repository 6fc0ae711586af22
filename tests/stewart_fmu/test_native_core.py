"""The C core (stewart_fmu/native, stewart.h) against the numba kernels and against physics.

Agreement: every C function equals its numba counterpart to 1e-12 relative (to the largest
entry of the quantity per sample, or its scale) on both shipped scenes at every model level of
conftest.LEVELS, on every scene of scenes/stiff and scenes/extreme, on random smooth states.
Statuses (and the index of a batch's first bad sample) must be equal. Physics: the checks of
test_dynamics_physics.py (power balance, Newton-Euler reference, inverse <-> forward round
trip) run on the C core with the same tolerances. Plant steps: stewart_step equals
Plant.do_step's advance and power balance, trips UNSTABLE where the Plant raises, and bounds
its work (TOO_MANY_STEPS).
"""
from __future__ import annotations


import numpy as np
import pytest

from helpers import LEVELS, SCENES_DIR, case, level_model, random_states, record, trajectory_samples
from reference.newton_euler import reference_inverse_dynamics
from stewart_fmu import dynamics as D
from stewart_fmu import energy as E
from stewart_fmu import integrators as I
from stewart_fmu import inverse_kinematics, load_scene
from stewart_fmu.errors import IntegrationError
from stewart_fmu.kane import twist_mass_matrix
from stewart_fmu.kinematics import _scaled_jacobian, condition_number
from stewart_fmu.stability import ENERGY_TOL, hold_state, step_energy
from stewart_fmu.plant import Plant
from stewart_fmu.status import ENERGY_GAIN, STATE_NONFINITE
from stewart_fmu.transmission import initial_state, leg_side_params, spring_forces

core = pytest.importorskip("stewart_fmu.native.core")

TOL = 1e-12
FILES = sorted([SCENES_DIR / "micro_manipulator.toml", SCENES_DIR / "motion_simulator.toml"]
               + list((SCENES_DIR / "stiff").glob("*.toml"))
               + list((SCENES_DIR / "extreme").glob("*.toml")))
MODEL_CASES = ([(f"{s}-{lv}", s, lv) for s in ("micro", "sim") for lv in LEVELS]
               + [(f"{f.parent.name}/{f.stem}", str(f), None) for f in FILES])


def get_model(spec, level):
    return level_model(spec, level) if level is not None else load_scene(spec)


def rel(a, b, axis=None) -> float:
    """max |a - b| / max |b| (per row when axis is given, then the worst row)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if axis is None:
        return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
    num = np.abs(a - b).reshape(len(a), -1).max(axis=1)
    den = np.maximum(np.abs(b).reshape(len(b), -1).max(axis=1), 1e-300)
    return float(np.max(num / den))


def states(model, n: int, seed: int):
    """n random states near home: poses inside the stroke with cond(J) < 1e3 (numba's
    kinematics), rates and accelerations scaled by the mechanism's size."""
    rng = np.random.default_rng(seed)
    c = model.characteristic_length
    qs = np.array([0.15 * c, 0.15 * c, 0.15 * c, 0.3, 0.3, 0.3])
    lo = model.leg_min if model.leg_min is not None else 0.0
    hi = model.leg_max if model.leg_max is not None else np.inf
    rows = []
    while len(rows) < n:
        q = model.home + qs * rng.uniform(-1.0, 1.0, 6)
        kin = inverse_kinematics(model, q)
        if np.all((kin.lengths > lo) & (kin.lengths < hi)) and kin.cond < 1e3:
            rows.append((q, qs * rng.uniform(-2.0, 2.0, 6), qs * rng.uniform(-40.0, 40.0, 6)))
    return tuple(np.array(col) for col in zip(*rows))


def case_states(spec, level, n, seed):
    model = get_model(spec, level)
    if level is not None:  # the physics tests' own states for the two shipped scenes
        return model, random_states(spec, n, seed)
    return model, states(model, n, seed)


# --- dynamics ----------------------------------------------------------------------------------

@pytest.mark.parametrize("cid,spec,level", MODEL_CASES, ids=[c[0] for c in MODEL_CASES])
def test_dynamics_match_numba(cid, spec, level):
    """inverse, parts, forward (single and batch), leg_state, Jacobian, cond(J), the twist mass
    matrix and the Kane terms equal the numba kernels to 1e-12 relative (cond: 1e-10)."""
    model, (q, qd, qdd) = case_states(spec, level, 30, seed=11)
    p = model.params
    P = core.native_params(p)
    sigma = D.inverse_dynamics(model, q, qd, qdd)
    s_c, index, status = core.inverse_dynamics_batch(P, q, qd, qdd)
    assert (index, status) == (-1, core.OK)
    worst = rel(s_c, sigma, axis=1)
    single = np.array([core.inverse_dynamics(P, q[k], qd[k], qdd[k])[0] for k in range(len(q))])
    worst = max(worst, rel(single, sigma, axis=1))

    parts_ref = np.empty((len(q), 6, 6))
    assert D._parts_batch(p, q, qd, qdd, parts_ref) == (-1, D.OK)
    parts_c, index, status = core.inverse_dynamics_parts_batch(P, q, qd, qdd)
    assert (index, status) == (-1, core.OK)
    # each part relative to max|sigma| of its sample (the parts sum to sigma)
    worst_parts = float((np.abs(parts_c - parts_ref).max(axis=(1, 2))
                         / np.abs(sigma).max(axis=1)).max())
    one, st = core.inverse_dynamics_parts(P, q[0], qd[0], qdd[0])
    assert st == core.OK and np.array_equal(one, parts_c[0])

    rng = np.random.default_rng(3)
    sig2 = rng.uniform(-1.0, 1.0, q.shape) * np.abs(sigma).max()
    acc = D.forward_dynamics(model, q, qd, sig2)
    a_c, index, status = core.forward_dynamics_batch(P, q, qd, sig2)
    assert (index, status) == (-1, core.OK)
    worst_fwd = rel(a_c, acc, axis=1)
    single = np.array([core.forward_dynamics(P, q[k], qd[k], sig2[k])[0] for k in range(len(q))])
    worst_fwd = max(worst_fwd, rel(single, acc, axis=1))

    worst_kin, worst_cond = 0.0, 0.0
    for k in range(len(q)):
        l, ld, om = D.leg_state(model, q[k], qd[k])
        lc, ldc, omc, st = core.leg_state(P, q[k], qd[k])
        assert st == core.OK
        J = _scaled_jacobian(p, q[k])
        Jc, st = core.jacobian(P, q[k], scaled=True)
        kin = inverse_kinematics(model, q[k], with_cond=False)
        Mt = np.empty((6, 6))
        leg = np.zeros((6, 3))
        leg[:, 0] = kin.lengths
        twist_mass_matrix(p, kin.rotation, kin.unit_vectors, kin.lever_arms, leg, Mt)
        Mc, st = core.mass_matrix(P, q[k])
        J1, _ = core.jacobian(P, q[k], scaled=False)
        worst_kin = max(worst_kin, rel(lc, l), rel(ldc, ld), rel(omc, om), rel(Jc, J),
                        rel(Mc, Mt), rel(J1, kin.jacobian))
        c_py = condition_number(model, q[k])
        c_c, st = core.condition_number(P, q[k])
        assert st == core.OK
        worst_cond = max(worst_cond, abs(c_c - c_py) / c_py)
    record(f"native inverse [{cid}]", worst, TOL)
    record(f"native parts [{cid}]", worst_parts, TOL)
    record(f"native forward [{cid}]", worst_fwd, TOL)
    record(f"native kinematics, J, M_nu [{cid}]", worst_kin, TOL)
    record(f"native cond(J) [{cid}]", worst_cond, 1e-10)
    assert worst <= TOL and worst_parts <= TOL and worst_fwd <= TOL, (worst, worst_parts,
                                                                      worst_fwd)
    assert worst_kin <= TOL, worst_kin
    assert worst_cond <= 1e-10, worst_cond


def test_condition_number_towards_fichters_singularity():
    """cond(J) on the yaw move onto Fichter's singular pose (scenes/extreme/singular_move):
    C (one-sided Jacobi) equals numpy's SVD to 1e-10 relative while cond <= 3e4; closer in,
    both carry the relative error eps * cond of the smallest singular value, so the test
    asks 1e-15 * cond, and at the singular pose both lie far above COND_LIMIT."""
    from stewart_fmu.kinematics import COND_LIMIT

    model = load_scene(SCENES_DIR / "extreme" / "singular_move.toml")
    P = core.native_params(model.params)
    worst = 0.0
    for d in (0.3, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
        q = model.home + np.array([0, 0, 0, 0, 0, np.pi / 2 - d])
        c_py = condition_number(model, q)
        c_c, st = core.condition_number(P, q)
        assert st == core.OK
        err = abs(c_c - c_py) / c_py
        if c_py <= 3e4:
            worst = max(worst, err)
        assert err <= max(1e-10, 1e-15 * c_py), (d, c_py, c_c)
    record("native cond(J) towards the singularity (cond <= 3e4)", worst, 1e-10)
    q = model.home + np.array([0, 0, 0, 0, 0, np.pi / 2])
    c_c, _ = core.condition_number(P, q)
    assert c_c > COND_LIMIT and condition_number(model, q) > COND_LIMIT
    nan_q = q.copy()
    nan_q[0] = np.nan
    assert core.condition_number(P, nan_q) == (np.inf, core.NONFINITE)


def bad_rows(model, q, qd, qdd):
    """(label, row index, modified q, qd, qdd) for a NaN row, a stroke violation, a singular
    pose and an infinite acceleration."""
    out = []
    n = len(q)
    for label, k in (("nan", n // 2), ("stroke", 3), ("singular", n - 2), ("inf", 1)):
        Q, QD, QDD = q.copy(), qd.copy(), qdd.copy()
        if label == "nan":
            QD[k, 2] = np.nan
        elif label == "stroke":
            Q[k, 2] += 10.0 * (model.leg_max if np.isfinite(model.leg_max or np.inf) else 1.0)
        elif label == "singular":
            # Fichter's singular pose of the micro geometry: yaw by +90 degrees at home
            Q[k] = model.home + np.array([0, 0, 0, 0, 0, np.pi / 2])
        else:
            QDD[k, 0] = np.inf
        out.append((label, k, Q, QD, QDD))
    return out


@pytest.mark.parametrize("spec", ["micro", "sim"])
def test_batches_report_the_first_bad_sample_as_numba(spec):
    """A NaN row, a stroke violation, a singular pose (micro: yaw +90 deg) and an inf input:
    the batch calls return the same first bad index and status as the numba batch kernels,
    and the rows before it equal numba's."""
    model = level_model(spec, "full")
    P = core.native_params(model.params)
    q, qd, qdd = random_states(spec, 12, seed=5)
    seen = set()
    for label, k, Q, QD, QDD in bad_rows(model, q, qd, qdd):
        out = np.empty((len(Q), 6))
        ref = D._inverse_batch(model.params, Q, QD, QDD, out)
        s_c, index, status = core.inverse_dynamics_batch(P, Q, QD, QDD)
        assert (index, status) == ref, (label, index, status, ref)
        assert np.array_equal(s_c[:index], out[:index])
        parts = np.empty((len(Q), 6, 6))
        ref_p = D._parts_batch(model.params, Q, QD, QDD, parts)
        _, index_p, status_p = core.inverse_dynamics_parts_batch(P, Q, QD, QDD)
        assert (index_p, status_p) == ref_p, label
        sig = np.where(np.isfinite(QDD), 1.0, QDD)   # forward: the bad row through sigma
        ref_f = D._forward_batch(model.params, Q, QD, sig, np.empty((len(Q), 6)))
        _, index_f, status_f = core.forward_dynamics_batch(P, Q, QD, sig)
        assert (index_f, status_f) == ref_f, label
        single = core.inverse_dynamics(P, Q[k], QD[k], QDD[k])[1]
        assert single == ref[1]
        seen.add((label, ref[1]))
    expected = {("nan", core.NONFINITE), ("stroke", core.STROKE), ("inf", core.NONFINITE)}
    assert expected <= seen, seen
    if spec == "micro":
        assert ("singular", core.SINGULAR) in seen, seen


# --- plant: derivative, energy, advances -------------------------------------------------------

PLANT_CASES = [(f"{f.parent.name}/{f.stem}", str(f), None) for f in FILES] + [
    (f"micro-{lv}", "micro", lv) for lv in LEVELS if lv != "full"]


def plant_state(model, q, qd, seed):
    """A 12 or 24 state at (q, qd) with the hold forces plus a random push, and that force."""
    F = D.inverse_dynamics(model, q, np.zeros(6), np.zeros(6))
    F = F + 0.05 * np.abs(F).max() * np.random.default_rng(seed).uniform(-1, 1, 6)
    y = initial_state(model, q, qd, F)
    if model.transmission is not None:
        y[12:18] += 1e-7 * np.random.default_rng(seed + 1).uniform(-1, 1, 6)
    return y, F


@pytest.mark.parametrize("cid,spec,level", PLANT_CASES, ids=[c[0] for c in PLANT_CASES])
def test_plant_kernels_match_numba(cid, spec, level):
    """initial_state, derivative (12 and 24 states), spring forces, energy terms and the step's
    power balance equal numba's to 1e-12 relative; rk4, euler and dopri5 advances over 1 ms and
    50 ms give numba's state (1e-12 relative to max|y|), status, dopri5's next step guess and
    evaluation counts."""
    model, (q, qd, _) = case_states(spec, level, 3, seed=21)
    p = model.params
    P = core.native_params(p)
    worst, worst_adv = 0.0, 0.0
    statuses = []
    for k in range(len(q)):
        y, F = plant_state(model, q[k], 0.3 * qd[k], seed=k)
        yc = core.initial_state(P, q[k], 0.3 * qd[k], F)
        y_ref = initial_state(model, q[k], 0.3 * qd[k], F)
        worst = max(worst, rel(yc, y_ref))
        dy, st = I.derivative(p, y, F)
        dyc, stc = core.derivative(P, y, F)
        assert stc == st
        worst = max(worst, rel(dyc[6:12], dy[6:12]), rel(dyc, dy))
        if model.transmission is not None:
            f_c, _ = core.spring_forces(P, y)
            worst = max(worst, rel(f_c, spring_forces(model, y)))
        pl = np.empty(core.N_PARAMS)
        core.lib.stewart_leg_side_params(P.ptr, core.ffi.from_buffer(pl))
        assert np.array_equal(pl, leg_side_params(p))
        e = E.energy_terms(model, y)
        ec = core.energy_terms(P, y)
        worst = max(worst, rel(ec, e))
        for method, max_step in (("rk4", 1e-3), ("euler", 1e-4), ("dopri5", 1e-3)):
            for h in (1e-3, 5e-2):
                o = core.options(method, max_step=max_step)
                y1, y1c = np.full_like(y, np.nan), np.full_like(y, np.nan)
                if method == "dopri5":
                    guess = 2e-4
                    ref = I.dopri5_advance(p, y, y1, F, h, guess, 1e-8, 1e-10, max_step,
                                           10_000, I.DOPRI5_A, I.DOPRI5_E)
                    st, g, ev = core.advance(P, o, y, y1c, F, h, guess)
                    assert (st, ev) == (ref[0], 1 + 6 * (ref[2] + ref[3])), (method, h)
                    assert abs(g - ref[1]) <= TOL * ref[1], (g, ref[1])
                else:
                    n = max(1, int(np.ceil(h / max_step - 1e-9)))
                    fn = I.rk4_advance if method == "rk4" else I.euler_advance
                    ref_st = fn(p, y, y1, F, h, n)
                    st, _, ev = core.advance(P, o, y, y1c, F, h)
                    assert (st, ev) == (ref_st, n * (4 if method == "rk4" else 1)), (method, h)
                statuses.append(st)
                if st == core.OK:
                    worst_adv = max(worst_adv, rel(y1c, y1))
                    e0 = E.energy_terms(model, y)
                    e1, e1c = np.empty(9), np.empty(9)
                    ref = step_energy(p, y1, e0, e1, F, ENERGY_TOL, h)
                    got = core.step_energy(P, y1c, e0, e1c, F, ENERGY_TOL, h)
                    assert got[0] == ref[0]
                    worst = max(worst, rel(e1c, e1),
                                abs(got[1] - ref[1]) / max(abs(ref[2]), abs(ref[1]), 1e-300),
                                abs(got[2] - ref[2]) / max(abs(ref[2]), 1e-300))
    record(f"native plant kernels [{cid}]", worst, TOL)
    record(f"native advances [{cid}]", worst_adv, TOL)
    assert worst <= TOL, worst
    assert worst_adv <= TOL, worst_adv
    assert core.OK in statuses


def plant_for(model, method, max_step, y0_q, F):
    plant = Plant(model, I.IntegratorOptions(method=method, max_step=max_step))
    plant.set_force(F)
    plant.set_initial(q=y0_q)
    plant.enter_initialization_mode()
    plant.exit_initialization_mode()
    return plant


@pytest.mark.parametrize("scene,method,max_step", [
    ("micro_manipulator.toml", "rk4", 1e-3), ("micro_manipulator.toml", "dopri5", 1e-3),
    ("micro_manipulator.toml", "euler", 1e-4), ("stiff/compliant.toml", "rk4", 1e-4),
    ("stiff/compliant.toml", "dopri5", 1e-3), ("motion_simulator.toml", "rk4", 1e-3)])
def test_stewart_step_follows_plant_do_step(scene, method, max_step):
    """stewart_data_step over 30 communication steps of 1 ms equals Plant.do_step (same state
    to 1e-12 relative, same evaluations and dopri5 step guess) under a held force that pushes
    the platform off its hold."""
    model = load_scene(SCENES_DIR / scene)
    P = core.native_params(model.params)
    y_hold, F_hold = hold_state(model)
    F = F_hold + 0.02 * np.abs(F_hold).max() * np.array([1, -1, 0.5, 0.2, -0.7, 0.1])
    plant = plant_for(model, method, max_step, model.home, F)
    o = core.options(method, max_step=max_step)
    d = core.ffi.new("stewart_data *")
    q0 = np.ascontiguousarray(model.home, dtype=float)
    core.lib.stewart_data_init(P.ptr, o, core.ffi.from_buffer("double[]", q0),
                               core.ffi.from_buffer("double[]", np.zeros(6)),
                               core.ffi.from_buffer("double[]", F), 0.0, d)
    worst = 0.0
    for k in range(30):
        plant.do_step(plant.time, 1e-3)
        st = core.lib.stewart_data_step(P.ptr, o, d, core.ffi.from_buffer("double[]", F), 1e-3)
        assert st == core.OK, (k, st)
        yc = np.frombuffer(core.ffi.buffer(d.y), dtype=float)[:model.state_size]
        worst = max(worst, rel(yc, plant._y))
        assert d.evaluations == plant.evaluations
        if method == "dopri5":
            assert abs(d.step_guess - plant._step_guess) <= TOL * plant._step_guess
    assert abs(d.t - plant.time) <= 1e-15
    record(f"native stewart_step = Plant.do_step [{scene}-{method}]", worst, TOL)
    assert worst <= TOL, worst


def test_stewart_step_detects_energy_gain_where_the_plant_raises():
    """RK4 with max_step 1 ms on scenes/stiff/compliant.toml (stable step ~0.35 ms): a 1 ms
    step from the hold with a small heave velocity gains energy; stewart_step returns
    UNSTABLE (y0 untouched) with numba's excess and allowed, and Plant.do_step raises
    IntegrationError on the same step."""
    model = load_scene(SCENES_DIR / "stiff" / "compliant.toml")
    P = core.native_params(model.params)
    y0, F = hold_state(model)
    y0 = y0.copy()
    y0[8] += 1e-3
    o = core.options("rk4", max_step=1e-3)
    e0 = core.energy_terms(P, y0)
    y1, e1 = np.empty(24), np.empty(9)
    keep = y0.copy()
    st, _, ev, excess, allowed = core.step(P, o, y0, y1, F, 1e-3, e0, e1)
    assert st == core.UNSTABLE == ENERGY_GAIN and ev == 4
    assert np.array_equal(y0, keep)
    ref_y1 = np.empty(24)
    assert I.rk4_advance(model.params, y0, ref_y1, F, 1e-3, 1) == 0
    ok, ref_ex, ref_al = step_energy(model.params, ref_y1, e0, np.empty(9), F, ENERGY_TOL,
                                     1e-3)
    assert ok and ref_ex > ref_al
    assert abs(excess - ref_ex) <= TOL * abs(ref_ex) and abs(allowed - ref_al) <= TOL * ref_al
    plant = plant_for(model, "rk4", 1e-3, model.home, F)
    plant._y = y0.copy()
    plant._energy = None
    with pytest.raises(IntegrationError):
        plant.do_step(plant.time, 1e-3)
    # the same step with max_step below the stability limit passes
    st, *_ = core.step(P, core.options("rk4", max_step=1e-4), y0, y1, F, 1e-3, e0, e1)
    assert st == core.OK


def test_stewart_step_reports_a_non_finite_state():
    """Platform only, at home with vx = the largest double and a rack force of 1e302 N: every
    right-hand side is finite (no legs, drive or friction see the leg rates), but the Euler
    update overflows vx. stewart_step returns STATE_NONFINITE (103, distinct from an input's
    NONFINITE), as stability.step_energy reports the state not finite; y0 is untouched."""
    model = level_model("micro", "platform_only")
    P = core.native_params(model.params)
    y0 = np.r_[model.home, np.zeros(6)]
    y0[6] = np.finfo(float).max
    keep = y0.copy()
    e0 = core.energy_terms(P, y0)
    found = False
    for sign in (1.0, -1.0):
        F = sign * np.full(6, 1e302)
        y1, ref_y1 = np.empty(12), np.empty(12)
        st, *_ = core.step(P, core.options("euler"), y0, y1, F, 1e-3, e0, np.empty(9))
        assert I.euler_advance(model.params, y0, ref_y1, F, 1e-3, 1) == I.OK
        assert np.array_equal(y1, ref_y1, equal_nan=True)
        ok, _, _ = step_energy(model.params, ref_y1, e0, np.empty(9), F, ENERGY_TOL, 1e-3)
        assert core.step_energy(P, y1, e0, np.empty(9), F, ENERGY_TOL, 1e-3)[0] == ok
        if not ok:
            assert st == core.STATE_NONFINITE == STATE_NONFINITE
            found = True
    assert found
    assert np.array_equal(y0, keep)


@pytest.mark.parametrize("method", ["rk4", "euler", "dopri5"])
def test_the_step_bounds_its_work(method):
    """max_steps bounds the internal steps of every method: rk4 / euler refuse more than
    max_steps fixed sub-steps (TOO_MANY_STEPS, no evaluation), dopri5 stops after max_steps
    attempts with numba's status and step guess."""
    model = load_scene(SCENES_DIR / "micro_manipulator.toml")
    P = core.native_params(model.params)
    y0, F = hold_state(model)
    e0 = core.energy_terms(P, y0)
    y1 = np.empty(12)
    o = core.options(method, max_step=1e-3, max_steps=10)
    st, g, ev, _, _ = core.step(P, o, y0, y1, F, 5e-2, e0, np.empty(9), 1e-3)
    assert st == core.TOO_MANY_STEPS
    if method == "dopri5":
        ref = I.dopri5_advance(model.params, y0, np.empty(12), F, 5e-2, 1e-3, 1e-8, 1e-10,
                               1e-3, 10, I.DOPRI5_A, I.DOPRI5_E)
        assert ref[0] == I.TOO_MANY_STEPS and ev == 1 + 6 * (ref[2] + ref[3])
        assert g == ref[1]
    else:
        assert ev == 0
    o = core.options(method, max_step=1e-3, max_steps=50)
    st, *_ = core.step(P, o, y0, y1, F, 5e-2, e0, np.empty(9), 1e-3)
    assert st == core.OK
    st, *_ = core.step(P, core.options(method, max_step=1e-9, max_steps=10_000), y0, y1, F,
                       1.0, e0, np.empty(9))
    assert st == core.TOO_MANY_STEPS


# --- physics on the C core, the tolerances of test_dynamics_physics.py -------------------------

PHYS_CASES = [(s, lv) for s in ("micro", "sim") for lv in LEVELS] + [("micro", "full+coulomb")]
PHYS_IDS = [f"{s}-{lv}" for s, lv in PHYS_CASES]


@pytest.mark.parametrize("name,level", PHYS_CASES, ids=PHYS_IDS)
def test_native_power_balance(name, level):
    """sum_i sigma_i ldot_i = dE/dt + friction power to 1e-8 relative, sigma from the C core,
    the rest from the Newton-Euler reference's jets (as test_power_balance_along_smooth_...)."""
    tol = 1e-8
    data, model = case(name, level)
    q, qd, qdd = trajectory_samples(name, seeds=(0, 1, 2), n=40)
    sigma, index, status = core.inverse_dynamics_batch(model.params, q, qd, qdd)
    assert (index, status) == (-1, core.OK)
    coulomb = model.friction is not None and model.friction.coulomb > 0
    worst, used = 0.0, 0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])
        if coulomb and np.abs(ref["ldot"]).min() < 1e-9:
            continue
        power = sigma[k] * ref["ldot"]
        scale = np.abs(power).sum() + abs(ref["energy_rate"]) + abs(ref["friction_power"])
        worst = max(worst, abs(power.sum() - ref["energy_rate"] - ref["friction_power"]) / scale)
        used += 1
    assert used >= 100
    record(f"native 1 power balance [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name,level", PHYS_CASES, ids=PHYS_IDS)
def test_native_matches_newton_euler(name, level):
    """C inverse dynamics equals the Newton-Euler reference to 1e-9 relative (max|sigma|)."""
    tol = 1e-9
    data, model = case(name, level)
    q, qd, qdd = random_states(name, 40, seed=100 + list(LEVELS).index(level)
                               if level in LEVELS else 109)
    sigma, index, status = core.inverse_dynamics_batch(model.params, q, qd, qdd)
    assert (index, status) == (-1, core.OK)
    worst = 0.0
    for k in range(len(q)):
        ref = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])["sigma"]
        worst = max(worst, np.abs(sigma[k] - ref).max() / np.abs(ref).max())
    record(f"native 2 sigma vs Newton-Euler [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


@pytest.mark.parametrize("name,level", PHYS_CASES[:-1], ids=PHYS_IDS[:-1])
def test_native_inverse_forward_round_trip(name, level):
    """forward(inverse(qdd)) = qdd and inverse(forward(sigma)) = sigma to 1e-9 relative, on the
    C core (translational and rotational parts each relative to their largest entry)."""
    tol = 1e-9
    _, model = case(name, level)
    P = core.native_params(model.params)
    q, qd, qdd = random_states(name, 50, seed=300 + list(LEVELS).index(level))
    sigma, _, st1 = core.inverse_dynamics_batch(P, q, qd, qdd)
    back, _, st2 = core.forward_dynamics_batch(P, q, qd, sigma)
    assert st1 == st2 == core.OK
    err_t = np.abs(back[:, :3] - qdd[:, :3]).max(axis=1) / np.abs(qdd[:, :3]).max(axis=1)
    err_r = np.abs(back[:, 3:] - qdd[:, 3:]).max(axis=1) / np.abs(qdd[:, 3:]).max(axis=1)
    sig2 = np.random.default_rng(5).uniform(-1.0, 1.0, q.shape) * np.abs(sigma).max()
    qdd2, _, _ = core.forward_dynamics_batch(P, q, qd, sig2)
    sig2_back, _, _ = core.inverse_dynamics_batch(P, q, qd, qdd2)
    worst = max(err_t.max(), err_r.max(),
                (np.abs(sig2_back - sig2).max(axis=1) / np.abs(sig2).max(axis=1)).max())
    record(f"native 3 inverse <-> forward [{name}-{level}]", worst, tol)
    assert worst <= tol, worst


def test_run_holder_steps_as_stewart_step():
    """core.Run (a stewart_data in C with numpy views): 20 steps of 1 ms, then a run of 20
    more in one call, equal 40 stewart_step calls on numpy arrays (bit for bit)."""
    model = load_scene(SCENES_DIR / "micro_manipulator.toml")
    P = core.native_params(model.params)
    _, F = hold_state(model)
    F = F + np.array([0.5, -0.5, 0.2, 0.0, 0.1, -0.3])
    o = core.options("dopri5", max_step=1e-3)
    run = core.Run(P, o, model.home, rack=F)
    y = core.initial_state(P, model.home, np.zeros(6), F)
    e, y1, e1, guess = core.energy_terms(P, y), np.empty(12), np.empty(9), 1e-3
    assert np.array_equal(run.y, y) and np.array_equal(run.energy, e)
    for k in range(40):
        st, guess, *_ = core.step(P, o, y, y1, F, 1e-3, e, e1, guess)
        assert st == core.OK
        y, y1, e, e1 = y1, y, e1, e
        if k < 20:
            assert run.step(1e-3) == core.OK
        elif k == 39:
            assert run.run(1e-3, 20) == (core.OK, 20)
    assert np.array_equal(run.y, y) and np.array_equal(run.energy, e)
    assert run.data.step_guess == guess and abs(run.time - 0.04) < 1e-15


def test_coulomb_friction_at_rest_is_numba_sign():
    """The motion simulator (Coulomb 150 N) at rest, ldot = +0 and -0, and at a NaN rate:
    the C friction term takes np.sign as numba compiles it (+-0 and NaN pass through), so
    sigma equals numba's bit for bit, signs of zero included, and the NaN row is NONFINITE."""
    model = level_model("sim", "full")
    P = core.native_params(model.params)
    q = np.ascontiguousarray(model.home)
    for qd in (np.zeros(6), -np.zeros(6)):
        ref, st = D._inverse_one(model.params, q, qd, np.zeros(6))
        got, st_c = core.inverse_dynamics(P, q, qd, np.zeros(6))
        assert st == st_c == core.OK
        assert np.array_equal(got, ref) and np.array_equal(np.signbit(got), np.signbit(ref))
    qd = np.zeros(6)
    qd[0] = np.nan
    assert core.inverse_dynamics(P, q, qd, np.zeros(6))[1] == D._inverse_one(
        model.params, q, qd, np.zeros(6))[1] == core.NONFINITE
