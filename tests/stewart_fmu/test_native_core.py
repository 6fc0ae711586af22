"""The C core (stewart_fmu/native, stewart.h) through its thin wrappers (native/core.py).

What the public API's tests do not reach: cond(J) by the core's SVD against numpy's towards a
singular pose; the plant step's refusals (energy gain where Plant raises, a non-finite state,
the bound on its work) and the run holder (core.Run) against single steps. The physics
(tests/stewart_fmu/test_dynamics_physics.py and the others) runs on this core through the public
API, and tests/stewart_fmu/test_plant_reference.py holds it to its recorded reference.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import integrators as I
from stewart_fmu import load_scene
from stewart_fmu.errors import IntegrationError
from stewart_fmu.native import core
from stewart_fmu.plant import Plant
from stewart_fmu.stability import hold_state
from tests.helpers import level_model, record

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"


def test_condition_number_towards_fichters_singularity():
    """cond(J) on the yaw move onto Fichter's singular pose (scenes/extreme/singular_move.toml):
    C (linalg.c's sw_condition) equals numpy's SVD of the C core's scaled J to 1e-10 relative while
    cond <= 3e4; closer in, both carry the relative error eps * cond of the smallest singular
    value, so the test asks 1e-15 * cond, and at the singular pose both lie far above
    COND_LIMIT."""
    from stewart_fmu.kinematics import COND_LIMIT

    model = load_scene(SCENES_DIR / "extreme" / "singular_move.toml")
    P = core.native_params(model.params)
    worst = 0.0
    for d in (0.3, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
        q = model.home + np.array([0, 0, 0, 0, 0, np.pi / 2 - d])
        c_py = float(np.linalg.cond(core.jacobian(P, q, scaled=True)[0]))
        c_c, st = core.condition_number(P, q)
        assert st == core.OK
        err = abs(c_c - c_py) / c_py
        if c_py <= 3e4:
            worst = max(worst, err)
        assert err <= max(1e-10, 1e-15 * c_py), (d, c_py, c_c)
    record("native cond(J) towards the singularity (cond <= 3e4)", worst, 1e-10)
    q = model.home + np.array([0, 0, 0, 0, 0, np.pi / 2])
    c_c, _ = core.condition_number(P, q)
    assert c_c > COND_LIMIT and np.linalg.cond(core.jacobian(P, q, scaled=True)[0]) > COND_LIMIT
    nan_q = q.copy()
    nan_q[0] = np.nan
    assert core.condition_number(P, nan_q) == (np.inf, core.NONFINITE)



def plant_for(model, method, max_step, y0_q, F):
    plant = Plant(model, I.IntegratorOptions(method=method, max_step=max_step))
    plant.set_force(F)
    plant.set_initial(q=y0_q)
    plant.enter_initialization_mode()
    plant.exit_initialization_mode()
    return plant


def test_stewart_step_detects_energy_gain_where_the_plant_raises():
    """RK4 with max_step 1 ms on scenes/stiff/compliant.toml (stable step ~0.35 ms): a 1 ms
    step from the hold with a small heave velocity gains energy; stewart_step returns
    UNSTABLE (y0 untouched) with the excess and allowed of its own check (step_energy on the
    advanced state), and Plant.do_step raises IntegrationError on the same step."""
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
    assert st == core.UNSTABLE and ev == 4
    assert np.array_equal(y0, keep)
    ref_y1 = np.empty(24)
    assert I.advance(P, I.IntegratorOptions(max_step=1e-3), y0, ref_y1, F, 1e-3) == core.OK
    ok, ref_ex, ref_al = core.step_energy(P, ref_y1, e0, np.empty(9), F, core.ENERGY_TOL, 1e-3)
    assert ok and ref_ex > ref_al
    assert excess == ref_ex and allowed == ref_al
    plant = plant_for(model, "rk4", 1e-3, model.home, F)
    plant.set_state(replace(plant.get_state(), y=y0.copy()))
    with pytest.raises(IntegrationError):
        plant.do_step(plant.time, 1e-3)
    # the same step with max_step below the stability limit passes
    st, *_ = core.step(P, core.options("rk4", max_step=1e-4), y0, y1, F, 1e-3, e0, e1)
    assert st == core.OK


def test_stewart_step_reports_a_non_finite_state():
    """Platform only, at home with vx = the largest double and a rack force of 1e302 N: every
    right-hand side is finite (no legs, drive or friction see the leg rates), but the Euler
    update overflows vx. stewart_step returns STATE_NONFINITE (103, distinct from a non-finite
    input's NONFINITE), as its check (step_energy) reports the advanced state not finite; y0
    is untouched."""
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
        assert I.advance(P, I.IntegratorOptions(method="euler"), y0, ref_y1, F, 1e-3) == core.OK
        assert np.array_equal(y1, ref_y1, equal_nan=True)
        ok, _, _ = core.step_energy(P, ref_y1, e0, np.empty(9), F, core.ENERGY_TOL, 1e-3)
        if not ok:
            assert st == core.STATE_NONFINITE
            found = True
    assert found
    assert np.array_equal(y0, keep)


@pytest.mark.parametrize("method", ["rk4", "euler", "dopri5"])
def test_the_step_bounds_its_work(method):
    """max_steps bounds the internal steps of every method: rk4 / euler refuse more than
    max_steps fixed sub-steps (TOO_MANY_STEPS, no evaluation), dopri5 stops after max_steps
    attempts (its evaluations: 1 + 6 per attempt)."""
    model = load_scene(SCENES_DIR / "micro_manipulator.toml")
    P = core.native_params(model.params)
    y0, F = hold_state(model)
    e0 = core.energy_terms(P, y0)
    y1 = np.empty(12)
    o = core.options(method, max_step=1e-3, max_steps=10)
    st, g, ev, _, _ = core.step(P, o, y0, y1, F, 5e-2, e0, np.empty(9), 1e-3)
    assert st == core.TOO_MANY_STEPS
    if method == "dopri5":
        assert ev >= 1 + 6 * 10 and (ev - 1) % 6 == 0 and 0 < g <= 1e-3
    else:
        assert ev == 0
    o = core.options(method, max_step=1e-3, max_steps=50)
    st, *_ = core.step(P, o, y0, y1, F, 5e-2, e0, np.empty(9), 1e-3)
    assert st == core.OK
    st, *_ = core.step(P, core.options(method, max_step=1e-9, max_steps=10_000), y0, y1, F,
                       1.0, e0, np.empty(9))
    assert st == core.TOO_MANY_STEPS


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


def test_non_finite_rates_at_rest_are_refused():
    """The motion simulator (Coulomb 150 N) at rest, ldot = +0 and -0: finite forces whose
    friction term passes the signed zero through (np.sign's convention); a NaN rate is
    NONFINITE."""
    model = level_model("sim", "full")
    P = core.native_params(model.params)
    q = np.ascontiguousarray(model.home)
    plus, st1 = core.inverse_dynamics(P, q, np.zeros(6), np.zeros(6))
    minus, st2 = core.inverse_dynamics(P, q, -np.zeros(6), np.zeros(6))
    assert st1 == st2 == core.OK and np.array_equal(plus, minus)
    qd = np.zeros(6)
    qd[0] = np.nan
    assert core.inverse_dynamics(P, q, qd, np.zeros(6))[1] == core.NONFINITE


def test_every_status_code_has_one_name_and_its_words():
    """The one status table (native/src/status.c): every status code stewart.h declares has a
    name (its STEWART_ constant's) and words, and stewart_fmu.status reads them from there."""
    import re

    from stewart_fmu import status

    header = (Path(__file__).resolve().parents[2] / "stewart_fmu" / "native" / "include"
              / "stewart.h").read_text()
    declared = {name: int(value) for name, value in
                re.findall(r"\bSTEWART_(\w+)\s*=\s*(\d+)\s*,?\s*(?:/\*|\n|$)", header)
                if not name.startswith(("PART_", "PH_", "CALL_", "RK4", "EULER", "DOPRI5"))}
    assert {"OK", "STROKE", "UNSTABLE", "BAD_CALL", "STATE_INVALID"} <= set(declared)
    assert status.NAME == {code: name for name, code in declared.items()}
    for code in declared.values():
        assert status.WHY[code] == core.ffi.string(core.lib.stewart_status_why(code)).decode()
    assert status.why(99) == "status 99"  # not a status: its number
