"""Speed of the native FMU: one co-simulation step (set 6 inputs + doStep + get 6 outputs).

Through fmpy (FMU2Slave / FMU3Slave, the calls a Python master makes), our FMU of the
micro-manipulator (rk4, 1 ms step, one internal step with the power-balance check) against a
trivial FMU of the same shape (6 inputs, 6 outputs, x += h u) that this script writes and
compiles itself; and the same loop in C (tests/stewart_fmu/fmi_master.c, dlopen), where the
FMI call overhead is negligible and the time is the plant's. Best of several repeats.
Run: .venv/bin/python benchmarks/bench_native_fmu.py [--steps N]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.fmu.export import export_fmu

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
FMI = ROOT / "stewart_fmu" / "native" / "fmi"
MASTER = ROOT / "tests" / "stewart_fmu" / "fmi_master.c"
H = 1e-3

# A trivial FMU, 6 in and 6 out, with every function of the FMI 2.0 / 3.0 API (our headers).
TRIVIAL_C = r"""
#include <stdlib.h>
#include <string.h>
#if FMI == 2
#include "fmi2_api.h"
#define ST fmi2Status
#else
#include "fmi3_api.h"
#define ST fmi3Status
#endif
typedef struct { double t, x[6], u[6]; } M;
static ST setv(M *m, const unsigned *vr, size_t n, const double *v) {
    size_t k; for (k = 0; k < n; k++) { if (vr[k] < 1 || vr[k] > 6) return (ST)3; m->u[vr[k] - 1] = v[k]; } return (ST)0; }
static ST getv(M *m, const unsigned *vr, size_t n, double *v) {
    size_t k; for (k = 0; k < n; k++) { if (vr[k] < 7 || vr[k] > 12) return (ST)3; v[k] = m->x[vr[k] - 7]; } return (ST)0; }
static ST step(M *m, double h) { int i; for (i = 0; i < 6; i++) m->x[i] += h * m->u[i]; m->t += h; return (ST)0; }
#if FMI == 2
const char *fmi2GetTypesPlatform(void) { return "default"; }
const char *fmi2GetVersion(void) { return "2.0"; }
fmi2Component fmi2Instantiate(fmi2String a, fmi2Type b, fmi2String c, fmi2String d, const fmi2CallbackFunctions *e,
                              fmi2Boolean f, fmi2Boolean g) { (void)a,(void)b,(void)c,(void)d,(void)e,(void)f,(void)g; return calloc(1, sizeof(M)); }
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) { return setv(c, vr, n, v); }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) { return getv(c, vr, n, v); }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean b) { (void)t, (void)b; return step(c, h); }
#define OKF(NAME, ...) fmi2Status NAME(__VA_ARGS__) { return fmi2OK; }
OKF(fmi2SetDebugLogging, fmi2Component c, fmi2Boolean l, size_t n, const fmi2String s[])
OKF(fmi2SetupExperiment, fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real d, fmi2Boolean e, fmi2Real f)
OKF(fmi2EnterInitializationMode, fmi2Component c)
OKF(fmi2ExitInitializationMode, fmi2Component c)
OKF(fmi2Terminate, fmi2Component c)
OKF(fmi2Reset, fmi2Component c)
OKF(fmi2GetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
OKF(fmi2GetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
OKF(fmi2GetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
OKF(fmi2SetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
OKF(fmi2SetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
OKF(fmi2SetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
OKF(fmi2GetFMUstate, fmi2Component c, fmi2FMUstate *s)
OKF(fmi2SetFMUstate, fmi2Component c, fmi2FMUstate s)
OKF(fmi2FreeFMUstate, fmi2Component c, fmi2FMUstate *s)
OKF(fmi2SerializedFMUstateSize, fmi2Component c, fmi2FMUstate s, size_t *n)
OKF(fmi2SerializeFMUstate, fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
OKF(fmi2DeSerializeFMUstate, fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
OKF(fmi2GetDirectionalDerivative, fmi2Component c, const fmi2ValueReference a[], size_t b, const fmi2ValueReference d[], size_t e, const fmi2Real f[], fmi2Real g[])
OKF(fmi2SetRealInputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[])
OKF(fmi2GetRealOutputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[])
OKF(fmi2CancelStep, fmi2Component c)
OKF(fmi2GetStatus, fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
OKF(fmi2GetRealStatus, fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
OKF(fmi2GetIntegerStatus, fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
OKF(fmi2GetBooleanStatus, fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
OKF(fmi2GetStringStatus, fmi2Component c, const fmi2StatusKind s, fmi2String *v)
#else
const char *fmi3GetVersion(void) { return "3.0"; }
fmi3Instance fmi3InstantiateCoSimulation(fmi3String a, fmi3String b, fmi3String c, fmi3Boolean d, fmi3Boolean e,
    fmi3Boolean f, fmi3Boolean g, const fmi3ValueReference h[], size_t i, fmi3InstanceEnvironment j,
    fmi3LogMessageCallback k, fmi3IntermediateUpdateCallback l) {
    (void)a,(void)b,(void)c,(void)d,(void)e,(void)f,(void)g,(void)h,(void)i,(void)j,(void)k,(void)l; return calloc(1, sizeof(M)); }
void fmi3FreeInstance(fmi3Instance c) { free(c); }
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t m) { (void)m; return setv(c, vr, n, v); }
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t m) { (void)m; return getv(c, vr, n, v); }
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean a, fmi3Boolean *b, fmi3Boolean *d,
    fmi3Boolean *e, fmi3Float64 *f) { (void)t,(void)a; *b = *d = *e = 0; *f = ((M *)c)->t + h; return step(c, h); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean a, fmi3Float64 b, fmi3Float64 d, fmi3Boolean e,
    fmi3Float64 f) { (void)c,(void)a,(void)b,(void)d,(void)e,(void)f; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { (void)c; return fmi3OK; }
#endif
"""


def build_trivial(folder: Path, version: int) -> Path:
    """A 6-in 6-out FMU (u[1..6] -> y[1..6], x += h u) compiled here; its path."""
    root = folder / f"trivial{version}"
    plat = "linux64" if version == 2 else "x86_64-linux"
    (root / "binaries" / plat).mkdir(parents=True)
    src = folder / f"trivial{version}.c"
    src.write_text(TRIVIAL_C)
    # Every other function of the API (fmpy looks them all up): a stub returning Error, in a
    # unit of its own (no prototypes there, the loader only needs the symbol).
    header = (FMI / f"fmi{version}_api.h").read_text()
    names = set(re.findall(rf"\b(fmi{version}\w+)\(", header))
    names |= {f"fmi3{a}{t}" for a in ("Get", "Set") for t in re.findall(r"FMI3_GETSET\(\w+, (\w+)\)", header)}
    defined = set(re.findall(rf"\b(fmi{version}\w+)\b", _section(TRIVIAL_C, version)))
    stubs = folder / f"stubs{version}.c"
    stubs.write_text("".join(f"int {n}(void) {{ return 3; }}\n" for n in sorted(names - defined)))
    subprocess.run(["cc", "-std=c99", "-O2", "-fPIC", "-shared", f"-DFMI={version}", "-w", "-I", str(FMI),
                    "-o", str(root / "binaries" / plat / "Trivial.so"), str(src), str(stubs)], check=True)
    var = []
    for i in range(1, 13):
        name, caus = (f"u[{i}]", "input") if i <= 6 else (f"y[{i - 6}]", "output")
        init = ' initial="exact"' if caus == "output" else ""
        if version == 2:
            var.append(f'<ScalarVariable name="{name}" valueReference="{i}" causality="{caus}" variability="continuous"'
                       f'{init}><Real start="0"/></ScalarVariable>')
        else:
            var.append(f'<Float64 name="{name}" valueReference="{i}" causality="{caus}" variability="continuous"'
                       f'{init} start="0"/>')
    if version == 2:
        outs = "".join(f'<Unknown index="{i}"/>' for i in range(7, 13))
        md = ('<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="2.0" modelName="trivial" '
              'guid="{trivial}" variableNamingConvention="structured"><CoSimulation modelIdentifier="Trivial"/>'
              f'<ModelVariables>{"".join(var)}</ModelVariables><ModelStructure><Outputs>{outs}</Outputs>'
              '</ModelStructure></fmiModelDescription>')
    else:
        outs = "".join(f'<Output valueReference="{i}"/>' for i in range(7, 13))
        md = ('<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="3.0" modelName="trivial" '
              'instantiationToken="{trivial}" variableNamingConvention="structured"><CoSimulation '
              'modelIdentifier="Trivial"/><ModelVariables><Float64 name="time" valueReference="0" '
              f'causality="independent" variability="continuous"/>{"".join(var)}</ModelVariables><ModelStructure>'
              f'{outs}</ModelStructure></fmiModelDescription>')
    (root / "modelDescription.xml").write_text(md)
    fmu = folder / f"trivial{version}.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        for p in sorted(root.rglob("*")):
            if p.is_file():
                z.write(p, p.relative_to(root).as_posix())
    return fmu


def _section(text: str, version: int) -> str:
    """The part of TRIVIAL_C compiled for this FMI version."""
    two, three = text.split("#if FMI == 2", 1)[1].rsplit("#else", 1)
    return two if version == 2 else three


def fmpy_step_time(fmu: Path, version: int, inputs: list[str], outputs: list[str], values: np.ndarray,
                   steps: int, repeats: int) -> float:
    """Best time per step of setReal(6) + doStep + getReal(6) through fmpy's FMU2Slave / FMU3Slave."""
    unzip = extract(str(fmu))
    md = read_model_description(unzip)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    vin, vout = [vr[n] for n in inputs], [vr[n] for n in outputs]
    best = float("inf")
    for _ in range(repeats):
        if version == 2:
            from fmpy.fmi2 import FMU2Slave
            f = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
            f.instantiate()
            f.setupExperiment(startTime=0.0)
            f.enterInitializationMode()
            f.exitInitializationMode()
            set_, get = f.setReal, f.getReal
        else:
            from fmpy.fmi3 import FMU3Slave
            f = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzip,
                          modelIdentifier=md.coSimulation.modelIdentifier)
            f.instantiate()
            f.enterInitializationMode(startTime=0.0)
            f.exitInitializationMode()
            set_, get = f.setFloat64, lambda vrs: f.getFloat64(vrs, 6)   # 6 values: 6 scalars or an array
        rows = values.tolist()
        step = f.doStep
        t0 = time.perf_counter()
        for k in range(steps):
            set_(vin, rows[k])
            step(k * H, H)
            get(vout)
        best = min(best, (time.perf_counter() - t0) / steps)
        f.terminate()
        f.freeInstance()
    return best


def c_step_time(master: Path, binary: Path, token: str, version: int, vin, vout, values, steps: int,
                folder: Path) -> float:
    script = folder / "script.txt"
    lines = [f"{steps} {H!r}", " ".join(map(str, [6, len(vin), *vin])), " ".join(map(str, [6, len(vout), *vout]))]
    lines += [" ".join(repr(x) for x in row) for row in values.tolist()]
    script.write_text("\n".join(lines) + "\n")
    out = subprocess.run([str(master), "bench", str(version), str(binary), token, str(script), "5"],
                         capture_output=True, text=True, check=True).stdout
    return min(float(line.split()[0]) for line in out.splitlines()) * 1e-6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    model = load_scene(SCENE)
    hold = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))
    t = np.arange(args.steps)[:, None] * H
    sigma = hold + 0.01 * np.abs(hold).max() * np.sin(2 * np.pi * 10 * t + np.arange(6))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        master = folder / "fmi_master"
        subprocess.run(["cc", "-std=c99", "-O2", "-I", str(FMI), "-o", str(master), str(MASTER), "-ldl"], check=True)
        rows = []
        for version in (2, 3):
            ours = export_fmu(SCENE, folder / f"micro{version}.fmu", fmi_version=version)
            trivial = build_trivial(folder, version)
            ins, outs = (([f"sigma[{i}]" for i in range(1, 7)], [f"l[{i}]" for i in range(1, 7)]) if version == 2
                         else (["sigma"], ["l"]))   # FMI 3.0: the arrays
            tins, touts = [f"u[{i}]" for i in range(1, 7)], [f"y[{i}]" for i in range(1, 7)]
            ours_t = triv_t = float("inf")
            for _ in range(args.repeats):   # alternated: a burst of load hits both alike
                ours_t = min(ours_t, fmpy_step_time(ours, version, ins, outs, sigma, args.steps, 1))
                triv_t = min(triv_t, fmpy_step_time(trivial, version, tins, touts, sigma, args.steps, 1))
            md = read_model_description(str(ours))
            unzip = Path(extract(str(ours)))
            binary = next(unzip.glob("binaries/*/StewartPlant.so"))
            vr = {v.name: v.valueReference for v in md.modelVariables}
            token = md.guid if version == 2 else md.instantiationToken
            c_ours = c_step_time(master, binary, token, version, [vr[n] for n in ins], [vr[n] for n in outs],
                                 sigma, args.steps, folder)
            tunzip = Path(extract(str(trivial)))
            c_triv = c_step_time(master, next(tunzip.glob("binaries/*/Trivial.so")), "{trivial}", version,
                                 list(range(1, 7)), list(range(7, 13)), sigma, args.steps, folder)
            rows.append((version, ours_t, triv_t, c_ours, c_triv))
    print(f"one step = set 6 inputs + doStep(1 ms) + get 6 outputs; best of {args.repeats} x {args.steps} steps")
    print(f"{'FMI':>4} | {'fmpy: ours':>11} | {'fmpy: trivial':>13} | {'ratio':>5} | {'C: ours':>9} | {'C: trivial':>10}")
    for version, a, b, c, d in rows:
        print(f"{version:>4} | {a * 1e6:8.2f} us | {b * 1e6:10.2f} us | {a / b:5.2f} | {c * 1e6:6.2f} us | "
              f"{d * 1e6:7.3f} us")


if __name__ == "__main__":
    main()
