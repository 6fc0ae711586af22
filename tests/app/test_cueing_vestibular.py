"""The vestibular models against their transfer functions' closed forms, and the motion a
platform delivers (f = R^T (a - g), w in the platform frame): physics, not snapshots."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_sim.cueing import vestibular as v
from stewart_sim.cueing.motion import MotionError, VehicleMotion

DT = 0.01
G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])


def _rot(thx, thy, thz):
    """R = Rz Ry Rx, written out here independently of stewart_fmu.rotations."""
    cx, sx, cy, sy, cz, sz = np.cos(thx), np.sin(thx), np.cos(thy), np.sin(thy), np.cos(thz), np.sin(thz)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _step_closed_form(numerator, taus, t):
    """Step response of numerator(s) / prod(tau_i s + 1) (distinct tau_i) by residues of
    H(s)/s: H(0) + sum_i N(p_i) / (p_i tau_i prod_{j != i} (tau_j p_i + 1)) exp(p_i t)."""
    y = np.full_like(t, numerator(0.0))
    for i, tau in enumerate(taus):
        p = -1.0 / tau
        rest = np.prod([tj * p + 1 for j, tj in enumerate(taus) if j != i])
        y += numerator(p) / (p * tau * rest) * np.exp(p * t)
    return y


K = 0.4   # Young & Meiry's otolith gain


def _otolith_h(s):
    tau_a, tau_l, tau_s = 13.2, 5.33, 0.66
    return K * (tau_a * s + 1) / ((tau_l * s + 1) * (tau_s * s + 1))


def _canal_h(s, tau_l):
    return tau_l * 30.0 * s**2 / ((tau_l * s + 1) * (0.1 * s + 1) * (30.0 * s + 1))


def test_the_published_time_constants_and_thresholds():
    # Young & Meiry / Young & Oman as Reid & Nahon tabulate them (cited in the module doc).
    assert v.OTOLITH_GAIN == 0.4 and v.OTOLITH_TAU == (13.2, 5.33, 0.66)
    assert v.CANAL_TAU_L == (6.1, 5.3, 10.2) and v.CANAL_TAU_S == 0.1 and v.CANAL_TAU_A == 30.0
    np.testing.assert_allclose(v.OTOLITH_THRESHOLD, [0.17, 0.17, 0.28])
    np.testing.assert_allclose(np.degrees(v.CANAL_THRESHOLD), [3.0, 3.6, 2.6])


def test_transfer_function_objects_have_the_models_gains_and_poles():
    oto = v.otolith_tf()
    assert float(np.real(oto.dcgain())) == pytest.approx(K, rel=1e-12)
    # between the breaks the gain peaks at 0.89 (0.5 rad/s), below K tau_a / tau_L = 0.99
    gains = [abs(complex(oto(1j * w))) for w in np.logspace(-3, 2, 501)]
    assert max(gains) == pytest.approx(0.8908, abs=1e-4)
    np.testing.assert_allclose(np.sort(oto.poles().real), [-1 / 0.66, -1 / 5.33], rtol=1e-12)
    np.testing.assert_allclose(oto.zeros().real, [-1 / 13.2], rtol=1e-12)
    for axis, tau_l in enumerate((6.1, 5.3, 10.2)):
        canal = v.canal_tf(axis)
        assert abs(complex(canal.dcgain())) == 0.0
        np.testing.assert_allclose(np.sort(canal.poles().real), [-1 / 0.1, -1 / tau_l, -1 / 30.0],
                                   rtol=1e-10)
        assert complex(canal(1j * 1.0)) == pytest.approx(_canal_h(1j, tau_l), rel=1e-12)


def test_otolith_step_response_is_the_closed_form_at_every_sample():
    # The zero-order hold is exact for a step: the samples equal the continuous response.
    t = np.arange(0, 200 + DT / 2, DT)
    x = np.zeros((t.size, 3))
    k0 = 100
    x[k0:] = [1.0, -2.0, 0.5]
    y = v.otolith(t, x)
    tau_a, tau_l, tau_s = v.OTOLITH_TAU
    tt = t[k0:] - t[k0]
    closed = _step_closed_form(lambda s: K * (tau_a * s + 1), (tau_l, tau_s), tt)
    # by hand, too: K (1 + (ta - tl)/(tl - ts) e^{-t/tl} - (ta - ts)/(tl - ts) e^{-t/ts})
    by_hand = K * (1 + (tau_a - tau_l) / (tau_l - tau_s) * np.exp(-tt / tau_l)
                   - (tau_a - tau_s) / (tau_l - tau_s) * np.exp(-tt / tau_s))
    np.testing.assert_allclose(closed, by_hand, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y[:k0], 0.0, atol=0)
    for axis, amp in enumerate((1.0, -2.0, 0.5)):
        np.testing.assert_allclose(y[k0:, axis], amp * closed, rtol=0, atol=1e-9 * abs(amp))
    # Steady state: a sustained specific force settles at K of its value; on the way the
    # otolith's lead (tau_a / tau_L = 2.48) takes it to ~K tau_a / tau_L = 0.99.
    np.testing.assert_allclose(y[-1], K * np.array([1.0, -2.0, 0.5]), rtol=1e-12)
    assert 0.8 < y[:, 0].max() < 1.0


def test_canal_step_response_is_the_closed_form_and_adapts_to_zero():
    t = np.arange(0, 300 + DT / 2, DT)
    x = np.zeros((t.size, 3))
    x[1:] = 0.2
    y = v.semicircular_canals(t, x)
    tt = t[1:] - t[1]
    for axis, tau_l in enumerate(v.CANAL_TAU_L):
        closed = _step_closed_form(lambda s, tl=tau_l: tl * 30.0 * s**2, (tau_l, 0.1, 30.0), tt)
        np.testing.assert_allclose(y[1:, axis], 0.2 * closed, rtol=0, atol=1e-10)
        # A constant rate is no longer felt: adapts to zero (after an overshoot below zero).
        assert abs(y[-1, axis]) < 1e-3 * 0.2
        assert y[:, axis].min() < 0


def _zoh_response(numerator, taus, w):
    """The exact frequency response of the zero-order-hold equivalent at z = exp(j w DT), from
    the residues c_i of H(s)/s: H(0) + sum_i c_i (1 - 1/z) / (1 - exp(p_i DT) / z)."""
    z = np.exp(1j * w * DT)
    out = numerator(0.0) + 0j
    for i, tau in enumerate(taus):
        p = -1.0 / tau
        c = numerator(p) / (p * tau * np.prod([tj * p + 1 for j, tj in enumerate(taus) if j != i]))
        out += c * (1 - 1 / z) / (1 - np.exp(p * DT) / z)
    return out


@pytest.mark.parametrize("model", ["otolith", "canal"])
def test_sine_response_matches_the_transfer_function_at_the_break_frequencies(model):
    # Steady-state amplitude and phase of a sine at each break frequency (and one in the
    # canals' passband): exactly those of the sampled model (residues computed here), and
    # within 1e-3 those of the continuous H(jw) delayed by the hold's half sample.
    tau_a, tau_l, tau_s = 13.2, 5.33, 0.66
    if model == "otolith":
        freqs = [1 / tau_a, 1 / tau_l, 1 / tau_s]
        cases = [(_otolith_h, lambda s: K * (tau_a * s + 1), (tau_l, tau_s))] * 3
        run = v.otolith
    else:
        freqs = [1 / 30.0, 1 / 6.1, 1.0, 1 / 0.1]
        cases = [(lambda s, tl=tl: _canal_h(s, tl), lambda s, tl=tl: tl * 30.0 * s**2,
                  (tl, 0.1, 30.0)) for tl in v.CANAL_TAU_L]
        run = v.semicircular_canals
    for w in freqs:
        periods = max(8, int(np.ceil(w * 400 / (2 * np.pi))))
        t = np.arange(0, periods * 2 * np.pi / w + 600, DT)
        x = np.repeat(np.sin(w * t)[:, None], 3, axis=1)
        y = run(t, x)
        last = t > t[-1] - 2 * (2 * np.pi / w)   # two periods after > 600 s of transient
        # Fit y = a sin + b cos over the last periods (least squares, exact for a pure sine).
        basis = np.column_stack([np.sin(w * t[last]), np.cos(w * t[last])])
        for axis, (h, numerator, taus) in enumerate(cases):
            (a, b), *_ = np.linalg.lstsq(basis, y[last, axis], rcond=None)
            measured = a + 1j * b
            exact = _zoh_response(numerator, taus, w)
            assert abs(measured - exact) < 1e-6 * abs(exact), (model, w, axis)
            continuous = h(1j * w) * np.exp(-1j * w * DT / 2)
            assert abs(measured - continuous) < 1e-3 * abs(continuous), (model, w, axis)


def test_delivered_motion_of_the_neutral_pose_at_rest_is_one_g_up():
    n = 5
    q = np.tile([0.0, 0.0, 2.3, 0.0, 0.0, 0.0], (n, 1))
    f, w = v.delivered_motion(np.arange(n) * DT, q, np.zeros((n, 6)), np.zeros((n, 6)), GRAVITY)
    np.testing.assert_array_equal(f, np.tile([0.0, 0.0, G], (n, 1)))
    np.testing.assert_array_equal(w, 0.0)


def test_a_platform_accelerating_feels_a_minus_g_rotated():
    rng = np.random.default_rng(7)
    n = 20
    q = np.column_stack([rng.normal(size=(n, 3)), rng.uniform(-0.5, 0.5, (n, 3))])
    qdd = np.column_stack([rng.normal(size=(n, 3)) * 3, np.zeros((n, 3))])
    f, _ = v.delivered_motion(np.arange(n) * DT, q, np.zeros((n, 6)), qdd, GRAVITY)
    for k in range(n):
        R = _rot(*q[k, 3:])
        np.testing.assert_allclose(f[k], R.T @ (qdd[k, :3] - GRAVITY), rtol=0, atol=1e-12)


def test_delivered_angular_velocity_is_the_body_rate_of_the_rotation():
    # skew(w_C) = R^T dR/dt along a smooth attitude path (central differences of R here).
    t = np.linspace(0, 2, 2001)
    th = np.column_stack([0.3 * np.sin(1.3 * t), 0.2 * np.cos(0.7 * t), 0.5 * np.sin(0.9 * t + 1)])
    thd = np.column_stack([0.3 * 1.3 * np.cos(1.3 * t), -0.2 * 0.7 * np.sin(0.7 * t),
                           0.5 * 0.9 * np.cos(0.9 * t + 1)])
    q = np.column_stack([np.zeros((t.size, 3)), th])
    qd = np.column_stack([np.zeros((t.size, 3)), thd])
    _, w = v.delivered_motion(t, q, qd, np.zeros_like(q), GRAVITY)
    h = t[1] - t[0]
    for k in (100, 1000, 1900):
        Rdot = (_rot(*th[k + 1]) - _rot(*th[k - 1])) / (2 * h)
        S = _rot(*th[k]).T @ Rdot
        np.testing.assert_allclose([S[2, 1], S[0, 2], S[1, 0]], w[k], atol=1e-6)
    # a pure roll rate is (thxdot, 0, 0) in C at any attitude (roll is the innermost rotation)
    qd_roll = np.zeros_like(q)
    qd_roll[:, 3] = 0.4
    _, w_roll = v.delivered_motion(t, q, qd_roll, np.zeros_like(q), GRAVITY)
    np.testing.assert_allclose(w_roll, np.tile([0.4, 0.0, 0.0], (t.size, 1)), atol=1e-15)


@pytest.mark.parametrize("a", [0.5, 1.5, 3.0])
def test_tilt_is_perceived_as_the_equivalent_sustained_acceleration(a):
    # The tilt-coordination premise: a platform pitched nose up by asin(a/g) at rest gives
    # f_x = a, as a vehicle accelerating forward at a; the otolith's x output of the two is
    # the same in steady state (K a: the static gain).
    t = np.arange(0, 120 + DT / 2, DT)
    n, k0 = t.size, 500
    q = np.tile([0.0, 0.0, 2.3, 0.0, 0.0, 0.0], (n, 1))
    q[k0:, 4] = -np.arcsin(a / G)   # nose up is negative thy (x forward, z up)
    f_platform, _ = v.delivered_motion(t, q, np.zeros((n, 6)), np.zeros((n, 6)), GRAVITY)
    assert f_platform[-1, 0] == pytest.approx(a, rel=1e-14)
    assert f_platform[-1, 2] == pytest.approx(np.sqrt(G**2 - a**2), rel=1e-14)
    f_vehicle = np.tile([0.0, 0.0, G], (n, 1))
    f_vehicle[k0:, 0] = a
    p_platform, p_vehicle = v.otolith(t, f_platform), v.otolith(t, f_vehicle)
    np.testing.assert_allclose(p_platform[k0:, 0], p_vehicle[k0:, 0], rtol=1e-12, atol=1e-12)
    assert p_platform[-1, 0] == pytest.approx(K * a, rel=1e-9)


def _vehicle(t, fx=None, wz=None):
    f = np.tile([0.0, 0.0, G], (t.size, 1))
    w = np.zeros((t.size, 3))
    if fx is not None:
        f[:, 0] = fx
    if wz is not None:
        w[:, 2] = wz
    return VehicleMotion(t, f, w)


def test_perception_of_a_platform_at_rest_for_a_vehicle_at_rest_has_no_error():
    t = np.arange(0, 10, DT)
    n = t.size
    q = np.tile([0.0, 0.0, 2.3, 0.0, 0.0, 0.0], (n, 1))
    p = v.perception(_vehicle(t), t, q, np.zeros((n, 6)), np.zeros((n, 6)), GRAVITY)
    np.testing.assert_array_equal(p.rms_f, 0.0)
    np.testing.assert_array_equal(p.rms_w, 0.0)
    np.testing.assert_array_equal(p.false_cue_time_f, 0.0)
    np.testing.assert_array_equal(p.false_cue_time_w, 0.0)
    np.testing.assert_array_equal(p.workspace_range, 0.0)
    np.testing.assert_array_equal(p.workspace_min, q[0])


def test_perception_counts_wrong_sign_cues_above_threshold_as_false():
    # The platform surges backwards (and yaws the other way) while the vehicle goes forward:
    # the perceived signals are exact opposites, so every sample perceived above threshold is
    # a false cue, and the error is twice the vehicle's perception.
    t = np.arange(0, 20, DT)
    n = t.size
    pulse = np.where((t > 2) & (t < 6), 1.0, 0.0)
    vehicle = _vehicle(t, fx=pulse, wz=0.2 * pulse)
    q = np.tile([0.0, 0.0, 2.3, 0.0, 0.0, 0.0], (n, 1))
    qd, qdd = np.zeros((n, 6)), np.zeros((n, 6))
    qdd[:, 0] = -pulse          # x acceleration in N at zero attitude: f_x = -pulse
    qd[:, 5] = -0.2 * pulse     # yaw rate at zero attitude: w_z = -0.2 pulse
    p = v.perception(vehicle, t, q, qd, qdd, GRAVITY)
    np.testing.assert_allclose(p.perceived_delivered_f[:, 0], -p.perceived_vehicle_f[:, 0], atol=1e-14)
    expected_f = np.count_nonzero(np.abs(p.perceived_vehicle_f[:, 0]) > 0.17) * DT
    expected_w = np.count_nonzero(np.abs(p.perceived_vehicle_w[:, 2]) > np.radians(2.6)) * DT
    assert expected_f > 3.0 and expected_w > 1.0
    assert p.false_cue_time_f[0] == pytest.approx(expected_f)
    assert p.false_cue_time_w[2] == pytest.approx(expected_w)
    np.testing.assert_array_equal(p.false_cue_time_f[1:], 0.0)
    np.testing.assert_array_equal(p.false_cue_time_w[:2], 0.0)
    rms = np.sqrt(np.mean((2 * p.perceived_vehicle_f[:, 0]) ** 2))
    assert p.rms_f[0] == pytest.approx(rms, rel=1e-12)


def test_heave_cues_count_from_one_g():
    # On z the false-cue test takes the signals from rest (1 g): a platform dropping while the
    # vehicle heaves up gives a false cue, though both perceive a positive specific force.
    t = np.arange(0, 10, DT)
    n = t.size
    pulse = np.where((t > 1) & (t < 3), 2.0, 0.0)
    f = np.tile([0.0, 0.0, G], (n, 1))
    f[:, 2] += pulse
    vehicle = VehicleMotion(t, f, np.zeros((n, 3)))
    qdd = np.zeros((n, 6))
    qdd[:, 2] = -pulse
    p = v.perception(vehicle, t, np.tile([0, 0, 2.3, 0, 0, 0.0], (n, 1)), np.zeros((n, 6)), qdd,
                     GRAVITY)
    assert np.all(p.perceived_delivered_f[:, 2] > 0)
    assert p.false_cue_time_f[2] == pytest.approx(
        np.count_nonzero(np.abs(p.perceived_vehicle_f[:, 2] - K * G) > 0.28) * DT)
    assert p.false_cue_time_f[2] > 1.0


def test_perception_refuses_platform_times_that_are_not_the_vehicles():
    t = np.arange(0, 1, DT)
    n = t.size
    q = np.tile([0, 0, 2.3, 0, 0, 0.0], (n, 1))
    with pytest.raises(MotionError, match="times must be the vehicle's"):
        v.perception(_vehicle(t), t + 0.5, q, np.zeros((n, 6)), np.zeros((n, 6)), GRAVITY)
    with pytest.raises(MotionError, match="uniformly sampled"):
        v.otolith(np.r_[0.0, 0.1, 0.3], np.zeros((3, 3)))
