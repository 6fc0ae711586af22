"""cffi build script of the axis loop (out-of-line API mode): `controller.native._axis`.

Compiles controller/native/axis.c together with the plant's C core (stewart_fmu/native/src,
one source of each algorithm) into one extension; the core's types (stewart_options,
stewart_data) come from its build script by `ffi.include`, so cdata made with
`stewart_fmu.native.core` (options, a stewart_data) pass straight to these functions.
setup.py runs it through `cffi_modules` on `pip install` (also editable); by hand:
`python controller/native/build_axis.py` builds the module in place.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]                       # the project root (setup.py's directory)
CORE = ROOT / "stewart_fmu" / "native"


def _core_builder():
    """stewart_fmu/native/build_core.py, loaded by path (setup.py runs build scripts outside
    the package): its FFI (declarations, sources, flags)."""
    spec = importlib.util.spec_from_file_location("_stewart_build_core", CORE / "build_core.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_core = _core_builder()

# Arrays as `void *` (as build_core does): Python passes ffi.from_buffer(array) untyped.
CDEF = """
#define AXIS_DIVERGED ...
void pid_voltages(double kp, double ki, double kd, double vmax, double dt, void *integral,
                  void *l_ref, void *ldot_ref, void *l, void *ldot, void *v_ff, void *v,
                  void *sat);
void advance_currents(double R, double Kt, double emf, double ilim, double decay,
                      double mean_decay, void *current, void *v, void *ldot, void *torque,
                      void *limited);
typedef struct {
    double kp, ki, kd, vmax, dt;
    double R, Kt, emf, ilim, decay, mean_decay;
    double gain;
    double bound;
} axis_loop;
typedef struct {
    double *l, *ldot, *q, *v, *i, *tau;
    unsigned char *sat;
} axis_records;
int closed_loop_run(void *params, const stewart_options *o, const axis_loop *c,
                    stewart_data *d, void *integral, void *current, void *t, long n,
                    void *l_ref, void *ldot_ref, void *v_ff, long k0, long k1, void *held,
                    const axis_records *rec, long *k_fail);
"""

ffibuilder = FFI()
ffibuilder.include(_core.ffibuilder)
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "controller.native._axis",
    '#include "axis.h"\n',
    sources=[_core._relative(HERE / "axis.c")] + [_core._relative(p) for p in _core.SOURCES],
    include_dirs=[_core._relative(HERE), _core._relative(CORE / "include")],
    extra_compile_args=_core.CFLAGS,
    libraries=["m"] if sys.platform != "win32" else [],
)

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT), verbose=False)
