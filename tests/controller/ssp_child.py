"""Run by test_ssp.py in a child process that cannot import this project: an SSP in FMPy's
simulate_ssp and in libcosim (libcosimpy), the plant's leg lengths after every step of each."""
import json
import sys
import zipfile
import xml.etree.ElementTree as ET

import numpy as np


def fmpy_run(path: str, steps: int, step: float) -> list:
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    # simulate_ssp takes one parameter set with names "component.variable": the archive's own
    # per-component sets (resources/<component>.ssv), as its SSD binds them
    params = []
    with zipfile.ZipFile(path) as z:
        for component in read_ssd(path).system.elements:
            root = ET.fromstring(z.read(f"resources/{component.name}.ssv"))
            for p in root.iter("{http://ssp-standard.org/SSP1/SystemStructureParameterValues}Parameter"):
                real = p[0]
                params.append(Parameter(name=f"{component.name}.{p.get('name')}", type="Real",
                                        value=float(real.get("value"))))
    result = simulate_ssp(path, stop_time=steps * step - step / 2, step_size=step,
                          parameter_set=ParameterSet(parameters=params))
    return np.column_stack([result[f"plant.l[{i}]"] for i in range(1, 7)]).tolist()


def libcosim_run(path: str, steps: int) -> list:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)

    execution = CosimExecution.from_ssp_file(path)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    index = execution.slave_index_from_instance_name("plant")
    refs = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    vrs = [refs[f"l[{i}]"] for i in range(1, 7)]
    rows = []
    for _ in range(steps):
        assert execution.step(1)
        rows.append(list(observer.last_real_values(index, vrs)))
    return rows

