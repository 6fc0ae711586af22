"""Run in child processes by test_native_fmu.py: FMI call scenarios through fmpy's low-level
FMU2Slave / FMU3Slave that must return Error, and a bounded random call-sequence fuzz. A crash
ends only the child (the test counts it); every status is returned as data (JSON)."""
from __future__ import annotations

import math
import random
import struct
from ctypes import byref

import numpy as np
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

OK, DISCARD, ERROR = 0, 2, 3


class Elements:
    """A model description's values one by one under their FMI 2.0 names (sigma[1],
    geometry.base_joints[1,3]) for FMI 2.0 and 3.0 alike. An FMI 3.0 array's element k is
    stored at the array's value reference + k, which the FMU does not declare: `declared` turns
    element references into whole arrays (the values of the others from `current`), `pick`
    takes the elements back out of the arrays' values."""

    def __init__(self, md):
        self.vr: dict[str, int] = {}        # element or variable name -> stored value reference
        self.name: dict[int, str] = {}      # stored value reference -> element name
        self.array: dict[int, tuple[int, int]] = {}  # element of an array -> (array's reference, k)
        self.size: dict[int, int] = {}      # declared value reference -> its number of values
        self.start: dict[int, float] = {}   # stored value reference -> start value (Real)
        self.variable: dict[str, object] = {}  # element name -> its variable
        self.outputs: list[str] = []        # element names of the outputs, in order
        for v in md.modelVariables:
            shape = tuple(getattr(v, "shape", None) or ())
            self.size[v.valueReference] = int(np.prod(shape)) if shape else 1
            names = ([f"{v.name}[{','.join(str(i + 1) for i in idx)}]" for idx in np.ndindex(shape)]
                     if shape else [v.name])
            starts = [v.start] * len(names) if v.start is None or not shape else str(v.start).split()
            for k, name in enumerate(names):
                self.vr[name], self.name[v.valueReference + k] = v.valueReference + k, name
                self.variable[name] = v
                if shape:
                    self.array[v.valueReference + k] = (v.valueReference, k)
                if v.type in ("Real", "Float64") and starts[k] is not None:
                    self.start[v.valueReference + k] = float(starts[k])
                if v.causality == "output":
                    self.outputs.append(name)
            self.vr[v.name] = v.valueReference

    def current(self) -> dict[int, list[float]]:
        """Every array's values at their start (zeros for outputs)."""
        return {a: [self.start.get(a + k, 0.0) for k in range(self.size[a])]
                for a in {a for a, _ in self.array.values()}}

    def declared(self, vrs, values, current: dict[int, list[float]]) -> tuple[list[int], list[float]]:
        """The declared value references and values that set the elements vrs to values."""
        whole: dict[int, list[float]] = {}
        for vr, x in zip(vrs, values):
            a, k = self.array.get(vr, (vr, 0))
            if a not in whole:
                whole[a] = list(current[a]) if a in current else [0.0]
            whole[a][k] = x
        return list(whole), [x for a in whole for x in whole[a]]

    def reads(self, vrs) -> tuple[list[int], int]:
        """The declared value references to read for the elements vrs, and how many values."""
        arrays = list(dict.fromkeys(self.array.get(vr, (vr, 0))[0] for vr in vrs))
        return arrays, sum(self.size.get(a, 1) for a in arrays)

    def pick(self, vrs, arrays, values) -> list[float]:
        """The elements vrs out of the values of arrays (reads(vrs))."""
        at, k = {}, 0
        for a in arrays:
            at[a] = k
            k += self.size.get(a, 1)
        return [values[at[self.array.get(vr, (vr, 0))[0]] + self.array.get(vr, (vr, 0))[1]] for vr in vrs]


class Adapter:
    """The calls the scenarios make, the same for FMI 2.0 and 3.0; each returns its status."""

    def __init__(self, unzipdir: str, version: int, messages: list, name: str = "child", token: str | None = None):
        self.version = version
        md = read_model_description(unzipdir)
        self.elements = Elements(md)   # element references: FMI 3.0 arrays set and read whole
        self.vr, self.start = self.elements.vr, self.elements.start
        self.outputs = [self.vr[n] for n in self.elements.outputs]
        # the declared range of every input element (the model description's min and max)
        self.range = {self.vr[n]: (float(v.min or -math.inf), float(v.max or math.inf))
                      for n, v in self.elements.variable.items() if v.causality == "input"}
        self.current = self.elements.current()
        tok = token or (md.guid if version == 2 else md.instantiationToken)
        common = dict(guid=tok, unzipDirectory=unzipdir, modelIdentifier="StewartPlant", instanceName=name)
        if version == 2:
            from fmpy import calloc, free
            from fmpy.fmi2 import (
                FMU2Slave,
                fmi2CallbackAllocateMemoryTYPE,
                fmi2CallbackFreeMemoryTYPE,
                fmi2CallbackFunctions,
                fmi2CallbackLoggerTYPE,
            )
            from fmpy.logging import addLoggerProxy

            def log(_env, _name, status, category, message):
                messages.append((status, (category or b"").decode(), message.decode()))

            cb = fmi2CallbackFunctions()
            cb.logger = fmi2CallbackLoggerTYPE(log)
            cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            addLoggerProxy(byref(cb))
            self._keep = (log, cb)
            self.fmu = FMU2Slave(**common)
            self.fmu.instantiate(loggingOn=True, callbacks=cb)
        else:
            from fmpy.fmi3 import FMU3Slave

            def log3(_env, status, category, message):
                messages.append((status, (category or b"").decode(), message.decode()))

            self._keep = (log3,)
            self.fmu = FMU3Slave(**common)
            self.fmu.instantiate(loggingOn=True, logMessage=log3)

    @staticmethod
    def status(fn, *args):
        """(status, result) of one call: fmpy raises on a status above Warning."""
        try:
            return OK, fn(*args)
        except FMICallException as exc:
            return exc.status, None

    def setup(self):
        if self.version == 2:
            s, _ = self.status(self.fmu.setupExperiment, None, 0.0)
            return s
        return OK

    def enter(self):
        if self.version == 2:
            return self.status(self.fmu.enterInitializationMode)[0]
        return self.status(self.fmu.enterInitializationMode, None, 0.0)[0]

    def exit(self):
        return self.status(self.fmu.exitInitializationMode)[0]

    def terminate(self):
        return self.status(self.fmu.terminate)[0]

    def reset(self):
        self.current = self.elements.current()
        return self.status(self.fmu.reset)[0]

    def set(self, vrs, values):
        """Set elements (an FMI 3.0 array whole, its other elements as last set)."""
        if self.version == 2:
            return self.status(self.fmu.setReal, list(vrs), [float(x) for x in values])[0]
        arrays, flat = self.elements.declared(list(vrs), [float(x) for x in values], self.current)
        status = self.status(self.fmu.setFloat64, arrays, flat)[0]
        if status == OK:
            k = 0
            for a in arrays:
                n = self.elements.size.get(a, 1)
                if a in self.current:
                    self.current[a] = flat[k:k + n]
                k += n
        return status

    def get(self, vrs):
        """(status, the elements' values)."""
        if self.version == 2:
            return self.status(self.fmu.getReal, list(vrs))
        arrays, n = self.elements.reads(list(vrs))
        status, values = self.status(self.fmu.getFloat64, arrays, n)
        return status, None if values is None else self.elements.pick(list(vrs), arrays, values)

    def step(self, t, h):
        return self.status(self.fmu.doStep, t, h)[0]

    def get_state(self):
        return self.status(self.fmu.getFMUstate if self.version == 2 else self.fmu.getFMUState)

    def set_state(self, state):
        return self.status(self.fmu.setFMUstate if self.version == 2 else self.fmu.setFMUState, state)[0]

    def serialize(self, state):
        return self.status(self.fmu.serializeFMUstate if self.version == 2 else self.fmu.serializeFMUState, state)

    def deserialize(self, blob):
        return self.status(self.fmu.deSerializeFMUstate if self.version == 2 else self.fmu.deserializeFMUState, blob)

    def get_string(self, vrs):
        return self.status(self.fmu.getString, list(vrs))[0]

    def set_string(self, vrs, values):
        return self.status(self.fmu.setString, list(vrs), list(values))[0]

    def set_boolean(self, vrs):
        return self.status(self.fmu.setBoolean, list(vrs), [True] * len(vrs))[0]

    def raw(self, name, *args):
        """A C function called directly with raw arguments (NULL pointers, wrong counts)."""
        return self.status(getattr(self.fmu, name), self.fmu.component, *args)[0]

    def free(self):
        self.fmu.freeInstance()


def calls_expected_to_fail(unzipdir: str, version: int) -> dict:
    messages: list = []
    st: dict[str, int] = {}
    p = 2 if version == 2 else 3
    fresh = Adapter(unzipdir, version, messages, "fresh")
    st["getReal before initialization mode"] = fresh.get([fresh.vr["platform.mass"]])[0]
    st["doStep before initialization"] = fresh.step(0.0, 1e-3)
    st["exitInitializationMode before enter"] = fresh.exit()
    st["setString unknown method with %"] = fresh.set_string([fresh.vr["solver.method"]], ["rk4%s%n"])
    st["setReal NaN parameter"] = fresh.set([fresh.vr["platform.mass"]], [math.nan])
    st["setReal inf q0"] = fresh.set([fresh.vr["q0[3]"]], [math.inf])
    st["setDebugLogging unknown category"] = fresh.raw(f"fmi{p}SetDebugLogging", True, 1,
                                                       (__import__("ctypes").c_char_p * 1)(b"logNothing"))
    fresh.set([fresh.vr["platform.mass"]], [-0.5])
    fresh.setup()
    fresh.enter()
    st["exitInitializationMode with platform.mass = -0.5"] = fresh.exit()
    st["doStep after failed initialization"] = fresh.step(0.0, 1e-3)
    st["setReal parameter after failed initialization"] = fresh.set([fresh.vr["platform.mass"]], [0.5])
    fresh.reset()
    fresh.setup()
    fresh.enter()
    recovered_fresh = fresh.exit()
    fresh.terminate()
    st["terminate twice"] = fresh.terminate()
    fresh.free()

    g = Adapter(unzipdir, version, messages, "gear")   # an overflowing parameter: never an OK with NaN/inf
    g.set([g.vr["drive.gear_ratio"]], [1e308])
    g.setup()
    g.enter()
    st["getReal rack_force in initialization with drive.gear_ratio = 1e308"] = g.get([g.vr["rack_force[1]"]])[0]
    g.exit()
    g.set([g.vr["tau[1]"]], [1.0])
    st["getReal rack_force with drive.gear_ratio = 1e308"] = g.get([g.vr["rack_force[1]"]])[0]
    g.free()

    a = Adapter(unzipdir, version, messages, "a")
    a.setup()
    a.enter()
    a.exit()
    a.step(0.0, 1e-3)
    _, before = a.get(a.outputs)
    _, state = a.get_state()
    _, blob = a.serialize(state)
    sig = a.vr["sigma[1]"]
    st["enterInitializationMode in step mode"] = a.enter()
    st["exitInitializationMode in step mode"] = a.exit()
    st["getReal unknown value reference"] = a.get([9999])[0]
    st["getReal unused value reference"] = a.get([a.vr["solver.method"] + 1])[0]  # before the inputs
    st["setReal unknown value reference"] = a.set([4294967295], [1.0])
    st["setReal output l[1]"] = a.set([a.vr["l[1]"]], [0.1])
    st["setReal NaN input"] = a.set([sig], [math.nan])
    st["setReal -inf input"] = a.set([sig], [-math.inf])
    st["setReal tau = 1e308"] = a.set([a.vr["tau[1]"]], [1e308])
    st["setReal tau just above its max"] = a.set([a.vr["tau[2]"]], [a.range[a.vr["tau[2]"]][1] * (1 + 1e-15)])
    st["setReal sigma just below its min"] = a.set([sig], [a.range[sig][0] * (1 + 1e-15)])
    st["doStep t + h overflows"] = a.step(1.7e308, 1.7e308)
    st["setReal parameter in step mode"] = a.set([a.vr["platform.mass"]], [0.6])
    st["setString solver.method in step mode"] = a.set_string([a.vr["solver.method"]], ["euler"])
    for h in (0.0, -1e-3, math.nan, math.inf, -math.inf):
        st[f"doStep h = {h}"] = a.step(1e-3, h)
    st["doStep wrong communication point"] = a.step(0.5, 1e-3)
    st["doStep NaN communication point"] = a.step(math.nan, 1e-3)
    st["getString of a Real"] = a.get_string([sig])
    st["setBoolean of a Real"] = a.set_boolean([sig])
    st["deserialize random bytes"] = a.deserialize(bytes(random.Random(1).randrange(256) for _ in range(len(blob))))[0]
    st["deserialize truncated"] = a.deserialize(blob[: len(blob) // 2])[0]
    corrupted = bytearray(blob)
    corrupted[len(blob) // 2] ^= 0x40
    st["deserialize corrupted byte"] = a.deserialize(bytes(corrupted))[0]
    st["deserialize empty"] = a.deserialize(b"\x00")[0]
    st["setFMUstate NULL"] = a.raw(f"fmi{p}SetFMUstate" if version == 2 else "fmi3SetFMUState", None)
    if version == 2:
        st["getReal NULL arrays"] = a.raw("fmi2GetReal", None, 3, None)
    else:
        st["getFloat64 NULL arrays"] = a.raw("fmi3GetFloat64", None, 3, None, 3)
        st["getFloat64 nValues != nvr"] = a.raw("fmi3GetFloat64", (__import__("ctypes").c_uint32 * 1)(sig), 1,
                                                (__import__("ctypes").c_double * 2)(), 2)
    # a NULL instance (and NULL output pointers): Error, no crash
    if version == 2:
        st["doStep NULL instance"] = a.status(a.fmu.fmi2DoStep, None, 1e-3, 1e-3, 1)[0]
        st["getReal NULL instance"] = a.status(a.fmu.fmi2GetReal, None, None, 0, None)[0]
        st["terminate NULL instance"] = a.status(a.fmu.fmi2Terminate, None)[0]
        a.fmu.fmi2FreeInstance(None)
    else:
        st["doStep NULL instance"] = a.status(a.fmu.fmi3DoStep, None, 1e-3, 1e-3, True, None, None, None, None)[0]
        st["getFloat64 NULL instance"] = a.status(a.fmu.fmi3GetFloat64, None, None, 0, None, 0)[0]
        st["terminate NULL instance"] = a.status(a.fmu.fmi3Terminate, None)[0]
        a.fmu.fmi3FreeInstance(None)
    _, after = a.get(a.outputs)
    unchanged = after == before
    recovered = a.step(1e-3, 1e-3)
    a.terminate()
    a.free()
    try:
        Adapter(unzipdir, version, messages, "bad token", token="{not-this-fmu}")
        st["instantiate with a foreign token"] = OK
    except Exception:  # fmpy: "Failed to instantiate FMU" (the FMU returned NULL)
        st["instantiate with a foreign token"] = ERROR
    return {"status": st, "unchanged": unchanged, "recovered": recovered + recovered_fresh,
            "messages": messages}


HEADER, CHECKSUM = 32, 24   # a serialized state: header bytes, the checksum's offset (component.c)


def fnv1a(data: bytes, h: int = 14695981039346656037) -> int:
    """64-bit FNV-1a, as component.c's."""
    for b in data:
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def reseal(blob: bytes | bytearray) -> bytes:
    """A serialized state with its checksum recomputed (the header up to the checksum, then the
    payload): an edit the checksum cannot see, as a forger makes it."""
    b = bytearray(blob)
    b[CHECKSUM:HEADER] = fnv1a(bytes(b[HEADER:]), fnv1a(bytes(b[:CHECKSUM]))).to_bytes(8, "little")
    return bytes(b)


def forged_states(unzipdir: str, version: int, edits: dict) -> dict:
    """A running instance's serialized state, edited per case ({name: [(byte offset in the
    state, struct format, value), ...]}) and resealed: each case's deserialize status, whether
    setFMUstate of what it returned worked, and the messages. Case "unedited" is the state as
    serialized, resealed."""
    import struct
    messages: list = []
    a = Adapter(unzipdir, version, messages, "forger")
    a.setup()
    a.enter()
    a.exit()
    for k in range(3):
        a.step(k * 1e-3, 1e-3)
    _, state = a.get_state()
    _, blob = a.serialize(state)
    out = {}
    for name, fields in {"unedited": [], **edits}.items():
        b = bytearray(blob)
        for offset, fmt, value in fields:
            struct.pack_into("<" + fmt, b, HEADER + offset, value)
        del messages[:]
        status, restored = a.deserialize(reseal(b))
        applied = a.set_state(restored) if status == OK else None
        out[name] = {"status": status, "applied": applied, "messages": [m for _, _, m in messages]}
    a.free()
    return out


def fuzz(unzipdir: str, version: int, seed: int, n_calls: int) -> dict:
    """Random calls; each call's status is checked against what it must be where that is
    determined (Error for out-of-order and bad-argument calls, an input outside its declared
    range among them), and every value a getReal returns with OK is finite (nonfinite_ok lists
    those that are not). Serialized states are also edited and resealed (their checksum
    recomputed): a forged state that loads must still give finite outputs."""
    rng = random.Random(seed)
    messages: list = []
    inst = Adapter(unzipdir, version, messages, f"fuzz{seed}")
    vr = inst.vr
    params = [vr[n] for n in ("platform.mass", "friction.viscous", "q0[3]", "solver.max_step", "geometry.leg_max",
                              "legs.lower_inertia[2]", "drive.pinion_radius")]
    inputs = [vr[f"sigma[{i}]"] for i in range(1, 7)] + [vr[f"tau[{i}]"] for i in range(1, 7)]
    start = {k: inst.start[k] for k in params}
    unknown = [9999, vr["solver.method"] + 1, 150, 2**31, 4294967295, 0 if version == 2 else 5000]
    phase, t = "inst", 0.0
    states: list = []
    blobs: list = []
    out = {"calls": 0, "must_fail": 0, "errors_returned": 0, "discards": 0, "steps_ok": 0, "other_errors": 0,
           "not_error": [], "gets_ok": 0, "values_read": 0, "nonfinite_ok": [], "forged": 0, "forged_loaded": 0,
           "refused_own_state": []}
    readable = inst.outputs + ([0] if version == 3 else [])   # FMI 3.0: time is readable too

    def weird(x: float) -> float:
        return rng.choice([x, x * (1 + rng.uniform(-0.1, 0.1)), -x, 0.0, 1e300, -1e300, math.nan, math.inf,
                           -math.inf, 5e-324, -5e-324, 2.2e-308, 1e308, -1.7976931348623157e308, x * 1e6,
                           9.999e6, 1.0001e7, -1.0001e6, x * 1e300])

    def outputs_finite(action: str, known: bool = True):
        """Read random outputs: an OK must carry finite values only (known: the phase is
        known, so whether the read must fail is too)."""
        ks = rng.sample(readable, rng.randint(1, len(readable)))
        s, values = inst.get(ks)
        note(action, s, known and phase in ("inst", "failed"))
        if s == OK:
            out["gets_ok"] += 1
            out["values_read"] += len(values)
            bad = [(inst.elements.name.get(k, k), v) for k, v in zip(ks, values) if not math.isfinite(v)]
            if bad:
                out["nonfinite_ok"].append([action, phase, t, bad[:3]])

    def note(action: str, status: int, must_fail: bool):
        out["calls"] += 1
        if status == DISCARD:
            out["discards"] += 1
        if must_fail:
            out["must_fail"] += 1
            if status == ERROR:
                out["errors_returned"] += 1
            else:
                out["not_error"].append([action, status, phase])
        elif status == ERROR:
            out["other_errors"] += 1

    for _ in range(n_calls):
        if phase == "inst" and rng.random() < 0.5:
            action = "init_all"     # reach step mode often: most of the interesting calls are there
        else:
            action = rng.choice(["setup_enter", "exit", "terminate", "reset", "set_param", "set_input", "set_input",
                                 "set_output", "unknown", "get_outputs", *["step"] * 10,
                                 "get_state", "set_state", "serialize", "deserialize_bad", "wrong_type", "renew",
                                 "deserialize_forged", "deserialize_forged",
                                 "set_method", *(["bad_count"] if version == 3 else [])])
        if action == "init_all":
            for name, call in (("setupExperiment", inst.setup), ("enterInitializationMode", inst.enter)):
                note(name, call(), False)
            s = inst.exit()
            note("exitInitializationMode", s, False)
            phase, t = ("step" if s == OK else "failed"), 0.0
        elif action == "setup_enter":
            s1 = inst.setup()
            s2 = inst.enter()
            note("setupExperiment/enterInitializationMode", max(s1, s2), phase != "inst")
            if phase == "inst" and max(s1, s2) == OK:
                phase, t = "init", 0.0
        elif action == "exit":
            s = inst.exit()
            note("exitInitializationMode", s, phase != "init")
            if phase == "init":
                phase = "step" if s == OK else "failed"
        elif action == "terminate":
            s = inst.terminate()
            note("terminate", s, phase != "step")
            if s == OK:
                phase = "term"
        elif action == "reset":
            s = inst.reset()
            note("reset", s, False)
            if s == OK:
                phase, t = "inst", 0.0
        elif action == "set_param":
            k = rng.choice(params)
            value = weird(start[k])
            s = inst.set([k], [value])
            note("setReal(parameter)", s, not math.isfinite(value) or phase not in ("inst", "init"))
        elif action == "set_input":
            ks = rng.sample(inputs, rng.randint(1, 12))
            values = [weird(rng.uniform(-5, 5)) for _ in ks]
            s = inst.set(ks, values)
            outside = any(not inst.range[k][0] <= v <= inst.range[k][1] for k, v in zip(ks, values))  # nan too
            note("setReal(inputs)", s, outside or phase in ("term", "failed"))
        elif action == "set_output":
            s = inst.set([rng.choice(inst.outputs)], [rng.uniform(-1, 1)])
            note("setReal(output)", s, True)
        elif action == "unknown":
            k = rng.choice(unknown)
            s = inst.get([k])[0] if rng.random() < 0.5 else inst.set([k], [1.0])
            note("unknown value reference", s, True)
        elif action == "get_outputs":
            outputs_finite("getReal(outputs)")
        elif action == "step":
            h = rng.choice([1e-3, 1e-3, 1e-4, 2.5e-3, 0.05, 1e300, 1e308, 1e-15, 5e-324, 0.0, -0.0, -1e-3, math.nan,
                            math.inf])
            tc = t if rng.random() < 0.85 else rng.choice([t + 1.0, t - 1e-3, math.nan, -math.inf, 1e308])
            s = inst.step(tc, h)
            bad = (phase != "step" or not (math.isfinite(h) and h > 0)
                   or not (abs(tc - t) <= 1e-9 * max(1.0, abs(t))))
            note("doStep", s, bad)
            if s == OK and not bad:
                t = tc + h
                out["steps_ok"] += 1
            if s == OK:
                outputs_finite("getReal(outputs) after doStep")
        elif action == "get_state":
            s, state = inst.get_state()
            note("getFMUstate", s, False)
            if s == OK:
                states.append((state, phase, t))
        elif action == "set_state" and states:
            state, ph, tt = rng.choice(states)
            s = inst.set_state(state)
            note("setFMUstate", s, False)
            if s != OK:
                out["refused_own_state"].append(["setFMUstate", ph])
            if s == OK:
                phase, t = ph, tt
        elif action == "serialize" and states:
            state, ph, tt = rng.choice(states)
            s, blob = inst.serialize(state)
            note("serializeFMUstate", s, False)
            if s == OK:
                blobs.append(blob)
                s2, restored = inst.deserialize(blob)
                note("deSerializeFMUstate", s2, False)
                if s2 == OK:
                    states.append((restored, ph, tt))
                else:
                    out["refused_own_state"].append(["deSerializeFMUstate", ph])
        elif action == "deserialize_bad":
            if blobs and rng.random() < 0.7:
                blob = bytearray(rng.choice(blobs))
                how = rng.choice(["truncate", "flip", "extend", "header"])
                if how == "truncate":
                    blob = blob[: rng.randrange(1, len(blob))]
                elif how == "flip":
                    k = rng.randrange(len(blob))
                    blob[k] ^= 1 << rng.randrange(8)
                elif how == "extend":
                    blob += b"\x00"
                else:
                    blob[:8] = b"NOTOURS!"
            else:
                blob = bytearray(rng.randrange(256) for _ in range(rng.randint(1, 2000)))
            s, _ = inst.deserialize(bytes(blob))
            note("deSerializeFMUstate(foreign)", s, True)
        elif action == "deserialize_forged" and blobs:
            # edits a checksum cannot see: hostile doubles in random fields, random bytes, resealed
            blob = bytearray(rng.choice(blobs))
            for _ in range(rng.randint(1, 4)):
                if rng.random() < 0.7:
                    k = HEADER + 8 * rng.randrange((len(blob) - HEADER) // 8)
                    blob[k:k + 8] = struct.pack("<d", rng.choice([math.nan, math.inf, -math.inf, 1e300, -1e300, 1e308,
                                                                  5e-324, 0.0, -1.0, 1e7 + 1, rng.uniform(-10, 10)]))
                else:
                    blob[rng.randrange(HEADER, len(blob))] = rng.randrange(256)
            s, restored = inst.deserialize(reseal(blob))
            note("deSerializeFMUstate(forged)", s, False)
            out["forged"] += 1
            if s == OK:
                out["forged_loaded"] += 1
                _, before = inst.get_state()
                s = inst.set_state(restored)
                note("setFMUstate(forged)", s, False)
                if s == OK:   # its phase may be edited too: read, then back to the state before
                    outputs_finite("getReal(outputs) of a forged state", known=False)
                    note("setFMUstate(back)", inst.set_state(before), False)
        elif action == "wrong_type":
            k = rng.choice(inputs[:6] + inst.outputs[:3])
            s = inst.get_string([k]) if rng.random() < 0.5 else inst.set_boolean([k])
            note("wrong type", s, True)
        elif action == "set_method":
            name = rng.choice(["rk4", "euler", "dopri5", "RK45", "%s%n%x", ""])
            s = inst.set_string([vr["solver.method"]], [name])
            note("setString(solver.method)", s, name not in ("rk4", "euler", "dopri5") or phase not in ("inst", "init"))
        elif action == "bad_count":   # FMI 3.0: nValues other than the arrays hold
            arrays = [a for a, n in inst.elements.size.items() if n > 1]
            ks = rng.sample(arrays, rng.randint(1, 3))
            right = sum(inst.elements.size[a] for a in ks)
            n = rng.choice([0, 1, right - 1, right + 1, len(ks), 2 * right, 2**31, 2**40])
            if n == right:
                n += 1
            if n > 2 * right:   # a huge count with a small buffer: refused before any value is touched
                import ctypes
                fn = inst.fmu.fmi3GetFloat64 if rng.random() < 0.5 else inst.fmu.fmi3SetFloat64
                s = inst.status(fn, inst.fmu.component, (ctypes.c_uint32 * len(ks))(*ks), len(ks),
                                (ctypes.c_double * right)(), n)[0]
            elif rng.random() < 0.5:
                s = inst.status(inst.fmu.getFloat64, ks, n)[0]
            else:
                s = inst.status(inst.fmu.setFloat64, ks, [rng.uniform(-1, 1) for _ in range(n)])[0]
            note("get/setFloat64(wrong nValues)", s, True)
        elif action == "renew":
            inst.terminate()
            inst.free()
            inst = Adapter(unzipdir, version, messages, f"fuzz{seed}")
            phase, t = "inst", 0.0
            out["calls"] += 1
        if len(messages) > 2000:
            del messages[:1000]
    inst.free()
    return out


def initialization_refusals(unzipdir: str, version: int, cases: dict) -> dict:
    """Per case ({name: {value reference: value}}): a fresh instance with those parameter values
    set, then exitInitializationMode; its status and the messages it logged."""
    out = {}
    for name, values in cases.items():
        messages: list = []
        fmu = Adapter(unzipdir, version, messages, name)
        status = fmu.set([int(vr) for vr in values], list(values.values()))
        fmu.setup()
        fmu.enter()
        out[name] = {"set": status, "exit": fmu.exit(), "messages": [m for _, _, m in messages]}
        fmu.free()
    return out
