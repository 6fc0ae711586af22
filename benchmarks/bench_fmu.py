"""Cost of one 1 ms co-simulation step of the full micro-manipulator, in-process and as an FMU.

(a) the in-process Plant (stewart_fmu.plant): do_step alone, with 'rk4' (the default) and
    'dopri5'; and set_force + do_step + the six leg lengths, the same work an importer asks for;
(b) the exported FMU through fmpy's FMU2Slave: setReal of the six sigma inputs, doStep,
    getReal of the six leg lengths, with 'rk4' and 'dopri5' (solver.method), and where that
    time goes (setReal / doStep / getReal, timed inside the loop);
(c) the importer's floor: the same set + step + get through FMU2Slave on a trivial pythonfmu FMU
    built here (one input, one output, do_step returns True), and on one with six of each.

Every figure is the best of several repeats of a loop of steps (gc off inside the loops); each
loop starts again from the initialized state, so the open-loop plant (held at its static forces)
never drifts out of its stroke. Real-time factor = 1 ms / cost per step. Targets: in-process
with the default integrator >= 200x real time; (b) <= 1.3x (c).
Run: .venv/bin/python benchmarks/bench_fmu.py [--steps N] [--repeats R]
"""
from __future__ import annotations

import argparse
import gc
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

from stewart_fmu import inverse_dynamics, load_scene
from stewart_fmu.fmu.export import export_fmu
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.plant import Plant

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"
H = 1e-3
TRIVIAL = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class {name}(Fmi2Slave):
    """The importer's floor: {n} input(s), {n} output(s), a step that does nothing."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for i in range({n}):
            setattr(self, f"u{{i}}", 0.0)
            setattr(self, f"y{{i}}", 0.0)
            self.register_variable(Real(f"u{{i}}", causality=Fmi2Causality.input))
            self.register_variable(Real(f"y{{i}}", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        return True
'''


def best(loop, repeats: int, steps: int) -> float:
    """Best seconds per step of loop(steps) over repeats (after a warm-up), gc off."""
    loop(min(steps, 50))
    times = []
    for _ in range(repeats):
        gc.disable()
        try:
            t0 = time.perf_counter()
            loop(steps)
            times.append(time.perf_counter() - t0)
        finally:
            gc.enable()
    return min(times) / steps


def in_process(model, method: str, hold, repeats: int, steps: int, with_io: bool) -> float:
    plant = Plant(model, IntegratorOptions(method=method))
    plant.setup_experiment(0.0)
    plant.enter_initialization_mode()
    plant.exit_initialization_mode()
    plant.set_force(hold)
    start = plant.get_state()

    def loop(n: int) -> None:
        plant.set_state(start)
        t = 0.0
        if with_io:
            for _ in range(n):
                plant.set_force(hold)
                plant.do_step(t, H)
                plant.outputs.lengths
                t += H
        else:
            for _ in range(n):
                plant.do_step(t, H)
                t += H

    return best(loop, repeats, steps)


class Importer:
    """An FMU through fmpy.fmi2.FMU2Slave, initialized, with a loop of set + step + get."""

    def __init__(self, path: Path, inputs: list[str], outputs: list[str],
                 strings: dict[str, str] | None = None):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        md = read_model_description(str(path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName="b")
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in (strings or {}).items():
            self.fmu.setString([vr[name]], [value])
        self.fmu.exitInitializationMode()
        self.inputs = [vr[n] for n in inputs]
        self.outputs = [vr[n] for n in outputs]
        self.start = self.fmu.getFMUstate()

    def loop(self, values, parts: dict | None = None):
        fmu, vin, vout = self.fmu, self.inputs, self.outputs
        values = list(values)

        def run(n: int) -> None:
            fmu.setFMUstate(self.start)
            t = 0.0
            if parts is None:
                for _ in range(n):
                    fmu.setReal(vin, values)
                    fmu.doStep(t, H)
                    fmu.getReal(vout)
                    t += H
                return
            clock = time.perf_counter
            s = d = g = 0.0
            for _ in range(n):
                t0 = clock()
                fmu.setReal(vin, values)
                t1 = clock()
                fmu.doStep(t, H)
                t2 = clock()
                fmu.getReal(vout)
                t3 = clock()
                s, d, g = s + t1 - t0, d + t2 - t1, g + t3 - t2
                t += H
            parts.update(setReal=s / n, doStep=d / n, getReal=g / n)

        return run

    def close(self) -> None:
        self.fmu.freeFMUstate(self.start)
        self.fmu.terminate()
        self.fmu.freeInstance()


def build_trivial(folder: Path, n: int) -> Path:
    from pythonfmu import FmuBuilder

    name = f"Trivial{n}"
    src = folder / f"src{n}"
    src.mkdir()
    script = src / f"trivial{n}.py"
    script.write_text(textwrap.dedent(TRIVIAL.format(name=name, n=n)))
    return Path(FmuBuilder.build_FMU(script, dest=folder, needsExecutionTool="true",
                                     canHandleVariableCommunicationStepSize="true",
                                     canGetAndSetFMUstate="true"))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000, help="steps per timed loop")
    ap.add_argument("--repeats", type=int, default=5, help="timed loops; the best counts")
    args = ap.parse_args(argv)
    model = load_scene(SCENE)
    hold = inverse_dynamics(model, model.home, np.zeros(6), np.zeros(6))
    sigma = [f"sigma[{i}]" for i in range(1, 7)]
    lengths = [f"l[{i}]" for i in range(1, 7)]
    rows: list[tuple[str, float]] = []
    r, n = args.repeats, args.steps
    for method in ("rk4", "dopri5"):
        rows.append((f"(a) Plant.do_step, {method}", in_process(model, method, hold, r, n, False)))
    rows.append(("(a) Plant set_force + do_step + lengths, rk4",
                 in_process(model, "rk4", hold, r, n, True)))
    parts: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="bench_fmu_") as tmp:
        tmp = Path(tmp)
        plant_fmu = export_fmu(SCENE, tmp / "micro.fmu")
        for method in ("rk4", "dopri5"):
            imp = Importer(plant_fmu, sigma, lengths, {"solver.method": method})
            rows.append((f"(b) FMU2Slave setReal 6 + doStep + getReal 6, {method}",
                         best(imp.loop(hold), r, n)))
            if method == "rk4":
                best(imp.loop(hold, parts), r, n)
            imp.close()
        for k in (1, 6):
            imp = Importer(build_trivial(tmp, k), [f"u{i}" for i in range(k)],
                           [f"y{i}" for i in range(k)])
            rows.append((f"(c) trivial pythonfmu FMU, setReal {k} + doStep + getReal {k}",
                         best(imp.loop([1.0] * k), r, n)))
            imp.close()

    cost = dict(rows)
    print(f"scene: {model.name}   step: {H * 1e3:g} ms   best of {r} loops of {n} steps")
    print(f"{'what':<60} {'per step':>11} {'x real time':>12}")
    for what, sec in rows:
        print(f"{what:<60} {sec * 1e6:>8.1f} us {H / sec:>11.1f}x")
    print("(b) rk4, where the time goes: " + ", ".join(
        f"{k} {v * 1e6:.1f} us" for k, v in parts.items()))
    a = cost["(a) Plant.do_step, rk4"]
    b = cost["(b) FMU2Slave setReal 6 + doStep + getReal 6, rk4"]
    c1 = cost["(c) trivial pythonfmu FMU, setReal 1 + doStep + getReal 1"]
    c6 = cost["(c) trivial pythonfmu FMU, setReal 6 + doStep + getReal 6"]
    verdict = lambda ok: "met" if ok else "MISSED"
    print(f"target: in-process, default integrator (rk4) >= 200x real time: "
          f"{H / a:.1f}x -> {verdict(H / a >= 200)}")
    print(f"target: (b) <= 1.3 x (c): (b)/(c) = {b / c1:.2f} -> {verdict(b / c1 <= 1.3)}   "
          f"[(b) / trivial with 6 in, 6 out = {b / c6:.2f}]")


if __name__ == "__main__":
    main()
