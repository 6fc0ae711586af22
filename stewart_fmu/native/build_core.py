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
# -ffp-contract=off: no fused multiply-add, so that the core, the exported FMU (the same flags,
# stewart_fmu/fmu/export.py) and the recorded reference agree to the last bit on machines with
# and without FMA; portable flags only.
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-math-errno"]


# X-macro tables of stewart_table.h that stewart.h expands: the prefix of the names each defines
# and its count
_X_TABLES = {"STEWART_PARAMS": ("STEWART_P_", "STEWART_N_PARAMS"),
             "STEWART_STANDARD": ("STEWART_S_", "STEWART_N_STANDARD"),
             "STEWART_REACH_PARAMS": ("STEWART_R_", "STEWART_N_REACH"),
             "STEWART_LIMITS": ("STEWART_LIMIT_", "STEWART_N_LIMITS"),
             "STEWART_ELASTIC": ("STEWART_E_", "STEWART_N_ELASTIC")}


def _cdef() -> str:
    """The declarations of stewart.h for cffi, which expands no macro: comments and
    preprocessor lines dropped (continuations included), the object-like #define constants of
    stewart.h and stewart_table.h declared (floating-point ones as `static const double`, the
    others as `#define NAME ...`: cffi reads their values from the compiled core), and the
    X-macro expansions of stewart.h replaced by the names they define (_X_TABLES)."""
    header = _joined(HERE / "include" / "stewart.h")
    table = _joined(HERE / "include" / "stewart_table.h")
    out = [_constant(line) for line in table.splitlines() if line.strip().startswith("#define")]
    for line in header.splitlines():
        s = line.strip()
        if s.startswith("#define"):
            out.append(_constant(s))
        elif (section := next((t for t in _X_TABLES if f"{t}(" in s), None)) is not None:
            prefix, count = _X_TABLES[section]
            out += [f"#define {prefix}{name} ..." for name in _table_names(table, section)]
            out.append(f"#define {count} ...")
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


def _constant(line: str) -> str:
    """cffi's form of an object-like #define ("" for a function-like macro or a guard)."""
    define = re.fullmatch(r"#define\s+(\w+)\s+(.+?)\s*", line.strip())
    if not define:
        return ""
    name, value = define.groups()
    if re.fullmatch(r"\d+", value):          # integer literals (array sizes too)
        return f"#define {name} {value}"
    if re.fullmatch(r"[-+]?[\d.]+([eE][-+]?\d+)?", value):   # floating-point limits
        return f"static const double {name};"
    return f"#define {name} ..."             # an expression: its value comes from C


def _joined(path: Path) -> str:
    """A header's text without comments, continuation lines joined."""
    text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
    return re.sub(r"\\\n", " ", text)


def _table_names(table: str, macro: str) -> list[str]:
    """The NAME column of an X-macro table of stewart_table.h (its entries' first arguments)."""
    body = re.search(rf"#define {macro}\(X\)(.*)", table).group(1)
    return re.findall(r"\bX\(\s*(\w+)\s*,", body)


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
