"""What the feasibility engine (stewart_fmu.reach, native/src/reach.c) costs, against a plain
numpy implementation of the same limits timed in the same run.

    python benchmarks/bench_reach.py [--poses N] [--threads]

The micro-manipulator with cones of 0.5 rad and legs of 3 mm radius: stroke (both ends), both
joint cones, the 15 leg pairs' clearance and cond(J) (limit 100) at each pose. Rows:

- one pose: one engine call (Engine.check of one pose; and the bare C call through cffi),
  against the numpy implementation on one pose;
- N poses (default 10^6): one batch call, against the numpy implementation vectorised over the
  poses (in blocks of 10^5);
- N poses without cond(J): the same without the SVD (cond_limit None);
- a reach query: Engine.travel from home along a random direction to 1e-9, against a numpy
  march + bisection with the vectorised margins at one pose per step;
- the constant-orientation map of the shipped micro-manipulator (stroke and cond(J)) at
  --map-grid (default 1 mm; stewart_sim.studies.workspace.maps): the same map code driven by
  the numpy implementation (its binding limits and travel) at --numpy-map-grid (default 10 mm:
  its cost grows with the columns, 100 times as many at 1 mm), against the engine on that grid;
  the 1 mm row is the engine's alone.

CPU time of this process, the least of a few runs (run with OPENBLAS_NUM_THREADS=1: numpy's SVD
then uses one core, as the engine does). Printed, never asserted in tests.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from stewart_fmu.reach import Engine
from stewart_fmu.scene import read_scene_dict, scene_from_dict

MICRO = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"
CONE, RADIUS, COND = 0.5, 0.003, 100.0
PAIRS = [(i, j) for i in range(6) for j in range(i + 1, 6)]


class NumpyLimits:
    """The same margins, vectorised in numpy (Ericson's clamped closest points per pair); the
    joint cones and the leg clearance left out (their margins inf) with joints=False, as for
    the shipped scene, which has neither."""

    def __init__(self, model, joints: bool = True):
        self.joints = joints
        self.a, self.p = np.asarray(model.base_joints), np.asarray(model.platform_joints)
        self.lo, self.hi = model.leg_min, model.leg_max
        self.lc = model.characteristic_length
        _, L, R = self.legs(np.asarray(model.home)[None])
        self.base_axes = L[0] / np.linalg.norm(L[0], axis=1)[:, None]
        self.top_axes = (R[0].T @ self.base_axes.T).T

    def legs(self, q):
        th = q[:, 3:]
        cx, sx, cy, sy, cz, sz = (np.cos(th[:, 0]), np.sin(th[:, 0]), np.cos(th[:, 1]),
                                  np.sin(th[:, 1]), np.cos(th[:, 2]), np.sin(th[:, 2]))
        R = np.empty((len(q), 3, 3))
        R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
        R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
        R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = -sy, cy * sx, cy * cx
        P = q[:, None, :3] + np.einsum("nij,kj->nki", R, self.p)
        return P, P - self.a[None], R

    def margins(self, q, with_cond: bool = True) -> np.ndarray:
        """(N, 6): stroke_min, stroke_max, base_cone, platform_cone, leg_clearance, cond."""
        P, L, R = self.legs(q)
        l = np.linalg.norm(L, axis=2)
        u = L / l[..., None]
        out = np.empty((len(q), 6))
        out[:, 0] = np.min(l - self.lo, axis=1)
        out[:, 1] = np.min(self.hi - l, axis=1)
        out[:, 2:5] = np.inf
        if with_cond:
            J = np.concatenate([u, np.cross(P - q[:, None, :3], u) / self.lc], axis=2)
            out[:, 5] = COND - np.linalg.cond(J)
        else:
            out[:, 5] = np.inf
        if not self.joints:
            return out
        out[:, 2] = CONE - np.max(np.arccos(np.clip(np.sum(u * self.base_axes, -1), -1, 1)), 1)
        top = np.einsum("nij,kj->nki", R, self.top_axes)
        out[:, 3] = CONE - np.max(np.arccos(np.clip(np.sum(u * top, -1), -1, 1)), 1)
        i, j = np.array(PAIRS).T
        d1, d2, r = L[:, i], L[:, j], self.a[i] - self.a[j]
        a, e = np.sum(d1 * d1, -1), np.sum(d2 * d2, -1)
        b, c, f = np.sum(d1 * d2, -1), np.sum(d1 * r, -1), np.sum(d2 * r[None], -1)
        den = a * e - b * b
        s = np.where(den > 0, np.clip((b * f - c * e) / np.where(den > 0, den, 1), 0, 1), 0)
        t = (b * s + f) / e
        s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
        t = np.clip(t, 0, 1)
        gap = (self.a[i] + d1 * s[..., None]) - (self.a[j] + d2 * t[..., None])
        out[:, 4] = np.min(np.linalg.norm(gap, axis=-1), axis=1) - 2 * RADIUS
        return out

    def travel(self, q0, d, hmax, tol=1e-9, reach=np.inf):
        """A march (steps from hmax / 64 doubling to hmax, up to reach), then bisection to
        tol: the engine's answer where no region outside a limit is narrower than a step."""
        lo, h = 0.0, hmax / 64
        while True:
            hi = min(lo + h, reach)
            if np.any(self.margins((q0 + hi * d)[None])[0] < 0):
                break
            if hi >= reach:
                return reach
            lo, h = hi, min(2 * h, hmax)
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            if np.any(self.margins((q0 + mid * d)[None])[0] < 0):
                hi = mid
            else:
                lo = mid
        return lo


class NumpyEngine:
    """What the workspace map asks of an Engine (model, binding, travel in the platform frame),
    answered by NumpyLimits: the same map algorithm on the numpy margins."""

    def __init__(self, model, limits: NumpyLimits):
        self.model, self.limits = model, limits

    def binding(self, Q) -> np.ndarray:
        out = self.limits.margins(np.asarray(Q, dtype=float)) < 0
        return np.where(out.any(axis=1), out.argmax(axis=1), -1)

    def travel(self, q0, direction, frame: str = "platform", reach: float = np.inf,
               step: float | None = None):
        assert frame == "platform" and step is not None
        return SimpleNamespace(step=self.limits.travel(np.asarray(q0, dtype=float),
                                                       np.asarray(direction, dtype=float), step,
                                                       reach=reach))


def best_of(fn, repeat: int) -> float:
    """The least CPU time of this process over `repeat` runs (s): on one core (the engine is
    single-threaded; run with OPENBLAS_NUM_THREADS=1 so numpy is too), and less sensitive than
    wall time to other processes on a busy machine."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=1_000_000)
    ap.add_argument("--map-grid", type=float, default=0.001, help="m; 0: no map row")
    ap.add_argument("--numpy-map-grid", type=float, default=0.01,
                    help="m, the grid of the map timed against numpy; 0: no such row")
    args = ap.parse_args()
    data = read_scene_dict(MICRO)
    data["joints"] = {"base_cone": CONE, "platform_cone": CONE}
    data["clearance"] = {"leg_radius": RADIUS}
    model = scene_from_dict(data, str(MICRO))
    eng, bare = Engine(model), Engine(model, cond_limit=None)
    ref = NumpyLimits(model)
    rng = np.random.default_rng(0)
    Q = model.home + rng.uniform(-1, 1, (args.poses, 6)) * [0.02, 0.02, 0.02, 0.3, 0.3, 0.3]
    one = np.ascontiguousarray(Q[:1])
    # the two agree (else the timing compares different work)
    got = eng.check(Q[:2000])
    want = ref.margins(Q[:2000])
    for k, name in enumerate(("stroke_min", "stroke_max", "base_cone", "platform_cone",
                              "leg_clearance")):
        assert np.allclose(got[name], want[:, k], rtol=0, atol=1e-9), name
    rows = []
    n_one = 2000
    t_c = best_of(lambda: [eng.check(one) for _ in range(n_one)], 3) / n_one
    t_np = best_of(lambda: [ref.margins(one) for _ in range(200)], 3) / 200
    rows.append(("one pose (Engine.check)", t_c, t_np))
    from stewart_fmu.native import core
    m, w = np.empty(10), np.empty(10, np.intc)
    ffi, lib = core.ffi, core.lib
    args_c = (model.native.ptr, ffi.from_buffer(eng.reach), ffi.from_buffer(one[0]), ffi.NULL,
              ffi.NULL, ffi.from_buffer(m), ffi.from_buffer("int[]", w))
    f = lib.stewart_reach_margins
    t_bare = best_of(lambda: [f(*args_c) for _ in range(20000)], 3) / 20000
    rows.append(("one pose (C call via cffi)", t_bare, t_np))
    block = 100_000

    def numpy_all(with_cond=True):
        for s in range(0, len(Q), block):
            ref.margins(Q[s:s + block], with_cond)
    t_c = best_of(lambda: eng.check(Q), 1)
    t_np = best_of(numpy_all, 1)
    rows.append((f"{len(Q):,} poses", t_c, t_np))
    t_c = best_of(lambda: bare.check(Q), 1)
    t_np = best_of(lambda: numpy_all(False), 1)
    rows.append((f"{len(Q):,} poses, no cond(J)", t_c, t_np))
    d = rng.normal(size=6) * [1, 1, 1, 5, 5, 5]
    d /= np.linalg.norm(d)
    lc = model.characteristic_length
    hmax = lc / 16 / np.hypot(np.linalg.norm(d[:3]), lc * np.linalg.norm(d[3:]))
    home = np.asarray(model.home, dtype=float)
    s_c = eng.travel(home, d).step
    s_np = ref.travel(home, d, hmax)
    t_c = best_of(lambda: [eng.travel(home, d) for _ in range(200)], 3) / 200
    t_np = best_of(lambda: ref.travel(home, d, hmax), 3)
    rows.append((f"reach query (steps {s_c:.9f} / {s_np:.9f})", t_c, t_np))
    if args.map_grid > 0 or args.numpy_map_grid > 0:
        from stewart_fmu import load_scene
        from stewart_sim.studies.workspace.maps import constant_orientation

        plain = Engine(load_scene(MICRO))
        home = plain.model.home
        twin = NumpyEngine(plain.model, NumpyLimits(plain.model, joints=False))
        for grid, engines in ((args.numpy_map_grid, (plain, twin)), (args.map_grid, (plain,))):
            if grid <= 0:
                continue
            found, times = [], []
            for e in engines:
                times.append(best_of(lambda: found.append(
                    constant_orientation(e, home, "platform", grid)), 1))
            name = f"map {grid * 1e3:g} mm: {found[0].volume * 1e3:.5f} l"
            if len(found) > 1:
                name += f" / {found[1].volume * 1e3:.5f} l"
            rows.append((name, times[0], times[1] if len(times) > 1 else None))
    print(f"{'workload':<44} {'engine':>12} {'numpy':>12} {'ratio':>8}")
    for name, a, b in rows:
        tail = f"{fmt(b):>12} {b / a:>7.1f}x" if b is not None else f"{'-':>12} {'-':>8}"
        print(f"{name:<44} {fmt(a):>12} {tail}")


def fmt(seconds: float) -> str:
    if seconds >= 1.0:
        return f"{seconds:.2f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds * 1e6:.2f} us"


if __name__ == "__main__":
    main()
