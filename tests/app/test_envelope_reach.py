"""The live envelope never sends a pose outside a joint cone or a leg clearance: the jumpy cues
of test_cueing_envelope (random poses held 20 to 200 samples, many past the stroke, the cones
or the clearance) on the micro-manipulator with [joints] and [clearance] added. Every sample
sent is checked against an independent numpy implementation of the cones and the clearance
(tests/app/test_workspace.py's Reference) and against the stroke, speed and acceleration as
test_cueing_envelope checks them; the cues do violate those limits and the envelope counts
its interventions under the engine's names."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.capability import GEOMETRIC, Margins
from stewart_fmu.scene import load_scene
from stewart_sim.live.envelope import Envelope, envelope_limits
from stewart_sim.scene.load import scene_of
from tests.app.test_cueing_envelope import DT, _run, _within_limits
from tests.app.test_workspace import Reference, tomllib_load

MICRO = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
# (cone rad, leg radius m, the envelope's clearance margin): cones the cues' tilts pass; leg
# capsules 2.1 mm (home) and 0.3 mm apart at the narrowest pair, the latter with a tenth of
# the radius kept (the default half would refuse home)
CASES = {"cones": (0.7, 0.008, 0.5), "clearance": (1.0, 0.0095, 0.1)}


def _scene(tmp_path: Path, cone: float, radius: float):
    path = tmp_path / "micro_reach.toml"
    path.write_text(MICRO.read_text() + f"\n[joints]\nbase_cone = {cone!r}\nplatform_cone = "
                    f"{cone!r}\n\n[clearance]\nleg_radius = {radius!r}\n")
    return load_scene(path), Reference(tomllib_load(MICRO), cone, radius)


def jumpy_cue(home: np.ndarray, seed: int):
    """test_cueing_envelope's jumpy cue: random poses, rates and accelerations, each held."""
    rng = np.random.default_rng(seed)
    scale = np.array([0.05, 0.05, 0.08, 0.5, 0.5, 0.8])
    q, qd, qdd = [], [], []
    while len(q) < 1500:
        n = int(rng.integers(20, 200))
        pose = home + scale * rng.uniform(-1, 1, 6)
        rate, acc = 0.2 * scale * rng.uniform(-1, 1, 6), scale * rng.uniform(-1, 1, 6)
        q += [pose] * n
        qd += [rate] * n
        qdd += [acc] * n
    return np.array(q), np.array(qd), np.array(qdd)


@pytest.mark.parametrize("case", sorted(CASES))
def test_jumpy_cues_never_leave_a_cone_or_the_clearance(case, tmp_path):
    cone, radius, keep = CASES[case]
    model, ref = _scene(tmp_path, cone, radius)
    limits = envelope_limits(model, scene_of(model).controller, Margins(clearance=keep))
    asked = dict.fromkeys(GEOMETRIC[:3], 0)
    counted = dict.fromkeys(GEOMETRIC, 0)
    for seed in range(4):
        cue = jumpy_cue(np.asarray(model.home, dtype=float), seed)
        env = Envelope(model, limits, DT)
        steps = _run(env, cue)
        _within_limits(steps, limits, model)
        sent = ref.margins(np.array([s.q for s in steps]))
        for name in GEOMETRIC[:3]:
            assert sent[name].min() > 0, (seed, name, sent[name].min())
            asked[name] += int((ref.margins(cue[0])[name] < 0).sum())
        for name in GEOMETRIC:
            counted[name] += env.interventions.per_limit[name]
    # the cues ask for poses past the limits the case is about, and the envelope says so
    names = ("base_cone", "platform_cone") if case == "cones" else ("leg_clearance",)
    for name in names:
        assert asked[name] > 0 and counted[name] > 0, (asked, counted)
