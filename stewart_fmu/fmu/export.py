"""Export a scene as a self-contained co-simulation FMU (FMI 2.0 or 3.0) in plain C.

The FMU's binary is the C core (stewart_fmu/native/include, src) and the FMI layer
(stewart_fmu/native/fmi) compiled with the system C compiler, plus a generated C file with the
scene's start values. It links libm only: no Python at run time. The FMU also carries every
source it was built from (sources/, with buildDescription.xml for FMI 3.0 and <SourceFiles>
for FMI 2.0), so it can be rebuilt on another platform. Where mingw-w64 is installed, the same
sources are also cross-compiled into a Windows DLL beside the host's binary (windows.py).
"""
from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..errors import SceneError, StewartError
from ..model import Model
from ..scene import parse_scene_bytes, read_scene_bytes, scene_from_dict
from . import model_description, variables, windows

MODEL_IDENTIFIER = "StewartPlant"
NATIVE = Path(__file__).resolve().parents[1] / "native"
# Portable flags: those of the core's own build (no fused multiply-add: bit for bit with the
# Python plant), no -march.
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-fno-math-errno", "-fPIC",
          "-fvisibility=hidden", "-Wall", "-Wextra", "-Wpedantic"]
FMI_SOURCES = {2: ["fmi/model.c", "fmi/glue.c", "fmi/fmi2Functions.c", "fmi/scene.c"],
               3: ["fmi/model.c", "fmi/glue.c", "fmi/fmi3Functions.c", "fmi/scene.c"]}
FMI_HEADERS = {2: ["fmi/model.h", "fmi/glue.h", "fmi/fmi_export.h", "fmi/fmi2_api.h"],
               3: ["fmi/model.h", "fmi/glue.h", "fmi/fmi_export.h", "fmi/fmi3_api.h"]}


SCENE_RESOURCE = "scene.toml"   # resources/scene.toml: the scene the FMU was exported from


class CompilerNotFoundError(StewartError):
    """No C compiler on this machine: set CC or install cc, gcc or clang."""


class BuildError(StewartError):
    """The C compiler failed on the FMU's sources (its output is in the message)."""


def find_compiler() -> str:
    """$CC if set, else the first of cc, gcc, clang on the PATH."""
    for name in ([os.environ["CC"]] if os.environ.get("CC") else []) + ["cc", "gcc", "clang"]:
        path = shutil.which(name)
        if path:
            return path
    raise CompilerNotFoundError("no C compiler found (tried $CC, cc, gcc, clang): install one "
                                "(e.g. apt install gcc) or set CC to its path")


def platform_folder(fmi_version: int, system: str | None = None,
                    machine: str | None = None) -> tuple[str, str]:
    """(binaries/<folder>, file extension) of this machine, or of the platform named as Python's
    platform.system() and platform.machine() name it there: linux64 / x86_64-linux and .so on
    Linux x86_64 (the platform this export is tested on); darwin64 / win64 and the FMI 3.0
    platform tuples elsewhere."""
    system = system or platform.system()
    machine = (machine or platform.machine()).lower()
    arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64"}.get(machine, machine)
    os_name = {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(system, system.lower())
    ext = {"darwin": ".dylib", "windows": ".dll"}.get(os_name, ".so")
    if fmi_version == 3:
        return f"{arch}-{os_name}", ext
    folder = {"linux": "linux64", "darwin": "darwin64", "windows": "win64"}.get(os_name)
    if folder is None or (os_name != "darwin" and arch != "x86_64"):
        raise BuildError(f"FMI 2.0 has no binaries folder for {system} {machine}: export FMI 3.0")
    return folder, ext


def core_sources(native: Path = NATIVE) -> list[str]:
    """The core's files, relative to `native`: include/*.h, src/*.h, src/*.c."""
    files = sorted(p.relative_to(native).as_posix()
                   for pattern in ("include/*.h", "src/*.h", "src/*.c") for p in native.glob(pattern))
    if not any(f.endswith(".c") for f in files):
        raise BuildError(f"the C core's sources are missing under {native}/src")
    return files


FMI_VERSIONS = (2, 3)
DEFAULT_FMI_VERSION = 2


def export_fmu(scene_path: str | Path, out_path: str | Path, fmi_version: int = DEFAULT_FMI_VERSION) -> Path:
    """Build the FMU of a scene file at out_path; returns out_path. The file is read once: its
    bytes are the FMU's resources/scene.toml and its Model the FMU's variables.

    SceneError for a bad scene (nothing written), CompilerNotFoundError without a C compiler,
    BuildError if compiling fails."""
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    text = read_scene_bytes(scene_path)
    model = scene_from_dict(parse_scene_bytes(text, scene_path), source=str(scene_path))
    return export_model(model, text, out_path, fmi_version)


def export_model(model: Model, scene_text: bytes, out_path: str | Path,
                 fmi_version: int = DEFAULT_FMI_VERSION) -> Path:
    """Build the FMU of a scene's Model at out_path (scene_text: the scene file as given, kept
    as resources/scene.toml for `run --fmu`'s check); returns out_path."""
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    if model.payload is not None:   # no FMU variable holds it: the FMU would drop it
        raise SceneError("payload", "the FMU has no payload parameters: export the scene without "
                         "[payload], or fold it into [platform]", model.source)
    compiler = find_compiler()
    platform_folder(fmi_version)   # BuildError before any work: no binaries folder for this platform
    out = Path(out_path)
    core = core_sources()
    c_files = [f for f in core if f.endswith(".c")] + FMI_SOURCES[fmi_version]
    with tempfile.TemporaryDirectory(prefix="stewart_native_fmu_") as tmp:
        root = Path(tmp) / "fmu"
        src = root / "sources"
        for rel in core + FMI_SOURCES[fmi_version][:-1] + FMI_HEADERS[fmi_version]:
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(NATIVE / rel, src / rel)
        table = variables.variables(model, fmi_version)
        (src / "fmi" / "scene.c").write_text(variables.scene_c_source(model, table, fmi_version))
        if fmi_version == 3:
            (src / "buildDescription.xml").write_bytes(
                model_description.build_description_xml(MODEL_IDENTIFIER, c_files))
        (root / "modelDescription.xml").write_bytes(
            model_description.build(model, table, fmi_version, MODEL_IDENTIFIER, c_files))
        build_binaries(compiler, [str(src / f) for f in c_files], [], root, MODEL_IDENTIFIER,
                       fmi_version, "the FMU")
        (root / "resources").mkdir()   # the scene as given: `run --fmu` checks it matches
        (root / "resources" / SCENE_RESOURCE).write_bytes(scene_text)
        doc = root / "documentation"
        doc.mkdir()
        (doc / "index.html").write_text(_documentation(model.name, fmi_version))
        pack(root, Path(tmp) / "packed.fmu", out)
    return out


def pack(root: Path, packed: Path, out: Path) -> None:
    """Zip the tree `root` into `packed` (deflated, sorted, POSIX names), then move it to `out`:
    whole or not at all, an existing `out` is replaced only at the end (FMUs, SSPs)."""
    with zipfile.ZipFile(packed, "w", zipfile.ZIP_DEFLATED) as z:
        for path in sorted(root.rglob("*")):
            if path.is_file():
                z.write(path, path.relative_to(root).as_posix())
    out.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(packed, out)


def build_binaries(compiler: str, sources: list[str], flags: list[str], root: Path,
                   identifier: str, fmi_version: int, what: str) -> None:
    """Compile the C `sources` (with CFLAGS and the extra `flags`, e.g. include directories)
    into the FMU tree `root`: binaries/<this platform>/<identifier><ext> with `compiler` and,
    where mingw-w64 is installed, binaries/<Windows>/<identifier>.dll beside it (windows.py;
    without it one line on stderr says why), side by side. BuildError naming `what` with the
    first failure's output."""
    folder, ext = platform_folder(fmi_version)
    binary = root / "binaries" / folder / f"{identifier}{ext}"
    binary.parent.mkdir(parents=True)
    host = [f for f in CFLAGS if not (ext == ".dll" and f == "-fPIC")] + flags
    builds = [([compiler, *host, "-shared", "-o", str(binary), *sources, "-lm"], binary)]
    win_folder, _ = platform_folder(fmi_version, windows.SYSTEM, windows.MACHINE)
    mingw = windows.find_mingw()
    if win_folder != folder and mingw is None:
        print(windows.missing_note(), file=sys.stderr)
    elif win_folder != folder:
        dll = root / "binaries" / win_folder / f"{identifier}.dll"
        dll.parent.mkdir(parents=True)
        builds.append((windows.command(mingw, CFLAGS + flags, sources, dll), dll))
    with ThreadPoolExecutor(len(builds)) as pool:
        procs = list(pool.map(lambda b: subprocess.run(b[0], capture_output=True, text=True), builds))
    for proc, (cmd, out) in zip(procs, builds):
        if proc.returncode != 0 or not out.exists():
            raise BuildError(f"compiling {what} failed ({' '.join(cmd)}):\n{proc.stderr[-4000:]}")


def _documentation(name: str, fmi_version: int) -> str:
    return (f"<html><body><h1>{name} (FMI {fmi_version}.0)</h1>"
            "<p>Stewart platform plant: inputs sigma[1..6] (rack forces, N) and, with a drive, "
            "tau[1..6] (motor torques, N m; FMI 3.0: arrays of six, as are the other "
            "quantities of several values), held over each communication step; sigma starts at "
            "the static force holding the home pose and tau at 0, so the platform stays put "
            "when no input is set. Default experiment: 0 to 1 s, 1 ms steps. Outputs: leg "
            "lengths and rates, pose and rates, twist, cond(J), rack forces and their parts. "
            "Parameters: the scene's values, q0/qd0, solver.method (rk4, euler, dopri5), "
            "solver.max_step, solver.rtol, solver.atol. A step into a stroke limit, a "
            "singular pose or a failed power-balance check returns Discard with the state "
            "unchanged, and the reason is logged (category logStatusDiscard) even with logging "
            "off. An input outside its declared min/max, or not finite, is refused with Error; an "
            "output that would be NaN or infinite is Error, never OK. A serialized FMU state "
            "carries a checksum, which detects corruption, not forgery: every field of a state "
            "is validated (finite, in range, consistent with the parameters) before it is "
            "applied. Self-contained C (libm only); rebuild from sources/ with any C99 "
            "compiler.</p></body></html>\n")
