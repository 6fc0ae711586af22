"""The FMU's Windows DLL (stewart_fmu/fmu/windows.py): cross-compiled with mingw-w64 beside the
Linux binary, it imports only Windows system and C runtime DLLs, exports exactly the FMI
functions the Linux binary exports, and, run by a Windows build of the C master
(tests/stewart_fmu/fmi_master.c) under wine, gives the Linux binary's outputs on the same inputs.

Not bit for bit: the DLL's sin, cos and pow are mingw-w64's (x87, linked in statically), which
differ from glibc's by one unit in the last place for a few arguments (measured here with
tests/stewart_fmu/libm_probe.c); the outputs then differ by about that much, well inside the
tolerance the native FMU keeps to the in-process Plant (RTOL, 1e-12 of each unit's scale).

The tools come from Debian (`make test` installs them as root): without them these tests are
skipped, saying why, except in CI as root, where their absence is a failure.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

from stewart_fmu import Model, inverse_dynamics, load_scene
from stewart_fmu.fmu import windows
from stewart_fmu.fmu.export import MODEL_IDENTIFIER, export_fmu
from tests.helpers import SCENE_FILES, record

HERE = Path(__file__).resolve().parent
FMI_INCLUDE = HERE.parents[1] / "stewart_fmu" / "native" / "fmi"
FOLDERS = {2: ("linux64", "win64"), 3: ("x86_64-linux", "x86_64-windows")}
OBJDUMP = "x86_64-w64-mingw32-objdump"   # binutils-mingw-w64-x86-64, a dependency of the compiler
# What every Windows has: the kernel and the C runtime (msvcrt, or the UCRT's api sets).
SYSTEM_DLLS = {"kernel32.dll", "msvcrt.dll"}
N, H = 2000, 1e-3   # 2 s of 1 ms steps: the platform turns through up to 0.8 rad (micro), 0.09 rad (sim)
RTOL = 1e-12
CASES = [(name, v) for name in ("micro", "sim") for v in (2, 3)]
IDS = [f"{name}-fmi{v}" for name, v in CASES]
# wine without its console noise, and without the .NET and HTML engines it would offer to
# install when it first creates its prefix (~/.wine, about 5 s once)
WINE_ENV = {**os.environ, "WINEDEBUG": "-all", "WINEDLLOVERRIDES": "mscoree,mshtml="}


def need(command: str, package: str) -> str:
    """The command's path. Without it: a skip naming the Debian package, or, in CI as root
    (where `make test` installs it), a failure."""
    path = shutil.which(command)
    if path:
        return path
    why = f"{command} not found (Debian's {package}; `make test` installs it when run as root)"
    if os.environ.get("CI") and hasattr(os, "geteuid") and os.geteuid() == 0:
        pytest.fail(f"{why}, but this is CI as root: make system-packages should have installed it")
    pytest.skip(why)


@dataclass
class Built:
    version: int
    path: Path
    unzipdir: Path
    md: object
    model: Model

    @property
    def so(self) -> Path:
        return self.unzipdir / "binaries" / FOLDERS[self.version][0] / f"{MODEL_IDENTIFIER}.so"

    @property
    def dll(self) -> Path:
        return self.unzipdir / "binaries" / FOLDERS[self.version][1] / f"{MODEL_IDENTIFIER}.dll"

    @property
    def token(self) -> str:
        return self.md.guid if self.version == 2 else self.md.instantiationToken


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[tuple[str, int], Built]:
    need(windows.MINGW_CC, windows.DEBIAN_PACKAGE)
    folder = tmp_path_factory.mktemp("windows_fmus")
    built = {}
    for name, version in CASES:
        path = export_fmu(SCENE_FILES[name], folder / f"{name}_{version}.fmu", fmi_version=version)
        unzipdir = Path(extract(str(path), str(folder / f"{name}_{version}")))
        built[(name, version)] = Built(version, path, unzipdir, read_model_description(str(path)),
                                       load_scene(SCENE_FILES[name]))
    return built


def objdump(dll: Path) -> str:
    return subprocess.run([need(OBJDUMP, "binutils-mingw-w64-x86-64"), "-p", str(dll)],
                          capture_output=True, text=True, check=True).stdout


# --- the archive and the DLL ------------------------------------------------------------------------

@pytest.mark.parametrize("version", [2, 3])
def test_fmu_carries_both_binaries_and_validates(fmus, version):
    b = fmus[("micro", version)]
    names = zipfile.ZipFile(b.path).namelist()
    linux, win = FOLDERS[version]
    assert sorted(n for n in names if n.startswith("binaries/")) == \
        [f"binaries/{linux}/{MODEL_IDENTIFIER}.so", f"binaries/{win}/{MODEL_IDENTIFIER}.dll"]
    assert validate_fmu(str(b.path)) == []
    assert "file format pei-x86-64" in subprocess.run(
        [need(OBJDUMP, "binutils-mingw-w64-x86-64"), "-f", str(b.dll)], capture_output=True, text=True,
        check=True).stdout


@pytest.mark.parametrize("version", [2, 3])
def test_dll_imports_only_windows_system_and_c_runtime(fmus, version):
    """No libgcc, no libwinpthread, no mingw runtime DLL: what every Windows has."""
    dlls = [line.split(":", 1)[1].strip() for line in objdump(fmus[("micro", version)].dll).splitlines()
            if line.strip().startswith("DLL Name:")]
    assert dlls and all(d.lower() in SYSTEM_DLLS or d.lower().startswith("api-ms-win-crt-") for d in dlls), dlls


@pytest.mark.parametrize("version", [2, 3])
def test_dll_exports_exactly_the_linux_binarys_fmi_functions(fmus, version):
    """The export table (PE: what is dllexport) is the Linux binary's dynamic symbols (ELF:
    visibility), which tests/stewart_fmu/test_native_fmu.py holds to the fmi* functions."""
    b = fmus[("micro", version)]
    dump = objdump(b.dll).splitlines()
    start = next(k for k, line in enumerate(dump) if "[Ordinal/Name Pointer] Table" in line)
    exported = []
    for line in dump[start + 1:]:
        if not line.strip().startswith("["):
            break
        exported.append(line.split("]", 1)[1].strip())
    linux = subprocess.run(["nm", "-D", "--defined-only", str(b.so)], capture_output=True, text=True,
                           check=True).stdout.split()
    linux = [s for s in linux if s.startswith("fmi")]
    assert exported and all(s.startswith(f"fmi{version}") for s in exported), exported
    assert sorted(exported) == sorted(linux)


# --- the DLL under wine against the Linux binary -------------------------------------------------------

@dataclass
class Masters:
    linux: Path
    windows: Path


@pytest.fixture(scope="module")
def masters(tmp_path_factory) -> Masters:
    """The C master built for Linux and for Windows (mingw-w64's own printf and scanf; its scanf
    misrounds a few 17-digit decimals, so the scripts carry hexadecimal floats, read exactly)."""
    mingw = need(windows.MINGW_CC, windows.DEBIAN_PACKAGE)
    folder = tmp_path_factory.mktemp("masters")
    src = str(HERE / "fmi_master.c")
    common = ["-std=c99", "-O2", "-Wall", "-I", str(FMI_INCLUDE)]
    subprocess.run(["cc", *common, "-o", str(folder / "fmi_master"), src, "-ldl"], check=True)
    subprocess.run([mingw, *common, "-D__USE_MINGW_ANSI_STDIO=1", "-o", str(folder / "fmi_master.exe"), src],
                   check=True)
    return Masters(folder / "fmi_master", folder / "fmi_master.exe")


def count(variable) -> int:
    """The values a declared variable holds: an FMI 3.0 array's elements, else 1."""
    dims = getattr(variable, "dimensions", None) or []
    return int(np.prod([int(d.start) for d in dims])) if dims else 1


def inputs(model: Model, with_tau: bool) -> np.ndarray:
    """N rows of sigma (the hold plus slow sinusoids of 30 % of the largest hold force: the pose
    turns through tenths of a radian) and, with a drive, tau (sinusoids of a tenth of that)."""
    rng = np.random.default_rng(5)
    t = np.arange(N)[:, None] * H
    hold = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))
    scale = np.abs(hold).max()
    waves = lambda amp: amp * np.sin(2 * np.pi * rng.uniform(0.5, 5, 6) * t + rng.uniform(0, 6.3, 6))  # noqa: E731
    sigma = hold + waves(0.3 * scale)
    if not with_tau:
        return sigma
    return np.hstack([sigma, waves(0.03 * scale * model.drive.pinion_radius / model.drive.gear_ratio)])


def master_rows(cmd: list[str], env=None) -> np.ndarray:
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return np.array([[float(x) for x in line.split()] for line in proc.stdout.splitlines()])


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_windows_master_under_wine_equals_linux(fmus, masters, case, tmp_path):
    """2 s of 1 ms steps, the same inputs: the DLL under wine through the Windows master, the
    .so through the Linux master. Same status at every step; every output within RTOL of its
    unit's scale (measured: mostly bit for bit, a few force parts one ulp apart; see
    test_libm_differs_by_one_ulp_at_most)."""
    wine = need("wine", "wine")
    b = fmus[case]
    declared = [v for v in b.md.modelVariables if v.causality in ("input", "output")]
    ins = [v for v in declared if v.causality == "input"]
    outs = [v for v in declared if v.causality == "output"]
    u = inputs(b.model, "tau" in {v.name.partition("[")[0] for v in ins})
    n_in, n_out = sum(map(count, ins)), sum(map(count, outs))
    lines = [f"{N} {H.hex()}",
             " ".join(map(str, [n_in, len(ins), *[v.valueReference for v in ins]])),
             " ".join(map(str, [n_out, len(outs), *[v.valueReference for v in outs]]))]
    units = [v.unit for v in outs for _ in range(count(v))]
    names = [v.name for v in outs for _ in range(count(v))]
    script = tmp_path / "script.txt"
    script.write_text("\n".join(lines + [" ".join(float(x).hex() for x in row) for row in u]) + "\n")
    version = str(b.version)
    linux = master_rows([str(masters.linux), "run", version, str(b.so), b.token, str(script)])
    win = master_rows([wine, str(masters.windows), "run", version, str(b.dll), b.token, str(script)], WINE_ENV)
    assert linux.shape == win.shape == (N, 2 + n_out)
    assert np.all(linux[:, 1] == 0) and np.all(win[:, 1] == 0)   # every step taken on both
    worst = 0.0
    for unit in set(units):
        cols = [2 + k for k, un in enumerate(units) if un == unit]
        scale = float(np.abs(linux[:, cols]).max())
        worst = max(worst, float(np.abs(win[:, cols] - linux[:, cols]).max()) / scale)
    record(f"windows dll under wine vs linux: {case[0]} fmi{case[1]}", worst, RTOL)
    assert worst <= RTOL, f"{worst:.3e} > {RTOL:.0e}"
    motion = np.ptp(linux[:, [2 + names.index(n) for n in ("thx", "thy", "thz")]], axis=0)
    assert motion.max() > 0.05   # the angles the sines and cosines see do range


def test_libm_differs_by_one_ulp_at_most(tmp_path):
    """Why the outputs above are not all bit for bit: sin, cos (one sincos call, as in the
    core's rotations.c) and pow of 20 000 arguments, glibc vs mingw-w64 under wine: at most one
    unit in the last place apart."""
    mingw = need(windows.MINGW_CC, windows.DEBIAN_PACKAGE)
    wine = need("wine", "wine")
    src = str(HERE / "libm_probe.c")
    flags = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Wpedantic"]
    subprocess.run(["cc", *flags, "-o", str(tmp_path / "probe"), src, "-lm"], check=True)
    subprocess.run([mingw, *flags, "-D__USE_MINGW_ANSI_STDIO=1", "-o", str(tmp_path / "probe.exe"), src, "-lm"],
                   check=True)
    args = ["20000", "0.5"]
    lin = subprocess.run([str(tmp_path / "probe"), *args], capture_output=True, text=True, check=True).stdout
    win = subprocess.run([wine, str(tmp_path / "probe.exe"), *args], capture_output=True, text=True, check=True,
                         env=WINE_ENV, timeout=300).stdout
    bits = lambda out: np.array([[int(x, 16) for x in line.split()] for line in out.splitlines()],  # noqa: E731
                                dtype=np.uint64)
    a, w = bits(lin), bits(win)
    assert a.shape == w.shape == (20000, 3)
    assert np.all((a >> np.uint64(63)) == (w >> np.uint64(63)))   # same signs: then the distance
    ulps = np.where(a > w, a - w, w - a)                              # of the bits is in ulps
    assert ulps.max() <= 1, ulps.max(axis=0)


def test_without_mingw_the_dll_is_left_out_with_one_line(tmp_path, monkeypatch, capsys):
    """No mingw-w64: export-fmu still writes the FMU (the host's binary, valid), and says in one
    line on stderr why it has no Windows binary."""
    from stewart_sim import cli

    monkeypatch.setattr(windows, "MINGW_CC", "no-such-mingw-gcc")
    out = tmp_path / "plant.fmu"
    assert cli.main(["export-fmu", str(SCENE_FILES["micro"]), "-o", str(out), "--fmi-version", "3"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [windows.missing_note()] and "no-such-mingw-gcc not found" in err[0]
    names = zipfile.ZipFile(out).namelist()
    assert [n for n in names if n.startswith("binaries/")] == [f"binaries/x86_64-linux/{MODEL_IDENTIFIER}.so"]
    assert validate_fmu(str(out)) == []
