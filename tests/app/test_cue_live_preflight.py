"""`cue` and `cue-live` judge a motion by the same limits (controller.capability, less the same
margins): a motion that offline `cue` calls inside every limit is flown by `cue-live` without
an intervention, and one it flags is limited live by the same limits, as many samples each.

Live is the whole chain on a simulated clock (test_cue_live.lockstep_chain: the motion replayed
as telemetry over loopback UDP, the live session, the emulated device in lockstep over loopback
UDP); offline is `cue`'s verdict (cueing.report.verdict over live.preflight, which runs the
session's own loop with an ideal device and no link). The two motions are the shipped braking
car with its deviation from rest scaled: 0.05 (inside every limit, margins included) and 0.2
(inside the mechanism's limits but past the live margins: the rack force above 80 % of Kf I_max
in the braking, and the envelope's catching up, counted as acceleration)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pymavlink")

from hil.device import Device  # noqa: E402
from hil.client import connect_udp  # noqa: E402
from hil.link import udp_server  # noqa: E402
from stewart_sim.commands.cue import preflown  # noqa: E402
from stewart_sim.cueing.motion import VehicleMotion, read_motion  # noqa: E402
from stewart_sim.cueing.report import verdict  # noqa: E402
from stewart_sim.cueing.study import cue_study  # noqa: E402
from stewart_sim.live.preflight import HOLD_AFTER  # noqa: E402
from tests.app.test_cue_live import BRAKING, lockstep_chain  # noqa: E402

REST = np.array([0.0, 0.0, 9.81])


def scaled(motion: VehicleMotion, k: float) -> VehicleMotion:
    return VehicleMotion(motion.t, REST + k * (motion.specific_force - REST),
                         k * motion.angular_velocity)


def live(scene, motion: VehicleMotion):
    """The chain's envelope interventions over the preflight's ticks."""
    server = udp_server("127.0.0.1", 0)
    seconds = float(motion.t[-1] - motion.t[0]) + HOLD_AFTER + 1.0 / scene.controller.rate
    session = lockstep_chain(scene, motion, server, connect_udp(*server.address),
                             Device(scene.model, scene.controller, lockstep=True), seconds)
    return session.envelope.interventions.as_dict()


@pytest.fixture(scope="module")
def scene():
    from stewart_sim.scene.load import load
    from tests.app.test_cue_live import SIM
    return load(SIM)


# long: the whole braking car (12.5 s, 12501 lockstep ticks of the emulated device over loopback
# UDP) per motion: the claim is about the whole flight
@pytest.mark.long
@pytest.mark.parametrize("k", [0.05, 0.2])
def test_what_cue_calls_inside_cue_live_flies_unlimited_and_what_it_flags_it_limits(scene, k):
    motion = scaled(read_motion(BRAKING), k)
    study = preflown(cue_study(scene, motion), scene, motion)
    run = study.runs[0]
    said = verdict(study)
    got = live(scene, motion)
    assert run.feasibility.violations == ()          # inside the mechanism's own limits
    if k == 0.05:
        assert said.startswith("classical: inside every limit;"), said
        assert got["limited"] == 0, got
    else:
        assert said.startswith("classical: inside the mechanism's limits, not the live "
                               "margins: cue-live's envelope: "), said
        flagged = {name for name, n in run.live["per_limit"].items() if n}
        assert flagged and {name for name, n in got["per_limit"].items() if n} == flagged
        assert got["per_limit"] == run.live["per_limit"] and got["limited"] > 0
    assert got["samples"] == run.live["samples"]
