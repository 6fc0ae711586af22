"""The emulated device's data: its counters, its per-run state, and what its parts see of it.

`hil.device.Device` is a dispatcher; its parts are functions of the device in their own modules:
the message handlers (hil.handlers), the tick's fault rules (hil.faults), the telemetry
(hil.streams), the STATUSTEXT rules (hil.statustext) and the observers' snapshots
(hil.observe). `DeviceView` declares every member of the device those functions use, so none
of them imports hil.device; tests/hil/test_dispatch.py holds `Device` to it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Protocol

import numpy as np

from hil.operating_mode import Event, Mode

if TYPE_CHECKING:
    from controller.capability import Capability
    from hil.framing import Receiver
    from hil.params import Param, Settings
    from hil.sensors import Sensors
    from hil.servo import Servo
    from hil.throttle import StatusLimiter
    from stewart_fmu.model import Model


@dataclass
class DeviceCounters:
    """What the device counted since start (link-level counts live in `Device.rx.stats`)."""

    ticks: int = 0
    setpoints_accepted: int = 0
    setpoints_refused: int = 0
    setpoints_ignored: int = 0      # valid, but the device was disarmed
    statustexts_suppressed: int = 0
    commands: int = 0
    commands_refused: int = 0
    params_set: int = 0
    params_refused: int = 0
    lockstep_refused: int = 0
    lockstep_repeated: int = 0
    signing_rejected: int = 0       # unsigned or badly signed frames with a key set
    watchdog_trips: int = 0
    faults: int = 0                 # plant steps refused (end stop)
    overruns: int = 0               # real-time ticks late by more than one period (serve)
    numeric_faults: int = 0         # numerical failures in the loop (safe hold, disarmed)
    handler_errors: int = 0         # messages whose handling raised (dropped, device serving)
    statustexts_rate_limited: int = 0  # cut by the STATUSTEXT token bucket (hil.throttle)
    frames_valid: int = 0           # decoded (and authenticated) frames for this system
    peer_changes: int = 0           # UDP peer switches (hil.peer)
    peer_kept: int = 0              # peer changes refused: armed, hold, a flood (hil.peer)
    flood_dropped: int = 0          # datagrams over their sender's budget, undecoded (hil.peer)


@dataclass
class DeviceState:
    """What the handlers and the tick's rules read and move, besides the servo."""

    last_pose: np.ndarray            # the pose of the last accepted setpoint (at start: home)
    mode: Mode = Mode.DISARMED       # moved only by Device.fire (hil.operating_mode.transition)
    last_setpoint_k: int = 0         # tick of the last valid setpoint
    last_setpoint_wall: float = 0.0  # its time on Device.clock (served in real time)
    ignored_said: bool = False       # one "setpoints ignored" per disarmed period
    setpoint_sequence: int | None = None   # sequence of the last accepted setpoint
    next_step: int = 0               # lockstep: the step the next LOCKSTEP must name
    last_reply: list[Any] | None = None    # lockstep: the reply to the last step
    said: dict[str, int] = field(default_factory=dict)  # repeat key -> tick it was last sent
    statustext_id: int = 0           # id of the last chunked STATUSTEXT


class DeviceView(Protocol):
    """The members of `hil.device.Device` its parts use (see the module doc)."""

    model: Model
    rate: float
    dt: float
    k: int                           # ticks done
    load: int
    lockstep: bool
    clock: Callable[[], float] | None
    last_fault: str | None
    settings: Settings
    params: dict[str, Param]
    capability: Capability
    leg_min: float
    leg_max: float
    home_lengths: np.ndarray
    servo: Servo
    plant: Any
    sensors: Sensors | None
    mav: Any
    rx: Receiver
    limiter: StatusLimiter
    observer: Any                    # hil.observe.Latest | None
    observe_every: int
    counters: DeviceCounters
    state: DeviceState

    @property
    def mode(self) -> Mode: ...

    @property
    def armed(self) -> bool: ...

    @property
    def link_errors(self) -> int: ...

    def fire(self, event: Event) -> str | None: ...

    def statustext(self, severity: int, text: str) -> list[Any]: ...

    def say_once(self, severity: int, text: str, key: str | None = None) -> list[Any]: ...

    def tick(self, step: int | None = None) -> list[Any]: ...

    def home_position(self) -> Any: ...

    def snapshot(self) -> Any: ...
