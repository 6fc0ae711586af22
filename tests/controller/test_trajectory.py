"""Global-space trajectories: exact derivatives, limits, and the checks before anything runs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.trajectory import (
    QUINTIC_PEAK_ACCELERATION,
    QUINTIC_PEAK_RATE,
    constant_acceleration,
    leg_references,
    quintic,
    sinusoid,
    waypoints,
    waypoints_csv,
)
from stewart_fmu import StrokeLimitError, TrajectoryError, inverse_kinematics, load_scene
from stewart_fmu.io import trajectory_table, write_csv

MICRO = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml")


def _derivative_error(t: np.ndarray, x: np.ndarray, dx: np.ndarray) -> float:
    """Largest gap between dx and the central difference of x, relative to max |dx|."""
    fd = (x[2:] - x[:-2]) / (t[2:, None] - t[:-2, None])
    return float(np.max(np.abs(fd - dx[1:-1])) / max(np.max(np.abs(dx)), 1e-300))


@pytest.mark.parametrize("make", [
    lambda: constant_acceleration(MICRO.home, np.r_[10, 0, 0, 0, 0, 8], 0.1, 10_000),
    lambda: quintic(MICRO.home, MICRO.home + np.r_[0.01, -0.01, 0.005, 0.05, 0, 0.1], 10_000, 0.5),
    lambda: sinusoid(MICRO.home, np.r_[0.005, 0.005, 0.005, 0.05, 0.05, 0.05],
                     np.r_[1, 2, 3, 1.5, 2.5, 0.5], 1.0, 10_000),
], ids=["constant", "quintic", "sinusoid"])
def test_derivatives_are_exact(make):
    """qd and qdd equal central differences of q and qd to 1e-4 relative at 10 kHz sampling
    (the O(dt^2) error of the difference itself)."""
    tr = make()
    assert _derivative_error(tr.t, tr.q, tr.qd) < 1e-4
    assert _derivative_error(tr.t, tr.qd, tr.qdd) < 1e-4


def test_waypoint_derivatives_are_exact_between_knots():
    """Cubic-spline waypoints: as above, but the qd -> qdd check skips the samples next to the
    inner knot, where the spline's jerk jumps (a central difference across it is O(dt))."""
    tr = waypoints(np.r_[0.0, 0.4, 1.0],
                   MICRO.home + np.array([[0] * 6, [0.01, 0, 0.005, 0, 0.05, 0], [0] * 6]), 10_000)
    assert _derivative_error(tr.t, tr.q, tr.qd) < 1e-4
    keep = np.abs(tr.t - 0.4) > 1.5e-4
    fd = (tr.qd[2:] - tr.qd[:-2]) / (tr.t[2:, None] - tr.t[:-2, None])
    gap = np.abs(fd - tr.qdd[1:-1])[keep[1:-1]]
    assert np.max(gap) / np.max(np.abs(tr.qdd)) < 1e-4


def test_quintic_respects_rate_and_acceleration_limits():
    """The shortest quintic meets one limit (to 1e-3) and exceeds none; rest to rest."""
    d = np.r_[0.01, 0.0, 0.02, 0.0, 0.1, 0.0]
    vmax, amax = np.r_[[0.05] * 3, [0.5] * 3], np.r_[[0.4] * 3, [4.0] * 3]
    tr = quintic(MICRO.home, MICRO.home + d, 20_000, max_rate=vmax, max_acceleration=amax)
    peak_v, peak_a = np.max(np.abs(tr.qd), axis=0), np.max(np.abs(tr.qdd), axis=0)
    assert np.all(peak_v <= vmax * (1 + 1e-9)) and np.all(peak_a <= amax * (1 + 1e-6))
    assert max(np.max(peak_v / vmax), np.max(peak_a / amax)) > 1 - 1e-3
    assert np.allclose(tr.qd[[0, -1]], 0, atol=1e-12) and np.allclose(tr.qdd[[0, -1]], 0, atol=1e-9)
    assert QUINTIC_PEAK_RATE == pytest.approx(1.875) and QUINTIC_PEAK_ACCELERATION == pytest.approx(5.7735, rel=1e-4)


def test_leg_references_match_inverse_kinematics():
    """Leg references are inverse kinematics of the poses (exactly) with cond(J) per sample."""
    tr = sinusoid(MICRO.home, np.r_[0.005] * 6, np.r_[1.0] * 6, 0.5, 1000)
    ref = leg_references(MICRO, tr)
    kin = inverse_kinematics(MICRO, tr.q, tr.qd, tr.qdd)
    assert np.array_equal(ref.l, kin.lengths) and np.array_equal(ref.lddot, kin.accelerations)
    assert ref.cond.shape == tr.t.shape and np.all(ref.cond < 10)


def test_references_refuse_a_move_past_the_stroke_before_running():
    """A move leaving the stroke raises StrokeLimitError naming the first bad sample's time."""
    tr = quintic(MICRO.home, MICRO.home + np.r_[0, 0, 0.09, 0, 0, 0], 1000, 1.0)
    with pytest.raises(StrokeLimitError, match=r"at sample \d+ \(t = "):
        leg_references(MICRO, tr)


def test_waypoints_from_csv(tmp_path):
    """A trajectory CSV's poses become a C2 path through them (passes each waypoint exactly)."""
    t = np.r_[0.0, 0.5, 1.0]
    q = MICRO.home + np.array([[0] * 6, [0.01, 0, 0, 0, 0, 0.05], [0] * 6])
    path = write_csv(tmp_path / "wp.csv", trajectory_table(t, q, np.zeros((3, 6)), np.zeros((3, 6))))
    tr = waypoints_csv(str(path), 1000)
    assert np.allclose(tr.q[[0, 500, 1000]], q, atol=1e-15)


@pytest.mark.parametrize("call, why", [
    (lambda: quintic(MICRO.home, MICRO.home), "give a duration"),
    (lambda: quintic(MICRO.home, MICRO.home, max_rate=1, max_acceleration=1), "same pose"),
    (lambda: sinusoid(MICRO.home, 0.01, 1.0, -1.0), "duration and rate must be finite and > 0"),
    (lambda: waypoints(np.r_[0.0, 0.0], np.zeros((2, 6))), "increase strictly"),
    (lambda: constant_acceleration(MICRO.home, [np.nan] * 6, 0.1), "non-finite"),
])
def test_bad_trajectory_requests_are_named(call, why):
    """Each bad request raises TrajectoryError saying why."""
    with pytest.raises(TrajectoryError, match=why):
        call()
