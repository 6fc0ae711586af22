"""The plant on the C core against its recorded reference, on every shipped scene.

tests/data/plant_reference.npz (tools/plant_reference.py) holds the results of a second
implementation of the same arithmetic, compiled Python kernels (inverse dynamics, the force breakdown, forward dynamics, leg state, cond(J),
energy terms, and 20 Plant steps of 1 ms with rk4, euler and dopri5, including where a step is
refused and why). The same computation on today's plant must agree to 1e-12 relative (per
quantity, to its largest entry), and refuse the same steps with the same status.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.helpers import ROOT, record
from tools.plant_reference import METHODS, OUT, SCENES
from tools.plant_reference import record as compute

TOL = 1e-12
REFERENCE = np.load(OUT)


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT / "scenes")).removesuffix(".toml")


@pytest.mark.parametrize("seed,path", list(enumerate(SCENES)), ids=[_name(p) for p in SCENES])
def test_plant_equals_its_recorded_reference(seed, path):
    name = _name(path)
    now = compute(path, seed)
    worst = 0.0
    for key, value in now.items():
        ref = REFERENCE[f"{name}/{key}"]
        if key.startswith("outcome_"):
            assert np.array_equal(value, ref), (key, value, ref)  # same refused step, same status
            continue
        assert value.shape == ref.shape, key
        if value.size:
            scale = max(float(np.max(np.abs(ref))), 1e-300)
            worst = max(worst, float(np.max(np.abs(value - ref))) / scale)
    assert {f"outcome_{m}" for m in METHODS} <= set(now)
    record(f"C core vs the recorded reference [{name}]", worst, TOL)
    assert worst <= TOL, worst
