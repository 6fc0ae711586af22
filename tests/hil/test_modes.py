"""hil.operating_mode: every (mode, event) pair of the device's transition table against the rules as
written here (a grid read off hil.device's contract), and the device following the table end
to end: each mode reached through messages and ticks, each event made through messages and
ticks, the mode and what the host sees (HEARTBEAT's armed flag, DRIVE_STATUS.watchdog, the
refusal's STATUSTEXT) as the table says."""
from __future__ import annotations

import itertools
from pathlib import Path

import pytest

pytest.importorskip("pymavlink")

from controller.plants import PlantStepError  # noqa: E402
from hil import mavlink_stewart as ms  # noqa: E402
from hil.device import Device  # noqa: E402
from hil.operating_mode import TABLE, WATCHDOG_STATE, Event, Mode, armed, transition  # noqa: E402
from hil.servo import HOMING_MIN_TIME  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "micro_manipulator.toml"
WATCHDOG = 0.05   # s: shorter than the shortest homing (hil.servo.HOMING_MIN_TIME, 0.2 s)

# The rules: the mode after each event, "!" + a word of the refusal's STATUSTEXT for the host's
# events refused, "-" for a device event refused because it cannot happen in that mode.
GRID = """
            ARM      DISARM    HOME      SETPOINT    WATCHDOG_EXPIRED  HOMING_DONE  FAULT
DISARMED    ARMED    DISARMED  !home     !setpoints  -                 -            DISARMED
ARMED       ARMED    DISARMED  HOMING    TRACKING    -                 -            DISARMED
TRACKING    ARMED    DISARMED  HOMING    TRACKING    TRIPPED           -            DISARMED
HOMING      ARMED    DISARMED  HOMING    TRACKING    -                 ARMED        DISARMED
TRIPPED     ARMED    DISARMED  HOMING    TRACKING    -                 -            DISARMED
"""


def _rules() -> dict[tuple[Mode, Event], str]:
    head, *rows = [line.split() for line in GRID.strip().splitlines()]
    return {(Mode[row[0]], Event[e]): cell for row in rows for e, cell in zip(head, row[1:])}


RULES = _rules()
PAIRS = list(itertools.product(Mode, Event))


def test_the_rules_and_the_table_cover_every_pair():
    assert len(PAIRS) == 35 and set(RULES) == set(PAIRS) == set(TABLE)


@pytest.mark.parametrize("mode, event", PAIRS, ids=[f"{m.name}-{e.name}" for m, e in PAIRS])
def test_transition(mode, event):
    rule, t = RULES[(mode, event)], transition(mode, event)
    if rule == "-":
        assert t.mode is mode and t.refusal
    elif rule.startswith("!"):
        assert t.mode is mode and rule[1:] in t.refusal.split() and "disarmed" in t.refusal
    else:
        assert t.mode is Mode[rule] and t.refusal is None


def test_modes_on_the_wire():
    """Armed in every mode but DISARMED; the watchdog runs only while TRACKING."""
    assert [m for m in Mode if not armed(m)] == [Mode.DISARMED]
    assert WATCHDOG_STATE == {Mode.DISARMED: ms.STEWART_WATCHDOG_IDLE,
                              Mode.ARMED: ms.STEWART_WATCHDOG_IDLE,
                              Mode.TRACKING: ms.STEWART_WATCHDOG_OK,
                              Mode.HOMING: ms.STEWART_WATCHDOG_IDLE,
                              Mode.TRIPPED: ms.STEWART_WATCHDOG_TRIPPED}


# --------------------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def model():
    return load_scene(SCENE)


def _command(cmd: int, p1: float = 0.0):
    return ms.MAVLink_command_long_message(1, 1, cmd, 0, p1, 0, 0, 0, 0, 0, 0)


def _setpoint(dev: Device):
    """A valid setpoint: the leg lengths now, sequence = the tick count."""
    return ms.MAVLink_leg_setpoint_message(0, dev.k, dev.plant.outputs.lengths.tolist(),
                                           [0.0] * 6, 0, [0.0] * 6)


def _ticks(dev: Device, seconds: float) -> list:
    out = []
    for _ in range(int(round(seconds / dev.dt)) + 2):
        out += dev.tick()
    return out


def _fault(dev: Device, monkeypatch) -> list:
    """One tick whose plant step is refused (as at an end stop)."""
    def refuse(t, h, torque):
        raise PlantStepError("an end stop (test)")
    with monkeypatch.context() as m:
        m.setattr(dev.servo.port, "step", refuse)
        return dev.tick()


EVENTS = {Event.ARM: lambda dev, mp: dev.receive(_command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1)),
          Event.DISARM: lambda dev, mp: dev.receive(_command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 0)),
          Event.HOME: lambda dev, mp: dev.receive(_command(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH)),
          Event.SETPOINT: lambda dev, mp: dev.receive(_setpoint(dev)),
          # past the watchdog time without a setpoint (it trips only while TRACKING)
          Event.WATCHDOG_EXPIRED: lambda dev, mp: _ticks(dev, WATCHDOG),
          # homing from home (where _reach leaves the platform) takes the shortest homing time
          Event.HOMING_DONE: lambda dev, mp: _ticks(dev, HOMING_MIN_TIME),
          Event.FAULT: _fault}


def _reach(model, mode: Mode) -> Device:
    """A device brought into `mode` by the host's messages and ticks alone."""
    dev = Device(model, watchdog=WATCHDOG)
    if mode is not Mode.DISARMED:
        dev.receive(_command(ms.MAV_CMD_COMPONENT_ARM_DISARM, 1))
    if mode is Mode.HOMING:
        dev.receive(_command(ms.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    if mode in (Mode.TRACKING, Mode.TRIPPED):
        dev.receive(_setpoint(dev))
    if mode is Mode.TRIPPED:
        _ticks(dev, WATCHDOG)
    assert dev.mode is mode
    return dev


# HOMING_DONE can be made only while homing (the end of a quintic that exists then).
E2E = [(m, e) for m, e in PAIRS if e is not Event.HOMING_DONE or m is Mode.HOMING]


@pytest.mark.parametrize("mode, event", E2E, ids=[f"{m.name}-{e.name}" for m, e in E2E])
def test_device_follows_the_table(model, monkeypatch, mode, event):
    dev = _reach(model, mode)
    out = EVENTS[event](dev, monkeypatch)
    t = transition(mode, event)
    rule = RULES[(mode, event)]
    assert dev.mode is t.mode is (mode if rule[0] in "!-" else Mode[rule])
    texts = [m.text for m in out if m.get_type() == "STATUSTEXT"]
    if t.refusal is not None and event in (Event.HOME, Event.SETPOINT):
        assert texts == [t.refusal]                      # the host reads the table's reason
    hb, ds = dev.heartbeat(), dev.drive_status()
    assert bool(hb.base_mode & ms.MAV_MODE_FLAG_SAFETY_ARMED) == armed(t.mode) == dev.armed
    assert ds.watchdog == WATCHDOG_STATE[t.mode]
    assert (hb.system_status == ms.MAV_STATE_CRITICAL) == (t.mode is Mode.TRIPPED)
    tripped_now = mode is Mode.TRACKING and t.mode is Mode.TRIPPED
    assert dev.counters.watchdog_trips == int(mode is Mode.TRIPPED) + int(tripped_now)


def test_pairs_counted():
    """35 pairs in the table; 31 of them made end to end (HOMING_DONE only while homing)."""
    assert len(E2E) == 31
