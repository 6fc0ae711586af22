"""The in-process FMI co-simulation component: life cycle, rollback, integrators, energy."""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stewart_fmu import inverse_dynamics, inverse_kinematics, load_scene, scene_from_dict
from stewart_fmu.errors import TrajectoryError
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.plant import CallSequenceError, Plant, StepRejected
from tests.reference.newton_euler import reference_inverse_dynamics  # noqa: E402

SCENES = Path(__file__).resolve().parents[2] / "scenes"
H = 1e-3


def _scene(name: str = "micro_manipulator.toml", drop: tuple[str, ...] = ()) -> dict:
    data = tomllib.loads((SCENES / name).read_text())
    return {k: v for k, v in data.items() if k not in drop}


def _hold(model) -> np.ndarray:
    """Rack forces that hold the platform at home."""
    return inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))


def _started(model, method: str = "rk4", **opts) -> Plant:
    plant = Plant(model, IntegratorOptions(method=method, **opts))
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    plant.exit_initialization_mode()
    return plant


def _wiggle(t: float, model) -> np.ndarray:
    """Hold forces plus a small multi-leg sinusoid (N)."""
    scale = 0.02 * float(np.max(np.abs(_hold(model))))
    return _hold(model) + scale * np.sin(2 * np.pi * np.array([3, 4, 5, 6, 7, 8]) * t)


def _run(plant: Plant, steps: int, h: float = H) -> np.ndarray:
    """Step with _wiggle inputs; returns the (steps, 12) states after each step."""
    out = []
    for _ in range(steps):
        plant.set_force(_wiggle(plant.time, plant.model))
        plant.do_step(plant.time, h)
        out.append(np.r_[plant.outputs.q, plant.outputs.qd])
    return np.array(out)


# --- life cycle and call sequence ---------------------------------------------------------

def test_call_sequence_is_checked():
    """Out-of-order calls and bad step arguments raise CallSequenceError (fmi2Error)."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = Plant(model)
    with pytest.raises(CallSequenceError, match="do_step is not allowed in phase 'instantiated'"):
        plant.do_step(0.0, H)
    with pytest.raises(CallSequenceError, match="exit_initialization_mode"):
        plant.exit_initialization_mode()
    plant.setup_experiment(0.5)
    plant.enter_initialization_mode()
    with pytest.raises(CallSequenceError, match="setup_experiment"):
        plant.setup_experiment(0.0)
    plant.exit_initialization_mode()
    with pytest.raises(CallSequenceError, match="set_initial"):
        plant.set_initial(q=model.home)
    for bad in (0.0, -H, math.nan, math.inf):
        with pytest.raises(CallSequenceError, match="step_size"):
            plant.do_step(0.5, bad)
    with pytest.raises(CallSequenceError, match="current_time 0.0 is not the component's time 0.5"):
        plant.do_step(0.0, H)
    plant.do_step(0.5, H)
    assert plant.time == 0.5 + H
    plant.terminate()
    with pytest.raises(CallSequenceError, match="terminated"):
        plant.do_step(plant.time, H)


def test_bad_inputs_are_rejected_and_the_inputs_held_are_kept():
    """Non-finite or mis-shaped inputs raise TrajectoryError naming the input; nothing changes."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model)
    plant.set_force(np.ones(6))
    for bad, why in (([np.nan] + [0.0] * 5, "finite"), ([1.0] * 5, "six numbers"),
                     (["a"] * 6, "six numbers")):
        with pytest.raises(TrajectoryError, match=f"force must be {why}"):
            plant.set_force(bad)
    assert np.array_equal(plant.rack_force, np.ones(6))
    no_drive = Plant(scene_from_dict(_scene(drop=("drive",))))
    with pytest.raises(CallSequenceError, match="no \\[drive\\]"):
        no_drive.set_torque(np.ones(6))


def test_initial_pose_outside_the_stroke_is_refused():
    """exit_initialization_mode checks the initial pose: StrokeLimitError naming the legs."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = Plant(model)
    plant.enter_initialization_mode()
    plant.set_initial(q=model.home + np.r_[0, 0, 0.2, 0, 0, 0])
    with pytest.raises(Exception, match="outside the stroke"):
        plant.exit_initialization_mode()


# --- state: rollback, serialization, reset -----------------------------------------------

@pytest.mark.parametrize("method", ["rk4", "dopri5", "RK45"])
def test_rollback_reproduces_the_run_bit_for_bit(method):
    """get_state / set_state, and serialize / deserialize into a new Plant, repeat a run exactly."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model, method)
    _run(plant, 20)
    saved = plant.get_state()
    first = _run(plant, 30)
    plant.set_state(saved)
    assert np.array_equal(_run(plant, 30), first)
    other = Plant(model, IntegratorOptions(method=method))
    other.set_state(Plant.deserialize_state(Plant.serialize_state(saved)))
    assert np.array_equal(_run(other, 30), first)
    with pytest.raises(CallSequenceError, match="not a serialized plant state"):
        Plant.deserialize_state(b"garbage")


def test_serialized_state_refuses_corrupted_foreign_and_invalid_bytes():
    """The component's format: every single-bit flip, a truncation, an extension, the key of
    another model and a state with a NaN are refused (CallSequenceError naming the reason);
    the intact bytes load. set_state refuses a running state of the wrong size for the model."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model)
    _run(plant, 5)
    state = plant.get_state()
    blob = Plant.serialize_state(state)
    assert Plant.deserialize_state(blob).y.tolist() == state.y.tolist()
    for k in range(len(blob)):
        for bit in (0, 7):
            bad = bytearray(blob)
            bad[k] ^= 1 << bit
            with pytest.raises(CallSequenceError, match="not a serialized plant state: "):
                Plant.deserialize_state(bytes(bad))
    for bad, why in ((blob[:-1], "wrong size"), (blob + b"\0", "wrong size"),
                     (b"STWSTATE" + blob[8:16] + bytes(8) + blob[24:], "different model")):
        with pytest.raises(CallSequenceError, match=why):
            Plant.deserialize_state(bad)
    nan_y = state.y.copy()
    nan_y[3] = math.nan
    with pytest.raises(CallSequenceError, match="not finite"):
        Plant.deserialize_state(Plant.serialize_state(replace(state, y=nan_y)))
    with pytest.raises(CallSequenceError, match="not a state of this plant"):
        plant.set_state(replace(state, y=np.zeros(24)))
    assert np.array_equal(plant.get_state().y, state.y)


def test_call_rules_are_the_components_one_table():
    """Plant's refusals of out-of-order calls come from the component's rule table: every
    phase a call's refusal names is one stewart_allowed accepts, and no other."""
    from stewart_fmu.native.core import lib
    from stewart_fmu.plant import PHASES

    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = Plant(model)
    with pytest.raises(CallSequenceError) as info:
        plant.do_step(0.0, H)
    allowed = str(info.value).split("(allowed in: ")[1].rstrip(")").split(", ")
    assert allowed == [p for i, p in enumerate(PHASES) if lib.stewart_allowed(lib.STEWART_CALL_DO_STEP, i)]
    assert allowed == ["stepping"]


def test_reset_returns_to_a_fresh_component():
    """reset() then the same calls give the same results."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model)
    first = _run(plant, 25)
    plant.reset()
    assert plant.phase == "instantiated" and plant.time == 0.0
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    plant.exit_initialization_mode()
    assert np.array_equal(_run(plant, 25), first)


def test_torque_input_equals_rack_force():
    """tau at the motor acts as zeta / r * tau at the rack (1e-15 relative)."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    gain = model.drive.gear_ratio / model.drive.pinion_radius
    a, b = _started(model), _started(model)
    F = _hold(model) * 1.01
    a.set_force(F)
    b.set_torque(F / gain)
    for _ in range(50):
        a.do_step(a.time, H)
        b.do_step(b.time, H)
    assert np.allclose(a.outputs.q, b.outputs.q, rtol=0, atol=1e-15)


# --- outputs ------------------------------------------------------------------------------

def test_outputs_match_kinematics_and_parts_sum_to_the_rack_force():
    """Lengths, rates, twist equal inverse_kinematics (1e-15); parts sum to the force (1e-12)."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model)
    _run(plant, 40)
    out = plant.outputs
    kin = inverse_kinematics(model, out.q, out.qd)
    assert np.allclose(out.lengths, kin.lengths, rtol=0, atol=1e-15)
    assert np.allclose(out.rates, kin.rates, rtol=0, atol=1e-15)
    assert np.allclose(out.twist, np.r_[out.qd[:3], kin.omega], rtol=0, atol=1e-15)
    assert out.cond == pytest.approx(float(kin.cond), rel=1e-12)
    total = sum(out.parts.values())
    assert np.max(np.abs(total - plant.rack_force)) <= 1e-12 * np.max(np.abs(plant.rack_force))
    assert set(out.parts) == set(plant.parts)


# --- integrators --------------------------------------------------------------------------

def _final_state(model, method: str, steps: int = 200, h: float = H, **opts) -> np.ndarray:
    plant = _started(model, method, **opts)
    return _run(plant, steps, h)[-1]


def test_integrators_agree_with_a_tight_reference():
    """0.2 s of forced motion: each method against DOP853 at rtol 1e-12, within its tolerance.

    Stated tolerances (max abs error in q (m, rad) and qd): rk4 at 1 ms 1e-9; dopri5 at
    rtol 1e-10 1e-9; RK45, Radau, BDF, LSODA at rtol 1e-8 1e-6."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    ref = _final_state(model, "DOP853", rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(_final_state(model, "rk4") - ref)) < 1e-9
    assert np.max(np.abs(_final_state(model, "dopri5", rtol=1e-10, atol=1e-12) - ref)) < 1e-9
    for method in ("RK45", "Radau", "BDF", "LSODA"):
        err = np.max(np.abs(_final_state(model, method, rtol=1e-8, atol=1e-10) - ref))
        assert err < 1e-6, (method, err)


def test_rk4_converges_with_order_four():
    """Halving RK4's internal step divides the error by 2^4 (measured order within 0.2 of 4)."""
    model = scene_from_dict(_scene(drop=("friction",)))
    ref = _final_state(model, "DOP853", steps=40, h=5e-3, rtol=1e-13, atol=1e-15)
    errs = [np.max(np.abs(_final_state(model, "rk4", steps=40, h=5e-3, max_step=dt) - ref))
            for dt in (5e-3, 2.5e-3, 1.25e-3)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 4) < 0.2), (errs, orders)


@pytest.mark.parametrize("scene", ["micro_manipulator.toml", "motion_simulator.toml"])
def test_energy_is_conserved_under_constant_forces_without_friction(scene):
    """With constant rack forces F and no friction, E - sum F_i l_i is conserved (E: kinetic
    incl. drives + gravity potential, from the independent reference): drift < 1e-9 of the
    energy exchanged over 0.3 s with dopri5 at rtol 1e-12."""
    data = _scene(scene, drop=("friction",))
    model = scene_from_dict(data)
    plant = _started(model, "dopri5", rtol=1e-12, atol=1e-14)
    F = _hold(model) * 1.02
    plant.set_force(F)

    def invariant() -> tuple[float, float]:
        out = plant.outputs
        ref = reference_inverse_dynamics(data, out.q, out.qd, np.zeros(6))
        energy = ref["kinetic"] + ref["potential"]
        return energy - float(F @ out.lengths), ref["kinetic"]

    start, _ = invariant()
    worst, exchanged = 0.0, 0.0
    for _ in range(300):
        plant.do_step(plant.time, H)
        value, kinetic = invariant()
        worst, exchanged = max(worst, abs(value - start)), max(exchanged, kinetic)
    assert exchanged > 0
    assert worst <= 1e-9 * exchanged, (worst, exchanged)


def test_friction_dissipates():
    """With friction, E - sum F_i l_i never increases (beyond 1e-12 of the exchange)."""
    data = _scene()
    model = scene_from_dict(data)
    plant = _started(model, "dopri5", rtol=1e-12, atol=1e-14)
    F = _hold(model) * 1.02
    plant.set_force(F)
    values = []
    for _ in range(200):
        plant.do_step(plant.time, H)
        out = plant.outputs
        ref = reference_inverse_dynamics(data, out.q, out.qd, np.zeros(6))
        values.append(ref["kinetic"] + ref["potential"] - float(F @ out.lengths))
    assert np.all(np.diff(values) <= 1e-12 * np.ptp(values)), np.diff(values).max()
    assert values[-1] < values[0]


# --- rejected steps -----------------------------------------------------------------------

@pytest.mark.parametrize("method", ["rk4", "dopri5", "RK45"])
def test_step_into_the_stroke_limit_is_rejected_and_rolls_back(method):
    """Large forces drive a leg past its stroke: StepRejected names the time and the lengths;
    the state stays at the start of the step; rolled back to a saved state with smaller
    forces, the run carries on."""
    model = load_scene(SCENES / "micro_manipulator.toml")
    plant = _started(model, method)
    saved = plant.get_state()
    plant.set_force(np.full(6, 200.0))
    with pytest.raises(StepRejected) as info:
        for _ in range(1000):
            before = plant.get_state()
            plant.do_step(plant.time, H)
    err = info.value
    assert err.time == before.time and "a leg left its stroke" in str(err)
    assert f"t = {before.time!r} s" in str(err) and "leg lengths" in str(err)
    assert np.array_equal(plant.get_state().y, before.y) and plant.time == before.time
    plant.set_state(saved)
    plant.set_force(_hold(model))
    for _ in range(10):
        plant.do_step(plant.time, H)
    assert plant.time == pytest.approx(10 * H, abs=1e-15)
