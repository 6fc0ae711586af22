"""Stiffness and modes: one pose in C against the same computation in numpy, and a map.

    python benchmarks/bench_modes.py [--runs N] [--poses N]

Scene scenes/motion_simulator.toml (its [stiffness]) with a payload off C. One pose: the C
core's stiffness and six modes (stewart_modes; per pose in a batch call, and one Python call
through stewart_fmu.stiffness.modes with its checks and the damping ratios, numpy's eig of the
12x12 first-order form) against numpy (the stiffness of
stiffness.c's formulas in numpy, the mass matrix of kane_terms, the Python reference of Eq. 7
with the payload as a body of its own, plus the drives', and scipy.linalg.eigh), the ratio in the same run. The map:
the lowest frequency and the compliance at the pivot over N random poses in one C call
(stewart_modes_batch, modes_map's kernel), one core. Prints the best of N runs of each.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.linalg

from stewart_fmu import load_scene
from stewart_fmu import stiffness as S
from stewart_fmu.kane_terms import drive_inertia, mass_matrix
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model, PayloadParams
from stewart_fmu.native import core

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "motion_simulator.toml"
PAYLOAD = PayloadParams(mass=500.0, com=(0.39, -0.26, 0.65), inertia=(100.0, 120.0, 150.0, 10.0, -5.0, 3.0))
TARGET_POSE_US, TARGET_MAP_S = 20.0, 1.0


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def numpy_modes(model: Model, q: np.ndarray) -> np.ndarray:
    """w^2 of the six modes in numpy: the same stiffness (springs, leg weights, payload, the
    geometric term; the static leg forces from the core's generalized gravity forces),
    kane_terms' mass matrix (the payload a body of its own) with the drives', scipy's eigh."""
    kin = inverse_kinematics(model, q, with_cond=False)
    R = kin.rotation if kin.rotation is not None else None
    u, l, J = kin.unit_vectors, kin.lengths, kin.jacobian
    th = q[3:]
    cx, sx, cy, sy, cz, sz = np.cos(th[0]), np.sin(th[0]), np.cos(th[1]), np.sin(th[1]), np.cos(th[2]), np.sin(th[2])
    R = (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
         @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))
    r = model.platform_joints @ R.T
    g = model.gravity
    p = model.payload
    rho = R @ np.asarray(p.com)
    Fp = p.mass * g
    gen, _, _ = core.twist_forces(model.native, q, np.zeros(6), np.zeros(6))   # weights, payload's too
    sigma = np.linalg.solve(J.T, -gen[3])
    lg = model.legs
    mu = lg.lower_mass * lg.lower_com - lg.upper_mass * lg.upper_com
    P = np.eye(3)[None] - u[:, :, None] * u[:, None, :]
    gu = u @ g
    H = (model.stiffness.leg_legs[:, None, None] * u[:, :, None] * u[:, None, :]
         - (sigma / l)[:, None, None] * P
         - (mu / l**2)[:, None, None] * (-(g[None, :, None] * u[:, None, :] + u[:, :, None] * g[None, None, :])
                                         - gu[:, None, None] * np.eye(3) + 3 * gu[:, None, None] * u[:, :, None] * u[:, None, :]))
    grad = -sigma[:, None] * u - (mu / l)[:, None] * (g[None] - gu[:, None] * u) - lg.upper_mass * g[None]
    A = np.concatenate([np.broadcast_to(np.eye(3), (6, 3, 3)), -np.array([_skew(x) for x in r])], axis=2)
    K = np.einsum("iak,iab,ibl->kl", A, H, A)
    geo = 0.5 * (np.einsum("ia,ib->ab", grad, r) + np.einsum("ia,ib->ab", r, grad)) - np.sum(grad * r) * np.eye(3)
    gp = -Fp
    geo += 0.5 * (np.outer(gp, rho) + np.outer(rho, gp)) - (gp @ rho) * np.eye(3)
    K[3:, 3:] += geo
    M = J.T @ (mass_matrix(model, q) + drive_inertia(model)) @ J   # the payload a body of kane_terms
    return scipy.linalg.eigh(K, M, eigvals_only=True)


def _best(fn, runs: int, inner: int) -> float:
    best = np.inf
    for _ in range(runs):
        start = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - start) / inner)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--poses", type=int, default=10_000)
    args = ap.parse_args()
    model = replace(load_scene(SCENE), payload=PAYLOAD)
    q = model.home + np.array([0.05, -0.03, 0.04, 0.03, -0.02, 0.05])
    w2_ref = numpy_modes(model, q)
    assert np.allclose(S.modes(model, q).omega2, w2_ref, rtol=1e-9), "numpy and C disagree"
    rng = np.random.default_rng(1)
    Q = model.home + rng.uniform(-1, 1, (args.poses, 6)) * np.array([0.2, 0.2, 0.2, 0.05, 0.05, 0.05])
    pivot = np.zeros(3)
    n_batch = 2000
    c_batch = _best(lambda: core.modes_batch(model.native, model.elastic, Q[:n_batch], pivot, False),
                    args.runs, 1) / n_batch
    c_call = _best(lambda: S.modes(model, q), args.runs, 200)
    numpy_call = _best(lambda: numpy_modes(model, q), args.runs, 20)
    map_s = _best(lambda: S.modes_map(model, Q, pivot), args.runs, 1)
    print(f"stiffness + six modes at one pose ({SCENE.name}, payload {PAYLOAD.mass:g} kg)")
    print(f"  {'':34s} {'us/pose':>10s} {'vs numpy':>9s}")
    print(f"  {'C, per pose of a batch call':34s} {1e6 * c_batch:10.2f} {numpy_call / c_batch:8.0f}x"
          f"   (target {TARGET_POSE_US:g} us)")
    print(f"  {'modes(), C + numpy damping':34s} {1e6 * c_call:10.2f} {numpy_call / c_call:8.0f}x")
    print(f"  {'numpy + scipy eigh':34s} {1e6 * numpy_call:10.2f} {1:8.0f}x")
    print(f"map of {args.poses} poses (lowest frequency, compliance at the pivot, weakest "
          f"direction): {map_s:.3f} s   (target {TARGET_MAP_S:g} s)")


if __name__ == "__main__":
    main()
