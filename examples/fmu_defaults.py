"""Export the plant as an FMU and run it with fmpy's defaults (docs/guides/fmu-and-ssp.md: The
plant as an FMI co-simulation unit): no inputs set, the inputs start at the force holding home,
so the platform stays put over the DefaultExperiment (0 to 1 s, 1 ms steps). Needs a C compiler."""
import tempfile
from pathlib import Path

import numpy as np
from fmpy import read_model_description, simulate_fmu

from stewart_fmu import load_scene
from stewart_fmu.fmu.export import export_fmu

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"
with tempfile.TemporaryDirectory() as tmp:
    fmu = export_fmu(SCENE, Path(tmp) / "plant.fmu", fmi_version=2)
    md = read_model_description(str(fmu))
    start = {v.name: v.start for v in md.modelVariables}
    print("sigma start (N):", [round(float(start[f"sigma[{i}]"]), 6) for i in range(1, 7)])
    de = md.defaultExperiment
    print(f"default experiment: {de.startTime} to {de.stopTime} s, step {de.stepSize} s")
    result = simulate_fmu(str(fmu), output=["z", "l[1]"])   # every setting from the FMU
home_z = load_scene(SCENE).home[2]
print(f"ran to t = {result['time'][-1]:g} s, |z - home| <= {np.abs(result['z'] - home_z).max():.1e} m")
