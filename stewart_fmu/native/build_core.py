"""cffi build script of the C core (out-of-line API mode): `stewart_fmu.native._core`.

setup.py runs it through `cffi_modules` on `pip install` (also editable); by hand:
`python stewart_fmu/native/build_core.py` builds the module in place.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]            # the project root (setup.py's directory)
SOURCES = sorted((HERE / "src").glob("*.c"))
# -ffp-contract=off: no fused multiply-add, as numba compiles the Python kernels (keeps the
# C results equal to them to the last bits on machines with FMA); portable flags only.
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-math-errno"]


def _cdef() -> str:
    """The declarations of stewart.h for cffi: preprocessor lines and comments dropped, the
    #define constants turned into cffi's `#define NAME ...` form."""
    text = (HERE / "include" / "stewart.h").read_text()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    out = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#define") and len(s.split()) >= 3:
            _, name, value = s.split(None, 2)
            if re.fullmatch(r"\d+", value):        # integer constants (array sizes too)
                out.append(f"#define {name} {value}")
            else:                                   # floating-point limits
                out.append(f"static const double {name};")
        elif s.startswith("#") or s in ('extern "C" {', "}") or not s:
            continue
        else:
            out.append(line)
    decls = "\n".join(out)
    # Array arguments as `void *` for cffi (the C prototypes keep their types; C converts void *
    # implicitly): Python then passes ffi.from_buffer(array) without a type, ~35 ns less per
    # argument than from_buffer("double[]", array). Struct fields are left as declared.
    def untyped(m: re.Match) -> str:
        args = re.sub(r"\b(?:const\s+)?double\s*\*\s*(\w+)", r"void *\1", m.group(0))
        return re.sub(r"\b(?:const\s+)?double\s+(\w+)\s*\[[^\]]*\]", r"void *\1", args)
    return re.sub(r"\([^()]*\)", untyped, decls)


def _relative(path: Path) -> str:
    """Source paths relative to the project root (setuptools wants relative paths)."""
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


ffibuilder = FFI()
ffibuilder.cdef(_cdef())
ffibuilder.set_source(
    "stewart_fmu.native._core",
    '#include "stewart.h"\n',
    sources=[_relative(p) for p in SOURCES],
    include_dirs=[_relative(HERE / "include")],
    extra_compile_args=CFLAGS,
    libraries=["m"] if sys.platform != "win32" else [],
)

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT), verbose=False)
