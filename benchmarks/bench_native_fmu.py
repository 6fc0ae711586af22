"""Speed of the native FMUs: one co-simulation step (set 6 inputs + doStep + get 6 outputs).

Both FMUs of the micro-manipulator, FMI 2.0 and 3.0: the plant (rk4, 1 ms step, one internal
step with the power-balance check; inputs sigma, outputs the leg lengths l; FMI 3.0: the
arrays) and the controller (`export-fmu --controller`: one 1 kHz sample; inputs the measured
l, outputs tau; scalars), each against a trivial FMU of the same shape (6 inputs, 6 outputs,
x += h u; scalars or arrays as ours) that this script writes and compiles itself. Each is timed through fmpy (FMU2Slave /
FMU3Slave, the calls a Python master makes) and through a C master
(tests/stewart_fmu/fmi_master.c, dlopen), where the call costs next to nothing: the C column
of the trivial FMU is the FMI call floor, that of ours its step, and fmpy's per-step overhead
is fmpy's trivial time less the C one, the same for any FMU of this shape. So the fmpy ratio
is (fmpy overhead + our step) / (fmpy overhead + trivial step). Times are the thread's CPU
time (a machine shared with other jobs preempts the loop), best of several rounds, each round
timing every FMU in turn (a burst of load hits all alike); ratios within one run.
Run: .venv/bin/python benchmarks/bench_native_fmu.py [--steps N] [--repeats R]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

from dataclasses import dataclass, replace

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from controller.config import controller_config
from controller.fmu import export_controller
from stewart_fmu import inverse_dynamics, inverse_kinematics, load_scene
from stewart_fmu.fmu.export import FMI_VERSIONS, export_fmu

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
/* u and y also as arrays of six, ua (13) and ya (14), as the plant's FMI 3.0 sigma and l */
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[], size_t m) {
    M *x = c; size_t k, j = 0;
    for (k = 0; k < n; k++) {
        if (vr[k] == 13 && j + 6 <= m) { memcpy(x->u, v + j, sizeof x->u); j += 6; }
        else if (vr[k] >= 1 && vr[k] <= 6 && j < m) x->u[vr[k] - 1] = v[j++];
        else return fmi3Error;
    }
    return j == m ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t m) {
    M *x = c; size_t k, j = 0;
    for (k = 0; k < n; k++) {
        if (vr[k] == 14 && j + 6 <= m) { memcpy(v + j, x->x, sizeof x->x); j += 6; }
        else if (vr[k] >= 7 && vr[k] <= 12 && j < m) v[j++] = x->x[vr[k] - 7];
        else return fmi3Error;
    }
    return j == m ? fmi3OK : fmi3Error; }
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean a, fmi3Boolean *b, fmi3Boolean *d,
    fmi3Boolean *e, fmi3Float64 *f) { (void)t,(void)a; *b = *d = *e = 0; *f = ((M *)c)->t + h; return step(c, h); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean a, fmi3Float64 b, fmi3Float64 d, fmi3Boolean e,
    fmi3Float64 f) { (void)c,(void)a,(void)b,(void)d,(void)e,(void)f; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { (void)c; return fmi3OK; }
#endif
"""


def build_trivial(folder: Path, version: int) -> Path:
    """A 6-in 6-out FMU (u[1..6] -> y[1..6], x += h u; FMI 3.0: also the arrays ua -> ya) compiled
    here; its path."""
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
        zeros = " ".join(["0"] * 6)
        var += [f'<Float64 name="ua" valueReference="13" causality="input" variability="continuous" start="{zeros}">'
                '<Dimension start="6"/></Float64>',
                f'<Float64 name="ya" valueReference="14" causality="output" variability="continuous" initial="exact" '
                f'start="{zeros}"><Dimension start="6"/></Float64>']
        outs = "".join(f'<Output valueReference="{i}"/>' for i in (*range(7, 13), 14))
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


@dataclass
class Case:
    """One FMU under test: its file and the 6 inputs and outputs a step sets and gets."""
    fmu: Path
    version: int
    inputs: list[str]   # variable names (an FMI 3.0 array: its one name)
    outputs: list[str]
    values: np.ndarray  # (steps, 6) inputs per step


def _slave(case: Case, unzip: str):
    md = read_model_description(unzip)
    if case.version == 2:
        f = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        return f, f.setReal, f.getReal
    f = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier)
    f.instantiate()
    f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    return f, f.setFloat64, lambda vrs: f.getFloat64(vrs, 6)   # 6 values: 6 scalars or an array


def fmpy_step_time(case: Case, unzip: str) -> float:
    """Time per step of setReal(6) + doStep + getReal(6) through fmpy's FMU2Slave / FMU3Slave,
    one fresh instance."""
    md = read_model_description(unzip)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    vin, vout = [vr[n] for n in case.inputs], [vr[n] for n in case.outputs]
    f, set_, get = _slave(case, unzip)
    rows, step = case.values.tolist(), f.doStep
    t0 = time.thread_time()   # CPU time, as the C master's: preemption by other jobs is not counted
    for k in range(len(rows)):
        set_(vin, rows[k])
        step(k * H, H)
        get(vout)
    elapsed = (time.thread_time() - t0) / len(rows)
    f.terminate()
    f.freeInstance()
    return elapsed


def c_step_time(master: Path, case: Case, unzip: str, folder: Path, repeats: int) -> float:
    """Best time per step of the same loop in the C master (fmi_master bench)."""
    md = read_model_description(unzip)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    vin, vout = [vr[n] for n in case.inputs], [vr[n] for n in case.outputs]
    binary = next(Path(unzip).glob(f"binaries/*/{md.coSimulation.modelIdentifier}.so"))
    token = md.guid if case.version == 2 else md.instantiationToken
    script = folder / "script.txt"
    lines = [f"{len(case.values)} {H!r}", " ".join(map(str, [6, len(vin), *vin])),
             " ".join(map(str, [6, len(vout), *vout]))]
    lines += [" ".join(repr(x) for x in row) for row in case.values.tolist()]
    script.write_text("\n".join(lines) + "\n")
    out = subprocess.run([str(master), "bench", str(case.version), str(binary), token, str(script), str(repeats)],
                         capture_output=True, text=True, check=True).stdout
    return min(float(line.split()[0]) for line in out.splitlines()) * 1e-6


def cases(folder: Path, steps: int) -> list[tuple[str, Case, Case]]:
    """(label, ours, trivial) for the plant and the controller FMU, FMI 2.0 and 3.0."""
    model = load_scene(SCENE)
    config = controller_config(model)
    t = np.arange(steps)[:, None] * H
    wave = np.sin(2 * np.pi * 10 * t + np.arange(6))
    hold = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))
    sigma = hold + 0.01 * np.abs(hold).max() * wave        # near the force holding home
    lengths = inverse_kinematics(model, model.home, with_cond=False).lengths + 1e-4 * wave   # 0.1 mm about home
    six = [f"[{i}]" for i in range(1, 7)]
    out = []
    for version in FMI_VERSIONS:
        trivial = Case(build_trivial(folder, version), version, [f"u{i}" for i in six], [f"y{i}" for i in six],
                       sigma)
        plant = export_fmu(SCENE, folder / f"plant{version}.fmu", fmi_version=version)
        names = (([f"sigma{i}" for i in six], [f"l{i}" for i in six]) if version == 2
                 else (["sigma"], ["l"]))   # FMI 3.0: the arrays
        same = trivial if version == 2 else replace(trivial, inputs=["ua"], outputs=["ya"])   # arrays for arrays
        out.append((f"plant {version}.0", Case(plant, version, *names, sigma), same))
        ctl = export_controller(model, config, folder / f"controller{version}.fmu", version)
        out.append((f"controller {version}.0", Case(ctl, version, [f"l{i}" for i in six], [f"tau{i}" for i in six],
                                                    lengths), replace(trivial, values=lengths)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    if not 1 <= args.steps <= 100_000 or not 1 <= args.repeats <= 100:
        ap.error("--steps must be in 1..100000 and --repeats in 1..100")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        master = folder / "fmi_master"
        subprocess.run(["cc", "-std=c99", "-O2", "-I", str(FMI), "-o", str(master), str(MASTER), "-ldl"], check=True)
        runs = cases(folder, args.steps)
        unzip = {c.fmu: extract(str(c.fmu)) for _, ours, trivial in runs for c in (ours, trivial)}
        best: dict[tuple[str, int, str], float] = {}
        for _ in range(args.repeats):   # every case in each round: a burst of load hits all alike
            for label, ours, trivial in runs:
                for k, case in enumerate((ours, trivial)):
                    for how, t in (("C", c_step_time(master, case, unzip[case.fmu], folder, 1)),
                                   ("fmpy", fmpy_step_time(case, unzip[case.fmu]))):
                        best[label, k, how] = min(best.get((label, k, how), float("inf")), t)
    print(f"one step = set 6 inputs + doStep(1 ms) + get 6 outputs, in us; best of {args.repeats} rounds of "
          f"{args.steps} steps")
    print(f"{'FMU, FMI':>15} | {'C: ours':>7} | {'trivial':>7} | {'fmpy: ours':>10} | {'trivial':>7} | {'ratio':>5} | "
          f"{'fmpy overhead':>13} | {'predicted':>9} | {'ours for 1.3x':>13}")
    for label, _, _ in runs:
        c_ours, c_triv, py_ours, py_triv = (best[label, k, how] for how in ("C", "fmpy") for k in (0, 1))
        overhead = py_triv - c_triv   # fmpy's own cost per step, the same for any FMU of this shape
        print(f"{label:>15} | {c_ours * 1e6:7.3f} | {c_triv * 1e6:7.3f} | {py_ours * 1e6:10.2f} | {py_triv * 1e6:7.2f} | "
              f"{py_ours / py_triv:5.2f} | {overhead * 1e6:13.2f} | {(overhead + c_ours) / py_triv:9.2f} | "
              f"{(0.3 * py_triv + c_triv) * 1e6:13.2f}")
    print("fmpy overhead: fmpy trivial - C trivial. predicted: (fmpy overhead + C ours) / fmpy trivial, the ratio "
          "if fmpy's cost is the same for both FMUs. ours for 1.3x: the C step of ours that would give 1.3x through "
          "fmpy (0.3 fmpy trivial + C trivial).")

if __name__ == "__main__":
    main()
