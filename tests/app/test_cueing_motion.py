"""Vehicle motion files: the round trip, one clear line for each kind of bad file, and the
shipped motions (scenes/motions/) regenerated from their synthesis with their stated figures."""
from __future__ import annotations

import numpy as np
import pytest

from stewart_fmu.errors import StewartError
from stewart_sim.cueing.motion import (
    MOTION_COLUMNS,
    MotionError,
    VehicleMotion,
    read_motion,
    write_motion,
)
from tests.helpers import ROOT
from tools.vehicle_motions import MOTIONS

G = 9.81
GOOD = "t,fx,fy,fz,wx,wy,wz\n0.0,0,0,9.81,0,0,0\n0.01,0.1,0,9.81,0,0,0.01\n0.02,0.2,0,9.81,0,0,0.02\n"


def test_write_then_read_is_exact(tmp_path):
    rng = np.random.default_rng(3)
    t = 0.5 + np.arange(50) / 100
    motion = VehicleMotion(t, rng.normal(size=(50, 3)), rng.normal(size=(50, 3)))
    back = read_motion(write_motion(tmp_path / "m.csv", motion))
    for name in ("t", "specific_force", "angular_velocity"):
        np.testing.assert_array_equal(getattr(back, name), getattr(motion, name))
    assert (tmp_path / "m.csv").read_text().splitlines()[0] == ",".join(MOTION_COLUMNS)


@pytest.mark.parametrize("text, says", [
    (GOOD.replace("wz", "yaw"), "header must be t,fx,fy,fz,wx,wy,wz"),
    (GOOD.replace("0.1,0,9.81", "abc,0,9.81"), "line 3, column 'fx': not a number"),
    (GOOD.replace("0.2,0,9.81", "nan,0,9.81"), "line 4, column 'fx': non-finite"),
    (GOOD.replace("0.02,", "0.01,", 1), "line 4, column 't': time must increase strictly"),
    (GOOD.replace("0.02,", "0.025,", 1), "line 4, column 't': sampling must be uniform: step 0.015"),
    (GOOD.replace("0.01,0.1,0,9.81,0,0,0.01", "0.01,0.1,0,9.81,0,0"), "line 3 has 6 fields"),
    ("t,fx,fy,fz,wx,wy,wz\n0,0,0,9.81,0,0,0\n", "need two or more samples"),
    ("", "empty file"),
])
def test_bad_files_get_one_line_naming_the_file_and_the_place(tmp_path, text, says):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(MotionError) as info:
        read_motion(path)
    message = str(info.value)
    assert says in message and str(path) in message and "\n" not in message
    assert isinstance(info.value, StewartError)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(MotionError, match="missing.csv: cannot read vehicle motion"):
        read_motion(tmp_path / "missing.csv")


def test_arrays_of_the_wrong_shape_are_refused():
    with pytest.raises(MotionError, match=r"specific_force must have shape \(3, 3\)"):
        VehicleMotion(np.arange(3.0), np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(MotionError, match="sample 1, column 'wz': non-finite"):
        VehicleMotion(np.arange(3.0), np.zeros((3, 3)), np.array([[0, 0, 0], [0, 0, np.inf], [0, 0, 0]]))


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_shipped_motions_are_what_their_synthesis_makes(name):
    shipped = read_motion(ROOT / "scenes" / "motions" / f"{name}.csv")
    made = MOTIONS[name]()
    for field in ("t", "specific_force", "angular_velocity"):
        np.testing.assert_allclose(getattr(shipped, field), getattr(made, field), rtol=1e-12,
                                   atol=1e-12)
    assert shipped.dt == pytest.approx(0.01)
    # every motion starts at rest: 1 g up, no rotation
    np.testing.assert_array_equal(shipped.specific_force[0], [0.0, 0.0, G])
    np.testing.assert_array_equal(shipped.angular_velocity[0], 0.0)


def test_braking_car_figures():
    m = MOTIONS["braking_car"]()
    f, w, t = m.specific_force, m.angular_velocity, m.t
    # 0.8 g along the path; in the body frame the 1.6 deg dive adds g sin(pitch). The pitch is
    # recovered here by the trapezoidal rule: good to ~(w dt)^2 / 12 = 1e-4 for the 1.5 Hz mode.
    pitch = np.r_[0.0, np.cumsum((w[1:, 1] + w[:-1, 1]) / 2 * np.diff(t))]
    decel = -(np.cos(pitch) * f[:, 0] + np.sin(pitch) * f[:, 2])   # the path's x, back from body
    assert decel.max() == pytest.approx(0.8 * G, rel=1e-4)
    # dive: 2 deg/g x 0.8 g = 1.6 deg once settled, 2.1 deg at the peak (damping ratio 0.3)
    assert np.degrees(pitch[np.searchsorted(t, 5.5)]) == pytest.approx(1.6, rel=1e-3)
    assert 2.0 < np.degrees(pitch.max()) < 2.2
    # the speed lost is 80 km/h: the car stops; at the end it stands still
    assert np.sum((decel[1:] + decel[:-1]) / 2 * np.diff(t)) == pytest.approx(80 / 3.6, rel=1e-3)
    np.testing.assert_allclose(f[-1], [0, 0, G], atol=1e-3)
    assert 10 <= t[-1] <= 15


def test_lane_change_figures():
    m = MOTIONS["lane_change"]()
    f, w, t = m.specific_force, m.angular_velocity, m.t
    roll = np.r_[0.0, np.cumsum((w[1:, 0] + w[:-1, 0]) / 2 * np.diff(t))]  # trapezoid: ~1e-4
    ay = np.cos(roll) * f[:, 1] - np.sin(roll) * f[:, 2]  # lateral acceleration of the path
    assert ay.max() == pytest.approx(0.4 * G, rel=1e-3) and ay.min() == pytest.approx(-0.4 * G, rel=1e-3)
    yaw_rate = np.hypot(w[:, 1], w[:, 2]) * np.sign(w[:, 2])
    # (the recovered roll's ~1e-4 error moves a_y by up to ~4e-5 m/s^2: 2e-6 rad/s here)
    np.testing.assert_allclose(yaw_rate, ay / 20.0, rtol=1e-4, atol=5e-6)
    # lateral offset: twice integrated a_y ends 3.5 m left after the first change, back at 0
    vy = np.r_[0.0, np.cumsum((ay[1:] + ay[:-1]) / 2 * np.diff(t))]
    y = np.r_[0.0, np.cumsum((vy[1:] + vy[:-1]) / 2 * np.diff(t))]
    assert y.max() == pytest.approx(3.5, rel=1e-3) and abs(y[-1]) < 1e-2
    assert 2.0 < np.degrees(np.abs(roll).max()) < 2.5   # 5 deg/g at 0.4 g, with overshoot


def test_takeoff_figures():
    m = MOTIONS["takeoff"]()
    f, w, t = m.specific_force, m.angular_velocity, m.t
    pitch_up = -np.r_[0.0, np.cumsum((w[1:, 1] + w[:-1, 1]) / 2 * np.diff(t))]
    assert np.degrees(pitch_up[-1]) == pytest.approx(10.0, rel=1e-3)
    assert np.degrees(-w[:, 1]).max() == pytest.approx(3.0, rel=1e-9)
    ground = (t > 6) & (t < 32)
    assert 0.24 * G < f[ground, 0].min() and f[ground, 0].max() < 0.31 * G
    assert f[ground, 2].std() > 0.05             # runway bumps
    assert 1.15 * G < f[:, 2].max() < 1.25 * G   # the pull-up's load factor
    assert t[-1] == 45.0
