"""Thin typed wrappers over the C core (stewart.h) for numpy float64 arrays.

The wrappers raise nothing themselves: each returns the C status code (the STEWART_* values,
equal to stewart_fmu.status: OK, NONFINITE, ..., TOO_MANY_STEPS, STEP_TOO_SMALL, and
UNSTABLE = 102 = ENERGY_GAIN, STATE_NONFINITE = 103 from the step's check) with the results,
so the Python API layer can map codes to its typed errors. Inputs must be C-contiguous float64 arrays of the documented shapes
(unchecked, for speed: the C side trusts the sizes); outputs are written into `out` when
given (no allocation), else into new arrays.

params: the packed model vector (Model.params, N_PARAMS floats). `native_params(model.params)`
converts it once to the C pointer the calls take; every function also accepts the numpy
vector itself (one conversion per call more).
"""
from __future__ import annotations

import numpy as np

from ._core import ffi, lib

OK, NONFINITE, STROKE, SINGULAR, GIMBAL, OVERFLOW = (
    lib.STEWART_OK, lib.STEWART_NONFINITE, lib.STEWART_STROKE, lib.STEWART_SINGULAR,
    lib.STEWART_GIMBAL, lib.STEWART_OVERFLOW)
TOO_MANY_STEPS, STEP_TOO_SMALL, UNSTABLE, STATE_NONFINITE = (
    lib.STEWART_TOO_MANY_STEPS, lib.STEWART_STEP_TOO_SMALL, lib.STEWART_UNSTABLE,
    lib.STEWART_STATE_NONFINITE)
# The compiled methods by name (stewart_method_name) and the core's default options: the one
# spelling of both (IntegratorOptions, the FMU's solver.method and its messages take them).
METHODS = {ffi.string(lib.stewart_method_name(k)).decode(): k for k in range(lib.STEWART_N_METHODS)}
DEFAULTS = lib.stewart_default_options()
N_PARAMS = lib.STEWART_N_PARAMS
N_ENERGY = lib.STEWART_N_ENERGY
ENERGY_TOL = lib.STEWART_ENERGY_TOL

# Arrays reach C through ffi.from_buffer (no copy; the cffi declarations take them as void *,
# see build_core._cdef): the C side reads them as double arrays of the documented sizes.
_buf = ffi.from_buffer


class NativeParams:
    """The packed parameters as the C core reads them: a private read-only copy and its
    pointer (convert once per model, pass to every call)."""

    __slots__ = ("array", "ptr")

    def __init__(self, params: np.ndarray):
        arr = np.array(params, dtype=np.float64, copy=True)
        if arr.shape != (N_PARAMS,):
            raise ValueError(f"params must have {N_PARAMS} entries, got shape {arr.shape}")
        self.array = arr
        self.ptr = _buf(arr)
        arr.flags.writeable = False


def native_params(params) -> NativeParams:
    return params if isinstance(params, NativeParams) else NativeParams(params)


def _p(params):
    return params.ptr if type(params) is NativeParams else _buf(params)


DEFAULT_METHOD = next(name for name, k in METHODS.items() if k == DEFAULTS.method)


def options(method: str = DEFAULT_METHOD, rtol: float = DEFAULTS.rtol, atol: float = DEFAULTS.atol,
            max_step: float = DEFAULTS.max_step, max_steps: int = DEFAULTS.max_steps,
            energy_tol: float = DEFAULTS.energy_tol):
    """A stewart_options struct (cdata; keep it and reuse it)."""
    o = ffi.new("stewart_options *")
    o.method = METHODS[method]
    o.rtol, o.atol, o.max_step, o.max_steps, o.energy_tol = rtol, atol, max_step, max_steps, energy_tol
    return o


def state_size(params) -> int:
    return lib.stewart_state_size(_p(params))


# --- dynamics --------------------------------------------------------------------------------

# The single-sample wrappers bind what they call as default arguments (local lookups): a call
# costs the four from_buffer conversions and the C call, little else.

def inverse_dynamics(params, q, qd, qdd, out=None, _b=_buf, _np=NativeParams, _e=np.empty,
                     _f=lib.stewart_inverse_dynamics):
    """(sigma (6,), status) of one sample."""
    if out is None:
        out = _e(6)
    return out, _f(params.ptr if type(params) is _np else _b(params), _b(q), _b(qd), _b(qdd),
                   _b(out))


def inverse_dynamics_parts(params, q, qd, qdd, out=None):
    """(parts (6 parts, 6 legs) in dynamics.PARTS order, status) of one sample."""
    if out is None:
        out = np.empty((6, 6))
    return out, lib.stewart_inverse_dynamics_parts(_p(params), _buf(q), _buf(qd),
                                                   _buf(qdd), _buf(out))


def forward_dynamics(params, q, qd, sigma, out=None, _b=_buf, _np=NativeParams, _e=np.empty,
                     _f=lib.stewart_forward_dynamics):
    """(qdd (6,), status) of one sample."""
    if out is None:
        out = _e(6)
    return out, _f(params.ptr if type(params) is _np else _b(params), _b(q), _b(qd), _b(sigma),
                   _b(out))


def _batch(fn, shape, params, a, b, c, out):
    n = a.shape[0]
    if out is None:
        out = np.empty((n,) + shape)
    status = ffi.new("int *")
    index = fn(_p(params), n, _buf(a), _buf(b), _buf(c), _buf(out), status)
    return out, index, status[0]


def inverse_dynamics_batch(params, Q, QD, QDD, out=None):
    """(sigma (N, 6), index of the first bad sample or -1, its status)."""
    return _batch(lib.stewart_inverse_dynamics_batch, (6,), params, Q, QD, QDD, out)


def inverse_dynamics_parts_batch(params, Q, QD, QDD, out=None):
    """(parts (N, 6, 6), index of the first bad sample or -1, its status)."""
    return _batch(lib.stewart_inverse_dynamics_parts_batch, (6, 6), params, Q, QD, QDD, out)


def regressor_batch(params, Q, QD, QDD, out=None):
    """(Y (N, 6, N_STANDARD), index of the first bad sample or -1, its status)."""
    return _batch(lib.stewart_regressor_batch, (6, lib.STEWART_N_STANDARD), params, Q, QD, QDD, out)


def forward_dynamics_batch(params, Q, QD, SIGMA, out=None):
    """(qdd (N, 6), index of the first bad sample or -1, its status)."""
    return _batch(lib.stewart_forward_dynamics_batch, (6,), params, Q, QD, SIGMA, out)


# --- kinematics and Kane terms ---------------------------------------------------------------

def leg_state(params, q, qd):
    """(lengths, rates, omega, status)."""
    l, ld, om = np.empty(6), np.empty(6), np.empty(3)
    st = lib.stewart_leg_state(_p(params), _buf(q), _buf(qd), _buf(l),
                               _buf(ld), _buf(om))
    return l, ld, om, st


def jacobian(params, q, scaled: bool = False):
    """(J (6, 6), status); scaled: rotational columns divided by the characteristic length."""
    J = np.empty((6, 6))
    return J, lib.stewart_jacobian(_p(params), _buf(q), int(scaled), _buf(J))


def condition_number(params, q):
    """(cond of the scaled J, status)."""
    c = ffi.new("double *")
    st = lib.stewart_condition_number(_p(params), _buf(q), c)
    return c[0], st


def twist_forces(params, q, qd, qdd):
    """(gen (4, 6), leg rows (6, 3) of (l, ldot, lddot), status) (the core's stewart_twist_forces, kane.c)."""
    gen, leg = np.empty((4, 6)), np.empty((6, 3))
    st = lib.stewart_twist_forces(_p(params), _buf(q), _buf(qd), _buf(qdd),
                                  _buf(gen), _buf(leg))
    return gen, leg, st


def mass_matrix(params, q):
    """(M_nu (6, 6), status), the twist-space mass matrix (stewart_mass_matrix, kane.c)."""
    M = np.empty((6, 6))
    return M, lib.stewart_mass_matrix(_p(params), _buf(q), _buf(M))


# --- plant -----------------------------------------------------------------------------------

def derivative(params, y, rack, out=None):
    """(y' , status) at the plant state y (12 or 24) with the rack forces held."""
    if out is None:
        out = np.empty(y.shape[0])
    return out, lib.stewart_derivative(_p(params), _buf(y), _buf(rack), _buf(out))


def plant_parts(params, y, rack, out=None):
    """(parts (6 parts, 6 legs) in dynamics.PARTS order, status) at the plant state y under the
    rack forces (stewart_plant_parts: with a transmission, the leg side's)."""
    if out is None:
        out = np.empty((6, 6))
    return out, lib.stewart_plant_parts(_p(params), _buf(y), _buf(rack), _buf(out))


def spring_forces(params, y):
    f = np.empty(6)
    return f, lib.stewart_spring_forces(_p(params), _buf(y), _buf(f))


def initial_state(params, q, qd, rack=None):
    y = np.empty(state_size(params))
    lib.stewart_initial_state(_p(params), _buf(q), _buf(qd),
                              ffi.NULL if rack is None else _buf(rack), _buf(y))
    return y


def energy_terms(params, y, out=None):
    """(T, V_g, V_s, d_1..d_6) at y (energy.energy_terms)."""
    if out is None:
        out = np.empty(N_ENERGY)
    lib.stewart_energy_terms(_p(params), _buf(y), _buf(out))
    return out


def step_energy(params, y1, e0, e1, rack, tol, h):
    """(finite, excess, allowed) the power balance of a step of length h (stability.py) (e1 written)."""
    ex, al = ffi.new("double *"), ffi.new("double *")
    ok = lib.stewart_step_energy(_p(params), _buf(y1), _buf(e0), _buf(e1),
                                 _buf(rack), tol, h, ex, al)
    return bool(ok), ex[0], al[0]


def advance(params, opts, y0, y1, rack, h, step_guess=None):
    """y1 = y0 advanced over h: (status, next step guess, evaluations)."""
    sg = ffi.new("double *", opts.max_step if step_guess is None else step_guess)
    ev = ffi.new("long *")
    st = lib.stewart_advance(_p(params), opts, _buf(y0), _buf(y1), _buf(rack), h,
                             sg, ev)
    return st, sg[0], ev[0]


def step(params, opts, y0, y1, rack, h, e0, e1, step_guess=None):
    """The plant step (stewart_step): (status, next step guess, evaluations, excess, allowed)."""
    sg = ffi.new("double *", opts.max_step if step_guess is None else step_guess)
    ev, ex, al = ffi.new("long *"), ffi.new("double *"), ffi.new("double *")
    st = lib.stewart_step(_p(params), opts, _buf(y0), _buf(y1), _buf(rack), h, sg,
                          ev, _buf(e0), _buf(e1), ex, al)
    return st, sg[0], ev[0], ex[0], al[0]


def refusal(params, method: str, t: float, h: float, status: int, y, rack, excess: float = 0.0,
            allowed: float = 0.0) -> str:
    """The message of a refused step (stewart_refusal): y and rack at the start of the step."""
    buf = ffi.new("char[1024]")
    lib.stewart_refusal(buf, 1024, _p(params), method.encode(), t, h, status, _buf(y), _buf(rack),
                        excess, allowed)
    return ffi.string(buf).decode()


# --- the rules between a scene's keys (rules.c) -----------------------------------------------

RULE_OK, RULE_POSE_STROKE, RULE_POSE_SINGULAR, RULE_DERIVED = (
    lib.STEWART_RULE_OK, lib.STEWART_RULE_POSE_STROKE, lib.STEWART_RULE_POSE_SINGULAR,
    lib.STEWART_RULE_DERIVED)


def check_rules(params, home) -> tuple[int, int, int, str]:
    """stewart_check_rules: (rule, vr, element, reason) of the first broken rule between the
    keys and of the home pose; rule is RULE_OK when none is."""
    out = ffi.new("stewart_rule_break *")
    rule = lib.stewart_check_rules(_p(params), _buf(np.ascontiguousarray(home, dtype=float)), out)
    return rule, out.vr, out.element, ffi.string(out.reason).decode()


def check_drive(gear_ratio: float, pinion_radius: float, rotor_inertia) -> tuple[int, int, str]:
    """stewart_check_drive: (rule, vr, reason) of the drive's derived quantities (the rack
    ratio, each leg's m_d) computed from its keys; rule is RULE_OK when they are in bounds."""
    out = ffi.new("stewart_rule_break *")
    rotor = np.ascontiguousarray(np.broadcast_to(np.asarray(rotor_inertia, dtype=float), (6,)))
    rule = lib.stewart_check_drive(gear_ratio, pinion_radius, _buf(rotor), out)
    return rule, out.vr, ffi.string(out.reason).decode()


def check_pose(params, q, vr: int) -> tuple[int, str]:
    """stewart_check_pose: (rule, reason) of a pose the plant would start from, named by the
    value reference vr (RULE_OK, RULE_POSE_STROKE or RULE_POSE_SINGULAR)."""
    out = ffi.new("stewart_rule_break *")
    rule = lib.stewart_check_pose(_p(params), _buf(np.ascontiguousarray(q, dtype=float)), vr, out)
    return rule, ffi.string(out.reason).decode()


class Run:
    """One plant run in C (a stewart_data the caller owns, mjData style): the state, its energy
    terms, the dopri5 step guess and the held rack forces live in C memory; `y`, `energy` and
    `rack` are numpy views of it (write `rack[:] = F` to change the held forces). `step(h)`
    is one stewart_data_step: a single C call from Python."""

    def __init__(self, params, opts, q, qd=None, rack=None, t: float = 0.0):
        self.params = native_params(params)
        self.options = opts
        self.data = ffi.new("stewart_data *")
        self._rack = ffi.new("double[6]")
        self.rack = np.frombuffer(ffi.buffer(self._rack), dtype=np.float64)
        if rack is not None:
            self.rack[:] = rack
        q = np.ascontiguousarray(q, dtype=np.float64)
        qd = np.zeros(6) if qd is None else np.ascontiguousarray(qd, dtype=np.float64)
        lib.stewart_data_init(self.params.ptr, opts, _buf(q), _buf(qd), self._rack, t,
                              self.data)
        n = self.data.n
        self.y = np.frombuffer(ffi.buffer(self.data.y), dtype=np.float64)[:n]
        self.energy = np.frombuffer(ffi.buffer(self.data.energy), dtype=np.float64)
        self._done = ffi.new("long *")

    @property
    def time(self) -> float:
        return self.data.t

    def step(self, h: float) -> int:
        """One plant step of h with the held rack forces; on a status but OK the state stays."""
        return lib.stewart_data_step(self.params.ptr, self.options, self.data, self._rack, h)

    def run(self, h: float, n: int) -> tuple[int, int]:
        """n steps of h in one C call: (status, steps done)."""
        status = lib.stewart_data_run(self.params.ptr, self.options, self.data, self._rack, h,
                                      n, self._done)
        return status, self._done[0]


# --- stiffness and modes (stiffness.c) ----------------------------------------------------------

def stiffness(params, elastic, q):
    """(K (6, 6), static leg forces sigma (6,), status) at pose q (stewart_stiffness)."""
    K, sigma = np.empty((6, 6)), np.empty(6)
    return K, sigma, lib.stewart_stiffness(_p(params), _buf(elastic), _buf(q), _buf(K), _buf(sigma))


def compliance(params, elastic, q, pivot):
    """(Cp (6, 6), status): the compliance at the pivot (in C) (stewart_compliance)."""
    C = np.empty((6, 6))
    return C, lib.stewart_compliance(_p(params), _buf(elastic), _buf(q), _buf(pivot), _buf(C))


def modes_mass(params, q):
    """(M (6, 6), status): the mass matrix of the modes (stewart_modes_mass)."""
    M = np.empty((6, 6))
    return M, lib.stewart_modes_mass(_p(params), _buf(q), _buf(M))


def modes(params, elastic, q):
    """(w2 (6,), shapes (6, 6) rows, status) (stewart_modes)."""
    w2, shapes = np.empty(6), np.empty((6, 6))
    st = lib.stewart_modes(_p(params), _buf(elastic), _buf(q), _buf(w2), _buf(shapes))
    return w2, shapes, st


def modes_batch(params, elastic, Q, pivot, with_compliance: bool = True):
    """(W2 (N, 6), Cp (N, 6, 6) or None, index of the first failed pose or -1, its status)."""
    n = Q.shape[0]
    W2 = np.empty((n, 6))
    Cp = np.empty((n, 6, 6)) if with_compliance else None
    status = ffi.new("int *")
    index = lib.stewart_modes_batch(_p(params), _buf(elastic), n, _buf(Q), _buf(pivot), _buf(W2),
                                    ffi.NULL if Cp is None else _buf(Cp), status)
    return W2, Cp, index, status[0]


def static_forces(params, q):
    """(sigma (6,), status): the leg forces holding pose q at rest, payload included
    (stewart_static_forces)."""
    sigma = np.empty(6)
    return sigma, lib.stewart_static_forces(_p(params), _buf(q), _buf(sigma))
