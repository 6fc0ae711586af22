"""The controller FMU's Windows DLL: built by the plant's build (stewart_fmu.fmu.export's
build_binaries, stewart_fmu/fmu/windows.py) beside the Linux binary, it imports only Windows
system and C runtime DLLs, exports exactly the Linux binary's FMI functions, and under wine (the
Windows build of tests/stewart_fmu/fmi_master.c) gives the Linux binary's outputs on the same
inputs bit for bit: the controller's arithmetic is + - * / and clamps (unlike the plant's, no
sin, cos or pow, where mingw-w64's and glibc's differ by an ulp at times); its one libm call, exp
for the motor current's decay over a period (controller/native/fmi/model.c, loop_of), is made
once at exitInitializationMode and gives the same double on both for the micro scene (a
difference there would show in every current and torque). The script gives the master its
numbers in hexadecimal: mingw-w64's scanf rounds a few 17-digit decimals to the neighbouring
double (measured: 3 of 60 000 of these inputs), which the outputs would then carry.

The tools and their checks are tests/stewart_fmu/test_windows_fmu.py's (its `masters` fixture
is taken from there): without them these tests are skipped, saying why.
"""
from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu

from controller.config import controller_config
from controller.fmu import MODEL_IDENTIFIER, export_controller
from stewart_fmu import load_scene
from stewart_fmu.fmu import windows
from tests.helpers import SCENE_FILES
from tests.stewart_fmu.test_windows_fmu import (FOLDERS, OBJDUMP, SYSTEM_DLLS, WINE_ENV,
                                                master_rows, need)
from tests.stewart_fmu.test_windows_fmu import masters  # noqa: F401 (a fixture: the C masters)

N = 2000   # controller periods of inputs (2 s at the micro scene's 1 kHz)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[int, tuple[Path, Path, object]]:
    """The micro scene's controller FMUs (FMI 2.0 and 3.0): (FMU, unzipped, model description)."""
    need(windows.MINGW_CC, windows.DEBIAN_PACKAGE)
    folder = tmp_path_factory.mktemp("controller_windows")
    model = load_scene(SCENE_FILES["micro"])
    config = controller_config(model)
    out = {}
    for version in (2, 3):
        path = export_controller(model, config, folder / f"controller{version}.fmu", version)
        unzipdir = Path(extract(str(path), str(folder / f"controller{version}")))
        out[version] = (path, unzipdir, read_model_description(str(path)))
    return out


def _binary(unzipdir: Path, version: int, windows_dll: bool) -> Path:
    folder = FOLDERS[version][1 if windows_dll else 0]
    return unzipdir / "binaries" / folder / f"{MODEL_IDENTIFIER}{'.dll' if windows_dll else '.so'}"


def _objdump(dll: Path) -> list[str]:
    return subprocess.run([need(OBJDUMP, "binutils-mingw-w64-x86-64"), "-p", str(dll)],
                          capture_output=True, text=True, check=True).stdout.splitlines()


@pytest.mark.parametrize("version", [2, 3])
def test_controller_fmu_carries_both_binaries(fmus, version):
    """Both binaries in the archive, nothing else under binaries/; fmpy validates the FMU; the
    DLL imports only what every Windows has and exports exactly the .so's fmi* functions."""
    path, unzipdir, _ = fmus[version]
    linux, win = FOLDERS[version]
    assert sorted(n for n in zipfile.ZipFile(path).namelist() if n.startswith("binaries/")) == \
        [f"binaries/{linux}/{MODEL_IDENTIFIER}.so", f"binaries/{win}/{MODEL_IDENTIFIER}.dll"]
    assert validate_fmu(str(path)) == []
    dump = _objdump(_binary(unzipdir, version, True))
    dlls = [ln.split(":", 1)[1].strip() for ln in dump if ln.strip().startswith("DLL Name:")]
    assert dlls and all(d.lower() in SYSTEM_DLLS or d.lower().startswith("api-ms-win-crt-")
                        for d in dlls), dlls
    start = next(k for k, ln in enumerate(dump) if "[Ordinal/Name Pointer] Table" in ln)
    exported = []
    for ln in dump[start + 1:]:
        if not ln.strip().startswith("["):
            break
        exported.append(ln.split("]", 1)[1].strip())
    so = subprocess.run(["nm", "-D", "--defined-only", str(_binary(unzipdir, version, False))],
                        capture_output=True, text=True, check=True).stdout.split()
    assert exported and sorted(exported) == sorted(s for s in so if s.startswith("fmi"))


def _inputs(md, rate: float) -> tuple[list, np.ndarray]:
    """The inputs in value-reference order and N rows of them: references about the home's leg
    lengths moving by up to 5 mm, measurements off them by up to 0.2 mm (the PIDs saturate at
    times), feedforward voltages of a few volts."""
    ins = [v for v in md.modelVariables if v.causality == "input"]
    rng = np.random.default_rng(3)
    t = np.arange(N)[:, None] / rate
    wave = lambda amp: amp * np.sin(2 * np.pi * rng.uniform(0.5, 5, 6) * t + rng.uniform(0, 6.3, 6))  # noqa: E731
    starts = {v.name: float(v.start) for v in ins}
    home = np.array([starts[f"l_ref[{i}]"] for i in range(1, 7)])
    l_ref = home + wave(5e-3)
    ldot_ref = np.gradient(l_ref, axis=0) * rate
    groups = {"l_ref": l_ref, "ldot_ref": ldot_ref, "v_ff": wave(3.0), "l": l_ref + wave(2e-4),
              "ldot": ldot_ref + wave(0.05)}
    rows = np.column_stack([groups[v.name.partition("[")[0]][:, int(v.name[-2]) - 1] for v in ins])
    return ins, rows


@pytest.mark.parametrize("version", [2, 3])
def test_windows_master_under_wine_equals_linux(fmus, masters, version, tmp_path):
    """N controller periods, the same inputs: the DLL under wine through the Windows master, the
    .so through the Linux master; every step taken on both, every output bit for bit; the
    voltages saturate at times (the limits are exercised)."""
    wine = need("wine", "wine")
    path, unzipdir, md = fmus[version]
    rate = next(float(v.start) for v in md.modelVariables if v.name == "rate")
    ins, rows = _inputs(md, rate)
    outs = [v for v in md.modelVariables if v.causality == "output"]
    lines = [f"{N} {(1.0 / rate).hex()}",
             " ".join(map(str, [len(ins), len(ins), *[v.valueReference for v in ins]])),
             " ".join(map(str, [len(outs), len(outs), *[v.valueReference for v in outs]]))]
    script = tmp_path / "script.txt"
    script.write_text("\n".join(lines + [" ".join(float(x).hex() for x in row) for row in rows]) + "\n")
    token = md.guid if version == 2 else md.instantiationToken
    linux = master_rows([str(masters.linux), "run", str(version), str(_binary(unzipdir, version, False)),
                         token, str(script)])
    win = master_rows([wine, str(masters.windows), "run", str(version), str(_binary(unzipdir, version, True)),
                       token, str(script)], WINE_ENV)
    assert linux.shape == win.shape == (N, 2 + len(outs))
    assert np.all(linux[:, 1] == 0) and np.all(win[:, 1] == 0)
    diff = float(np.max(np.abs(win - linux)))
    print(f"controller FMI {version}.0, DLL under wine vs .so: max |d| = {diff:.3g} over {N} steps")
    assert np.array_equal(win, linux)
    saturated = [2 + k for k, v in enumerate(outs) if v.name.startswith("saturated")]
    share = float(np.mean(linux[:, saturated]))
    print(f"saturated: {share:.2f} of the samples")
    assert 0.05 < share < 0.95

