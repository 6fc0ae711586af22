"""Kinematics of the plant: inverse and forward kinematics, the Jacobian, stroke limits,
singularities, and the typed errors the dynamics raise for bad poses and bad arrays.

Tolerances are stated in each docstring and asserted; worst residuals are recorded (print them
with STEWART_RESIDUALS=1).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.linalg import expm

from stewart_fmu import (
    ForwardKinematicsError,
    KinematicsError,
    SingularityError,
    StrokeLimitError,
    TrajectoryError,
    check_poses,
    forward_dynamics,
    forward_kinematics,
    inverse_dynamics,
    inverse_dynamics_parts,
    inverse_kinematics,
    scene_from_dict,
)
from tests.helpers import (
    leg_geometry,
    level_dict,
    level_model,
    random_states,
    rate_matrix,
    record,
    rotation,
    scene_dict,
    smooth_trajectory,
)
from tests.reference.newton_euler import reference_inverse_dynamics

SCENES = ("micro", "sim")


def no_stroke(name: str, level: str = "full"):
    """(dict, Model) of a scene without stroke limits (leg_min/leg_max are optional keys)."""
    d = level_dict(scene_dict(name), level)
    del d["geometry"]["leg_min"], d["geometry"]["leg_max"]
    return d, scene_from_dict(d)


def skew(w) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


# --- inverse kinematics and the Jacobian -------------------------------------------------------

@pytest.mark.parametrize("name", SCENES)
def test_inverse_kinematics_matches_independent_geometry(name):
    """inverse_kinematics against numpy geometry from the contract: leg vectors, lengths, unit
    vectors and Jacobian rows [u_i, (R p_i) x u_i] to 1e-14 relative; rates ldot = J (v, E thd)
    to 1e-13 relative; accelerations equal the reference's jets (lddot) to 1e-10 relative."""
    model, data = level_model(name, "full"), scene_dict(name)
    q, qd, qdd = random_states(name, 40, seed=1)
    kin = inverse_kinematics(model, q, qd, qdd)
    worst_geo = worst_rate = worst_acc = 0.0
    for k in range(len(q)):
        r, L, l, u, J = leg_geometry(data, q[k])
        worst_geo = max(worst_geo, np.abs(kin.leg_vectors[k] - L).max() / np.abs(L).max(),
                        np.abs(kin.lengths[k] - l).max() / l.max(),
                        np.abs(kin.unit_vectors[k] - u).max(),
                        np.abs(kin.jacobian[k] - J).max() / np.abs(J).max())
        ldot = J @ np.r_[qd[k, :3], rate_matrix(q[k, 3:]) @ qd[k, 3:]]
        worst_rate = max(worst_rate, np.abs(kin.rates[k] - ldot).max() / np.abs(ldot).max())
        lddot = reference_inverse_dynamics(data, q[k], qd[k], qdd[k])["lddot"]
        worst_acc = max(worst_acc, np.abs(kin.accelerations[k] - lddot).max() / np.abs(lddot).max())
    single = inverse_kinematics(model, q[0])
    assert single.lengths.shape == (6,) and single.jacobian.shape == (6, 6)
    assert single.rates is None and single.accelerations is None
    for label, worst, tol in (("geometry", worst_geo, 1e-14), ("rates", worst_rate, 1e-13),
                              ("accelerations vs jets", worst_acc, 1e-10)):
        record(f"5 inverse kinematics {label} [{name}]", worst, tol)
        assert worst <= tol, (label, worst)


@pytest.mark.parametrize("name", SCENES)
def test_jacobian_matches_finite_differences(name):
    """Each column of J (ldot = J (v, omega)) equals central differences of the leg lengths
    (numpy, not the plant) along a small twist (x + h e_k, expm(h [e_k]x) R), h = 1e-6 (1e-6 m
    for translation, 1e-6 rad for rotation), to 1e-6 relative to the column's largest entry."""
    tol = 1e-6
    data = scene_dict(name)
    a = np.asarray(data["geometry"]["base_joints"])
    p = np.asarray(data["geometry"]["platform_joints"])
    model = level_model(name, "full")
    q, _, _ = random_states(name, 20, seed=2)
    J = inverse_kinematics(model, q).jacobian
    h = 1e-6
    worst = 0.0
    for k in range(len(q)):
        x, R = q[k, :3], rotation(q[k, 3:])
        lengths = lambda xx, RR: np.linalg.norm(xx + p @ RR.T - a, axis=1)
        for c in range(6):
            e = np.eye(6)[c]
            plus = lengths(x + h * e[:3], expm(h * skew(e[3:])) @ R)
            minus = lengths(x - h * e[:3], expm(-h * skew(e[3:])) @ R)
            fd = (plus - minus) / (2 * h)
            worst = max(worst, np.abs(fd - J[k, :, c]).max() / np.abs(J[k, :, c]).max())
    record(f"5 Jacobian vs finite differences [{name}]", worst, tol)
    assert worst <= tol, worst


# --- forward kinematics ------------------------------------------------------------------------

@pytest.mark.parametrize("name", SCENES)
def test_forward_kinematics_inverts_inverse_kinematics(name):
    """forward_kinematics(inverse lengths) returns the pose to 1e-10 (m and rad) for random
    reachable poses (trajectory samples with 0.3-0.5 rad angles, and random states), from the
    default guess (home) and from a guess near the pose."""
    tol = 1e-10
    model = level_model(name, "full")
    traj = np.concatenate([smooth_trajectory(name, s)(np.linspace(0, 2, 15))[0] for s in (0, 1)])
    q = np.vstack([traj, random_states(name, 30, seed=3)[0]])
    worst = 0.0
    for k in range(len(q)):
        lengths = inverse_kinematics(model, q[k]).lengths
        worst = max(worst, np.abs(forward_kinematics(model, lengths) - q[k]).max())
        guess = q[k] + 1e-3 * np.r_[model.characteristic_length * np.ones(3), np.ones(3)]
        worst = max(worst, np.abs(forward_kinematics(model, lengths, guess=guess) - q[k]).max())
    record(f"5 forward kinematics round trip [{name}]", worst, tol)
    assert worst <= tol, worst


def _home_lengths(name):
    model = level_model(name, "full")
    return model, inverse_kinematics(model, model.home).lengths


def _unreachable(name, kind):
    """Unreachable lengths. 'all_tiny' and 'pair_short' are provably unreachable (checked by
    the triangle inequality |p_i - p_j| <= |a_i - a_j| + l_i + l_j in the test); the single-leg
    cases are unreachable numerically (least squares from 200 starts keeps a residual > 0.018 m
    on the micro scene and > 0.44 m on the simulator: scratch run)."""
    model, l0 = _home_lengths(name)
    a, p = model.base_joints, model.platform_joints
    gap = np.linalg.norm(p[:, None] - p[None], axis=-1) - np.linalg.norm(a[:, None] - a[None], axis=-1)
    i, j = np.unravel_index(np.argmax(gap), gap.shape)
    out = l0.copy()
    if kind == "all_tiny":
        out = 1e-3 * l0
    elif kind == "pair_short":
        out[[i, j]] = 0.25 * gap[i, j]  # l_i + l_j = gap / 2 < |p_i - p_j| - |a_i - a_j|
    elif kind == "one_far_too_short":
        out[5] = 1e-3 * l0[5]
    elif kind == "one_far_too_long":
        out[5] = 3.0 * l0[5]
    return model, out, gap


@pytest.mark.parametrize("kind", ["all_tiny", "pair_short", "one_far_too_short", "one_far_too_long"])
@pytest.mark.parametrize("name", SCENES)
def test_forward_kinematics_raises_for_unreachable_lengths(name, kind):
    """Unreachable leg lengths raise ForwardKinematicsError (a KinematicsError) whose message
    says Newton did not converge and gives the lengths and the residual. The stroke limits are
    lifted so that Newton itself meets the impossible geometry (with them, the stroke check
    rejects these lengths first: see the test below)."""
    model, lengths, gap = _unreachable(name, kind)
    model = dataclasses.replace(model, leg_min=None, leg_max=None)
    if kind in ("all_tiny", "pair_short"):  # provably unreachable: some pair breaks the triangle
        a, p = model.base_joints, model.platform_joints
        da = np.linalg.norm(a[:, None] - a[None], axis=-1)
        dp = np.linalg.norm(p[:, None] - p[None], axis=-1)
        assert np.any(dp > da + lengths[:, None] + lengths[None, :])
    with pytest.raises(ForwardKinematicsError, match="did not converge") as info:
        forward_kinematics(model, lengths)
    assert isinstance(info.value, KinematicsError)
    assert "residual" in str(info.value) and repr(float(lengths[5])) in str(info.value)


@pytest.mark.parametrize("lengths", [
    pytest.param("negative", id="negative"), pytest.param("zero", id="zero"),
    pytest.param("nan", id="nan"), pytest.param("inf", id="inf"), pytest.param("five", id="five")])
def test_forward_kinematics_rejects_invalid_lengths(lengths):
    """Non-positive, non-finite or not six lengths: ForwardKinematicsError saying what is needed."""
    model, l0 = _home_lengths("micro")
    bad = {"negative": np.r_[l0[:5], -0.1], "zero": np.r_[l0[:5], 0.0],
           "nan": np.r_[l0[:5], np.nan], "inf": np.r_[l0[:5], np.inf], "five": l0[:5]}[lengths]
    with pytest.raises(ForwardKinematicsError, match="six finite positive numbers"):
        forward_kinematics(model, bad)


@pytest.mark.parametrize("name", SCENES)
def test_forward_kinematics_rejects_lengths_outside_the_stroke(name):
    """All legs 10x their home length are outside [leg_min, leg_max]: forward_kinematics should
    raise a KinematicsError (ForwardKinematicsError or StrokeLimitError) rather than return a
    pose the mechanism cannot reach."""
    model, l0 = _home_lengths(name)
    assert np.all(10 * l0 > model.leg_max)
    with pytest.raises(KinematicsError):
        forward_kinematics(model, 10 * l0)


# --- stroke limits and singularities -----------------------------------------------------------

@pytest.mark.parametrize("side", ["above", "below"])
@pytest.mark.parametrize("name", SCENES)
def test_check_poses_raises_stroke_limit_error_naming_sample_and_time(name, side):
    """A pose past leg_max (heave up) or below leg_min (heave down) at sample 7 of a trajectory:
    StrokeLimitError with index 7, time t[7], and a message naming the sample, the time, the legs
    and the stroke; without times, time is None and the message has no time."""
    model = level_model(name, "full")
    traj = smooth_trajectory(name, 0)
    t = np.linspace(0.0, 1.0, 12)
    q = traj(t)[0]
    check_poses(model, q)  # the unmodified trajectory passes
    l0 = inverse_kinematics(model, model.home).lengths.mean()
    target = 1.3 * model.leg_max if side == "above" else 0.7 * model.leg_min
    q[7:, 2] += target - l0  # samples 7.. leave the stroke: the first is 7
    with pytest.raises(StrokeLimitError) as info:
        check_poses(model, q, t)
    err = info.value
    assert err.index == 7 and err.time == t[7]
    msg = str(err)
    assert "at sample 7" in msg and f"t = {float(t[7])!r} s" in msg and "outside the stroke" in msg
    assert f"[{model.leg_min}, {model.leg_max}]" in msg and "leg(s) [" in msg
    with pytest.raises(StrokeLimitError) as info:
        check_poses(model, q)
    assert info.value.index == 7 and info.value.time is None and "t =" not in str(info.value)


def singular_pose(model) -> np.ndarray:
    """Home turned by 90 deg about z: the classic rotation singularity of this layout (a scan of
    thz finds det J changing sign there in both scenes; cond(J) ~ 1e16)."""
    return np.r_[model.home[:5], np.pi / 2]


@pytest.mark.parametrize("name", SCENES)
def test_singular_pose_raises_singularity_error_everywhere(name):
    """At home turned 90 deg about z (stroke limits dropped for the simulator, whose legs then
    reach 3.77 m; the micro scene's stay within its stroke): cond(J) > 1e10; check_poses,
    inverse_dynamics, inverse_dynamics_parts and forward_dynamics raise SingularityError with the
    sample index (batch: 5; single sample: 0) and the time for check_poses, never NaN. Near it
    (0.5 degree off, cond(J) > 100) nothing raises and the forces are finite."""
    model = level_model("micro", "full") if name == "micro" else no_stroke(name)[1]
    qs = singular_pose(model)
    assert inverse_kinematics(model, qs).cond > 1e10
    q, qd, qdd = (np.array(c) for c in random_states(name, 8, seed=4))
    q[5] = qs
    t = np.arange(8) * 0.01
    with pytest.raises(SingularityError) as info:
        check_poses(model, q, t)
    assert info.value.index == 5 and info.value.time == t[5] and "at sample 5" in str(info.value)
    sigma = inverse_dynamics(model, np.delete(q, 5, 0), np.delete(qd, 5, 0), np.delete(qdd, 5, 0))
    for fn, third in ((inverse_dynamics, qdd), (inverse_dynamics_parts, qdd), (forward_dynamics, qdd)):
        with pytest.raises(SingularityError, match="singular") as info:
            fn(model, q, qd, third)
        assert info.value.index == 5 and "at sample 5" in str(info.value) and "cond" in str(info.value)
        with pytest.raises(SingularityError) as info:
            fn(model, q[5], qd[5], third[5])
        assert info.value.index == 0
    near = qs - np.r_[0, 0, 0, 0, 0, np.radians(0.5)]
    assert 1e2 < inverse_kinematics(model, near).cond < 1e10
    check_poses(model, near[None])
    assert np.all(np.isfinite(inverse_dynamics(model, near, qd[0], qdd[0])))
    assert np.all(np.isfinite(sigma))


@pytest.mark.parametrize("name", SCENES)
def test_stroke_errors_from_the_dynamics_name_the_sample(name):
    """A pose past the stroke at sample 3: inverse_dynamics, inverse_dynamics_parts and
    forward_dynamics raise StrokeLimitError with index 3 naming the sample, never NaN."""
    model = level_model(name, "full")
    q, qd, qdd = (np.array(c) for c in random_states(name, 6, seed=5))
    q[3, 2] += 2.0 * model.leg_max
    for fn in (inverse_dynamics, inverse_dynamics_parts, forward_dynamics):
        with pytest.raises(StrokeLimitError) as info:
            fn(model, q, qd, qdd)
        assert info.value.index == 3 and "at sample 3" in str(info.value)
        assert "stroke" in str(info.value)


@pytest.mark.parametrize("name", SCENES)
def test_gimbal_lock(name):
    """At pitch thy = pi/2 (stroke limits dropped): forward_dynamics raises SingularityError
    saying gimbal lock (Euler rates undefined), while inverse_dynamics (which only needs E, not
    its inverse) returns the reference's forces to 1e-9 relative."""
    data, model = no_stroke(name)
    q = np.r_[model.home[:3], 0.0, np.pi / 2, 0.0]
    qd = np.r_[0.01, 0.02, -0.01, 0.3, -0.2, 0.1]
    qdd = np.r_[0.1, -0.2, 0.3, 1.0, 2.0, -1.0]
    assert inverse_kinematics(model, q).cond < 1e3
    with pytest.raises(SingularityError, match="gimbal") as info:
        forward_dynamics(model, q, qd, np.zeros(6))
    assert info.value.index == 0
    sigma = inverse_dynamics(model, q, qd, qdd)
    ref = reference_inverse_dynamics(data, q, qd, qdd)["sigma"]
    worst = np.abs(sigma - ref).max() / np.abs(ref).max()
    record(f"5 inverse dynamics at gimbal lock vs reference [{name}]", worst, 1e-9)
    assert worst <= 1e-9, worst


# --- bad arrays ---------------------------------------------------------------------------------

FUNCS = {"inverse_dynamics": (inverse_dynamics, ("q", "qd", "qdd")),
         "inverse_dynamics_parts": (inverse_dynamics_parts, ("q", "qd", "qdd")),
         "forward_dynamics": (forward_dynamics, ("q", "qd", "sigma"))}


NONFINITE_CASES = []
for _fn in FUNCS:
    for _array in range(3):
        for _value in ("nan", "inf", "-inf"):
            for _column in (2, 4):
                NONFINITE_CASES.append(pytest.param(
                    _fn, _array, _value, _column,
                    id=f"{_fn}-{FUNCS[_fn][1][_array]}-{_value}-col{_column}"))


@pytest.mark.parametrize("fn,array,value,column", NONFINITE_CASES)
@pytest.mark.parametrize("batch", [True, False], ids=["batch", "single"])
def test_nonfinite_input_raises_trajectory_error_naming_array_and_sample(fn, array, value,
                                                                         column, batch):
    """A NaN or +-inf in q, qd or qdd/sigma (a position or an angle column) at sample 4 of a
    batch (or in a single sample): TrajectoryError naming the array and the sample, not NaN."""
    func, names = FUNCS[fn]
    model = level_model("micro", "full")
    q, qd, qdd = random_states("micro", 6, seed=6)
    third = qdd if fn != "forward_dynamics" else inverse_dynamics(model, q, qd, qdd)
    arrays = [q.copy(), qd.copy(), third.copy()]
    arrays[array][4, column] = float(value)
    k = 4 if batch else 0
    if not batch:
        arrays = [x[4] for x in arrays]
    with pytest.raises(TrajectoryError) as info:
        func(model, *arrays)
    msg = str(info.value)
    assert f"non-finite value in {names[array]} at sample {k}" in msg, msg


BAD_SHAPES = {
    "5 columns": lambda q, qd, x: (q[:, :5], qd[:, :5], x[:, :5]),
    "7 columns": lambda q, qd, x: (np.hstack([q, q[:, :1]]), qd, x),
    "rows differ": lambda q, qd, x: (q, qd[:3], x),
    "third rows differ": lambda q, qd, x: (q, qd, x[:3]),
    "single vs batch": lambda q, qd, x: (q[0], qd, x),
    "single of 5": lambda q, qd, x: (q[0, :5], qd[0, :5], x[0, :5]),
    "single third of 5": lambda q, qd, x: (q[0], qd[0], x[0, :5]),
    "3-D": lambda q, qd, x: (q[None], qd[None], x[None]),
    "scalar": lambda q, qd, x: (1.0, qd[0], x[0]),
}


@pytest.mark.parametrize("fn", list(FUNCS))
@pytest.mark.parametrize("case", list(BAD_SHAPES))
def test_wrong_shapes_raise_trajectory_error(fn, case):
    """Arrays that are not (N, 6) or (6,) alike raise TrajectoryError naming an array and the
    shapes."""
    func, names = FUNCS[fn]
    model = level_model("micro", "full")
    q, qd, qdd = random_states("micro", 5, seed=7)
    with pytest.raises(TrajectoryError, match="must have shape") as info:
        func(model, *BAD_SHAPES[case](q, qd, qdd))
    assert any(f"'{n}'" in str(info.value) for n in names)


def test_non_numeric_entries_raise_trajectory_error():
    """q with a string entry raises TrajectoryError (a ValueError) naming the array."""
    model = level_model("micro", "full")
    q, qd, qdd = random_states("micro", 2, seed=8)
    bad = q.tolist()
    bad[1][3] = "a"
    with pytest.raises(TrajectoryError, match="q"):
        inverse_dynamics(model, bad, qd, qdd)


def test_empty_batch_returns_empty():
    """A batch of zero samples is not an error: (0, 6) in, (0, 6) out."""
    model = level_model("micro", "full")
    z = np.zeros((0, 6))
    assert inverse_dynamics(model, z, z, z).shape == (0, 6)
    assert forward_dynamics(model, z, z, z).shape == (0, 6)


def test_compiled_condition_number_equals_inverse_kinematics():
    """kinematics.condition_number (compiled, one pose) equals inverse_kinematics' cond(J) to
    1e-12 relative on random poses near home."""
    from stewart_fmu.kinematics import condition_number

    model = level_model("micro", "full")
    rng = np.random.default_rng(12)
    for _ in range(50):
        q = model.home + rng.normal(size=6) * np.r_[0.01, 0.01, 0.01, 0.2, 0.2, 0.2]
        ref = float(inverse_kinematics(model, q).cond)
        assert abs(condition_number(model, q) - ref) <= 1e-12 * ref
