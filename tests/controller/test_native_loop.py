"""The axis loop in C (controller/native/axis.c): the PID and motor-current arithmetic against
the formulas written out in Python (bit for bit, saturation, anti-windup and non-finite inputs
included), the C loop in chunks against one call, and the C loop against the Python loop
around InProcessPlant on the `run` reference (every recorded signal, bit for bit)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import controller.cosim as cosim
from controller.axis import AxisControllers, MotorCurrents
from controller.config import controller_config
from controller.cosim import run_closed_loop
from controller.design import tune_pid
from controller.drive import axis_model
from controller.moves import run_reference
from controller.plants import InProcessPlant
from stewart_fmu import load_scene
from tests.helpers import SCENE_FILES


def _pid_reference(kp, ki, kd, vmax, dt, integral, l_ref, ldot_ref, l, ldot, v_ff):
    v, sat = np.empty(6), np.empty(6, dtype=bool)
    for i in range(6):
        e = l_ref[i] - l[i]
        u = kp * e + ki * integral[i] + kd * (ldot_ref[i] - ldot[i]) + v_ff[i]
        out = min(max(u, -vmax), vmax)
        v[i], sat[i] = out, out != u
        if not (sat[i] and (e > 0) == (u > 0) and e != 0.0):
            integral[i] += e * dt
    return v, sat


def _currents_reference(R, Kt, emf, ilim, decay, mean_decay, current, v, ldot):
    torque, limited = np.empty(6), np.empty(6, dtype=bool)
    for i in range(6):
        steady = (v[i] - emf * ldot[i]) / R
        gap = current[i] - steady
        mean, end = steady + gap * mean_decay, steady + gap * decay
        limited[i] = abs(mean) > ilim
        current[i] = min(max(end, -ilim), ilim)
        torque[i] = Kt * min(max(mean, -ilim), ilim)
    return torque, limited


def _micro():
    model = load_scene(SCENE_FILES["micro"])
    config = controller_config(model)
    axis = axis_model(model, config.motor, config.load_mass)
    return model, config, axis, tune_pid(axis, config.bandwidth, config.phase_margin)


def test_pid_and_currents_equal_their_formulas():
    """AxisControllers.step and MotorCurrents.step (C) equal the formulas in Python bit for
    bit over 2000 random samples that saturate the voltage and the current about half the
    time, with integral and current carried; a NaN measurement gives NaN outputs as Python's
    min / max do (the NaN passes through), flagged saturated (NaN != NaN), the integral held."""
    _, config, axis, gains = _micro()
    ctrl, motors = AxisControllers(gains, axis, config.dt), MotorCurrents(axis, config.dt)
    vmax, ilim = axis.motor.voltage_limit, axis.motor.current_limit
    rng = np.random.default_rng(7)
    integral, current = np.zeros(6), np.zeros(6)
    saturated = limited_count = 0
    for _ in range(2000):
        scale = 2 * vmax / gains.kp
        l_ref, l = rng.uniform(0, 1, 6), rng.uniform(0, 1, 6)
        l = l_ref + scale * rng.uniform(-1, 1, 6)
        ldot_ref, ldot = rng.uniform(-0.1, 0.1, 6), rng.uniform(-0.1, 0.1, 6)
        v_ff = rng.uniform(-0.5, 0.5, 6) * vmax
        v, sat = ctrl.step(l_ref, ldot_ref, l, ldot, v_ff)
        v_ref, sat_ref = _pid_reference(gains.kp, gains.ki, gains.kd, vmax, config.dt, integral,
                                        l_ref, ldot_ref, l, ldot, v_ff)
        assert np.array_equal(v, v_ref) and np.array_equal(sat, sat_ref)
        assert np.array_equal(ctrl.integral, integral)
        torque, limited = motors.step(v, ldot)
        t_ref, lim_ref = _currents_reference(
            axis.motor.resistance, axis.motor.torque_constant, axis.emf_constant, ilim,
            motors.decay, motors.mean_decay, current, v, ldot)
        assert np.array_equal(torque, t_ref) and np.array_equal(limited, lim_ref)
        assert np.array_equal(motors.current, current)
        saturated += int(sat.sum())
        limited_count += int(limited.sum())
    assert 0.2 < saturated / 12000 < 0.8 and limited_count > 0, (saturated, limited_count)
    l = np.full(6, 0.5)
    l[2] = np.nan
    v, sat = ctrl.step(np.full(6, 0.5), np.zeros(6), l, np.zeros(6), np.zeros(6))
    v_ref, sat_ref = _pid_reference(gains.kp, gains.ki, gains.kd, vmax, config.dt, integral,
                                    np.full(6, 0.5), np.zeros(6), l, np.zeros(6), np.zeros(6))
    assert np.isnan(v[2]) and sat[2]       # NaN != NaN: flagged, the integral holds
    assert np.array_equal(v, v_ref, equal_nan=True) and np.array_equal(sat, sat_ref)
    assert np.array_equal(ctrl.integral, integral)


def test_loop_in_chunks_equals_one_call(monkeypatch):
    """closed_loop_run carries the plant state, integral and currents from call to call: the
    run in chunks of 37 samples equals the run in one call, bit for bit, and the progress
    callback sees every chunk's end."""
    model, config, _, _ = _micro()
    config = dataclasses.replace(config, feedforward="kane")
    traj = run_reference(model, config, 0.4)
    whole = run_closed_loop(model, config, traj)
    monkeypatch.setattr(cosim, "CHUNK", 37)
    seen = []
    chunked = run_closed_loop(model, config, traj, progress=lambda k, n: seen.append((k, n)))
    n = len(traj.t)
    assert seen == [(min(k + 37, n), n) for k in range(0, n, 37)]
    for name in whole.table.dtype.names:
        assert np.array_equal(whole.table[name], chunked.table[name]), name


@pytest.mark.parametrize("feedforward", ["none", "kane"])
def test_c_loop_equals_the_python_loop_bit_for_bit(feedforward):
    """The `run` reference (1 s) on the micro-manipulator: the C loop (the core's stewart_step)
    and the Python loop around InProcessPlant (Plant.do_step, the same C step, and the C
    controller functions through cffi) record the same signals, bit for bit."""
    model, config, _, _ = _micro()
    config = dataclasses.replace(config, feedforward=feedforward)
    traj = run_reference(model, config, 1.0)
    c_loop = run_closed_loop(model, config, traj)
    python = run_closed_loop(model, config, traj, plant=InProcessPlant(model))
    for name in c_loop.table.dtype.names:
        assert np.array_equal(c_loop.table[name], python.table[name]), name
