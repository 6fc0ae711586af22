"""The live loop of `cue-live`: one tick per device period, telemetry to leg setpoints.

Each tick k (session time t_k = k / rate, the device's time; due at start + t_k on the clock):
1. the operator's commands (stewart_sim.live.control) and the newest valid telemetry sample
   (stewart_sim.live.receiver: a bounded drain, refusals counted by kind);
2. the mode (live.pipeline_modes: its one transition table): an accepted sample while cueing
   steps the washout (stewart_sim.live.cue_stream; at most MAX_STEPS steps a tick, a backlog
   taken by the next ticks); no sample for `loss_timeout` s is a
   telemetry loss: the platform fades to neutral and the washout restarts at rest when
   telemetry is back (after the fade has reached neutral);
3. the pose reference: the cue extrapolated to t_k, or the neutral pose at rest while fading,
   parking or parked;
4. the safety envelope (live.envelope.Envelope: stroke, leg speed and acceleration, rack
   force, cond(J); an emergency stop is its `brake`) -> leg lengths, rates and feed-forward
   forces; the force rate is the backward difference of the forces sent;
5. LEG_SETPOINT k to the device (stewart_sim.live.device_out), and the row of the record; no
   LEG_STATE back for `device_timeout` s (default: the device's own watchdog, WDG_TIMEOUT,
   0.2 s on the emulated device: as long as the device itself waits for a setpoint before it
   holds its legs) is the loss of the device: one line on stderr at once, counted in the
   summary, and the session ends there: no more setpoints (a device that still hears us holds
   its legs when its watchdog trips), no park (a fade sent to a device that does not answer
   proves nothing), the device disarmed (bounded tries: DeviceOut.hold) and `cue-live` exits
   with status 2 after its summary;
6. with an observer (`cue-live --view`), every rate / OBSERVE_HZ ticks a hil.observe.Snapshot
   for the live view: the pose sent (the host does not know the measured pose; the device's
   own view has it), the cue's reference pose, the lengths the device last measured, the
   feed-forward rack forces, cond(J), and the specific forces at the pilot's head ([cueing]
   head, platform frame): the vehicle's (the newest telemetry sample: the vehicle frame is the
   platform's at neutral) and the one the pose sent delivers (cueing.vestibular.delivered_at).

The clock is any function of seconds: the monotonic wall clock in `run_realtime`, a simulated
one in tests (`LiveSession.tick(now)` takes the time), so the whole chain runs deterministic
with the device in lockstep. Latency (in the summary) is, per accepted telemetry sample, the
time on the monotonic clock from the start of the drain that read it to the moment the first
setpoint computed from it left: the pipeline's own share. A datagram also waits in the socket
for up to one period before the tick drains it; benchmarks/bench_cue_live.py measures the whole
path, from the sender's send to the setpoint frame on the device's side of the link.
"""
from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from hil.observe import OBSERVE_HZ, Latest, Snapshot
from hil.timing import Lateness, gc_frozen, wait_until
from stewart_fmu.kinematics import condition_number
from stewart_fmu.model import Model
from stewart_sim.cueing.study import CueError
from stewart_sim.cueing.vestibular import delivered_at
from stewart_sim.cueing.washout_step import WashoutStepper
from stewart_sim.live.control import Control
from stewart_sim.live.cue_stream import CueStream, OptimalStream, Reference
from stewart_sim.live.device_out import DeviceOut
from stewart_sim.live.envelope import Envelope, envelope_limits
from stewart_sim.live.fade import Blend, Fade, fade_to_home
from stewart_sim.live.optimal_stream import LIVE_RATE_MIN, LiveOptimal
from stewart_sim.live.pipeline_modes import Event, Mode, fading, transition
from stewart_sim.live.receiver import TelemetryReceiver
from stewart_sim.scene.load import Scene

LOSS_TIMEOUT = 0.1      # s without an accepted telemetry sample: a loss, the platform fades
MAX_LAG = 0.01          # s a tick may start late before the ticks it missed are skipped
PARK_TIMEOUT = 30.0     # s of ticks a park (or a brake) may take at most
RECORD_CHUNK = 65536    # rows of the record allocated at a time
RECORD_COLUMNS = ("t", "seq", "mode", "t_telemetry", *(f"l_set{i}" for i in range(1, 7)),
                  *(f"l{i}" for i in range(1, 7)))
MODE_CODES = {m: i for i, m in enumerate(Mode)}   # the record's mode column
OPERATOR_EVENTS = {"park": Event.PARK, "quit": Event.PARK, "estop": Event.ESTOP,
                   "resume": Event.RESUME}


@dataclass
class SessionCounts:
    ticks: int = 0
    overruns: int = 0       # ticks more than MAX_LAG late (the missed ticks skipped)
    cue_steps: int = 0
    fades: int = 0
    device_losses: int = 0  # no LEG_STATE for device_timeout s (the session ends at the first)
    commands: dict[str, int] = field(default_factory=dict)


class Record:
    """The session's rows (RECORD_COLUMNS), in chunks, up to `capacity` rows (later rows are
    counted, not kept)."""

    def __init__(self, capacity: int) -> None:
        self.capacity = int(capacity)
        self._chunks: list[np.ndarray] = []
        self.rows = 0
        self.dropped = 0

    def add(self, row: list[float]) -> None:
        if self.rows >= self.capacity:
            self.dropped += 1
            return
        i = self.rows % RECORD_CHUNK
        if i == 0:
            self._chunks.append(np.full((RECORD_CHUNK, len(RECORD_COLUMNS)), math.nan))
        self._chunks[-1][i] = row
        self.rows += 1

    def table(self) -> np.ndarray:
        if not self._chunks:
            return np.zeros((0, len(RECORD_COLUMNS)))
        return np.concatenate(self._chunks)[:self.rows]


class LiveSession:
    """The live loop's state and its tick (see the module doc)."""

    def __init__(self, model: Model, receiver: TelemetryReceiver, cue: CueStream,
                 envelope: Envelope, device: DeviceOut, rate: float,
                 control: Control | None = None, loss_timeout: float = LOSS_TIMEOUT,
                 record: Record | None = None, observer: Latest | None = None,
                 head=None, device_timeout: float | None = None,
                 warn: Callable[[str], None] | None = None) -> None:
        self.model = model
        self.receiver, self.cue, self.envelope, self.device = receiver, cue, envelope, device
        self.control = control
        self.period = 1.0 / rate
        self.rate = rate
        self.loss_timeout = loss_timeout
        self.record = record
        self.home = np.asarray(model.home, float)
        self.mode = Mode.STARTING
        self.blend: Blend | None = None
        self.fade: Fade | None = None
        self.k = 0
        self.counts = SessionCounts()
        self.latency = Lateness(1.0)        # a histogram; "misses" (over 1 s) unused
        self.last_accept = -math.inf
        self.t_telemetry = math.nan         # the newest sample's time the cue has used
        self._pending: float | None = None  # when the drain of a sample no setpoint used began
        self._force: np.ndarray | None = None
        self._force_t = -math.inf
        self.stopped_by: str | None = None
        self.lateness: Lateness | None = None   # the real-time run's tick lateness
        self.observer = observer
        self.head = head
        self._observe_every = max(1, round(rate / OBSERVE_HZ))
        self._f_vehicle: tuple[float, float, float] | None = None
        self._measured = np.asarray(model.home, float) * math.nan
        self._device_timeout = device_timeout
        self.warn = warn or (lambda line: print(line, file=sys.stderr, flush=True))
        self.device_lost_at: float | None = None   # session time the device was found lost
        self._state_at: float | None = None        # clock time the last LEG_STATE came

    @property
    def device_timeout(self) -> float:
        """s without a LEG_STATE back before the device is lost (see the module doc)."""
        return (self._device_timeout if self._device_timeout is not None
                else float(self.device.watchdog))

    @property
    def device_lost(self) -> bool:
        return self.device_lost_at is not None

    # --- the mode ---------------------------------------------------------------------------

    def event(self, ev: Event, now: float) -> bool:
        """Apply an event to the mode (live.pipeline_modes' table); False when refused. Entering
        RUNNING restarts the washout at rest and blends its cue in from the pose held
        (live.fade.Blend); entering FADING or PARKING starts the fade home from the pose
        last sent (live.fade.fade_to_home) unless one is under way."""
        t = transition(self.mode, ev)
        if t.refusal is not None:
            return False
        old, new = self.mode, t.mode
        if new is not old:
            if new is Mode.RUNNING:
                self.cue.reset()
                self.blend = Blend(self.envelope.last.q.copy(), now)
            elif new in (Mode.FADING, Mode.PARKING) and not fading(old):
                self.fade = fade_to_home(self.model, self.envelope.limits,
                                         self.envelope.last.q, now)
            if new is Mode.FADING:
                self.counts.fades += 1
                self.receiver.forget_order()     # a restarted sender is taken when it returns
            self.mode = new
        return True

    def _commands(self, now: float) -> None:
        if self.control is None:
            return
        for word in self.control.poll():
            self.counts.commands[word] = self.counts.commands.get(word, 0) + 1
            if word == "quit":
                self.stopped_by = "quit"
            self.event(OPERATOR_EVENTS[word], now)

    # --- one tick ---------------------------------------------------------------------------

    def reference(self, now: float) -> Reference:
        """The pose to send at `now` in the current mode (not STOPPED: that is the brake)."""
        if self.mode is Mode.RUNNING:
            r = self.cue.reference(now)
            if self.blend is not None and not self.blend.done(now):
                return Reference(*self.blend.apply(now, r.q, r.qd, r.qdd))
            return r
        if fading(self.mode):
            return Reference(*self.fade.sample(now))
        return Reference(self.home, np.zeros(6), np.zeros(6))

    def tick(self, now: float) -> None:
        """Tick k at clock time `now` (see the module doc)."""
        self._commands(now)
        drained = time.monotonic()
        s = self.receiver.poll(now)
        if s is not None:
            self.last_accept = now
            self._f_vehicle = s.specific_force
            if self.event(Event.TELEMETRY, now):
                self.counts.cue_steps += self.cue.push(s, now)
                self.t_telemetry = s.t
                self._pending = drained
        elif self.mode is Mode.RUNNING and now - self.last_accept > self.loss_timeout:
            self.event(Event.LOSS, now)
        elif self.mode is Mode.RUNNING:         # a backlog of grid points (cue_stream)
            self.counts.cue_steps += self.cue.advance(now)
        if fading(self.mode) and self.fade.done(now):
            self.event(Event.FADE_DONE, now)
        ref = None
        if self.mode is Mode.STOPPED:
            step = self.envelope.brake()
        else:
            ref = self.reference(now)
            step = self.envelope.step(ref.q, ref.qd, ref.qdd)
        # the force rate over the time since the last tick (more than a period after a stall)
        force = step.forces
        force_rate = (np.zeros(6) if self._force is None or now <= self._force_t
                      else (force - self._force) / (now - self._force_t))
        self._force, self._force_t = force, now
        states = self.device.send(self.k, self.k * self.period, step.lengths, step.rates, force,
                                  force_rate)
        if self._pending is not None and self.mode is Mode.RUNNING:
            self.latency.add(self.device.send_time - self._pending)
            self._pending = None
        if states:
            self._measured = np.asarray(states[-1].length, float)
        self._watch_device(now, bool(states))
        if self.observer is not None and self.k % self._observe_every == 0:
            self._publish(step, ref)
        if self.record is not None:
            measured = list(states[-1].length) if states else [math.nan] * 6
            self.record.add([self.k * self.period, self.k, MODE_CODES[self.mode],
                             self.t_telemetry, *step.lengths, *measured])
        self.k += 1
        self.counts.ticks += 1

    def _watch_device(self, now: float, answered: bool) -> None:
        """The loss of the device (see the module doc, item 5): said once, at once."""
        if answered or self._state_at is None:
            self._state_at = now            # the first setpoint starts the device's clock
            return
        if self.device_lost or now - self._state_at <= self.device_timeout:
            return
        self.device_lost_at = self.k * self.period
        self.counts.device_losses += 1
        self.stopped_by = "the device's loss"
        self.warn(f"cue-live: device lost at {self.device_lost_at:.3f} s: no LEG_STATE for "
                  f"{now - self._state_at:.3f} s (over {self.device_timeout:g} s, the device's "
                  "watchdog): setpoints stopped, the session ends")

    def _publish(self, step, ref: Reference | None) -> None:
        """A snapshot for the live view (see the module doc, item 6)."""
        f, _ = delivered_at(step.q, step.qd, step.qdd, self.model.gravity, self.head)
        lengths = self._measured if np.all(np.isfinite(self._measured)) else step.lengths
        self.observer.publish(Snapshot(
            tick=self.k, t=self.k * self.period, q=tuple(step.q.tolist()),
            q_ref=None if ref is None else tuple(ref.q.tolist()),
            lengths=tuple(np.asarray(lengths, float).tolist()),
            forces=tuple(step.forces.tolist()), cond=condition_number(self.model, step.q),
            armed=True, f_vehicle=self._f_vehicle,
            f_delivered=(float(f[0]), float(f[1]), float(f[2]))))

    @property
    def parked(self) -> bool:
        """Parked at home, or stopped by the emergency stop."""
        return self.mode in (Mode.PARKED, Mode.STOPPED)


def run_realtime(session: LiveSession, duration: float = math.inf,
                 park_timeout: float = PARK_TIMEOUT,
                 clock: Callable[[], float] = time.monotonic,
                 ready: Callable[[], None] | None = None) -> Lateness:
    """Tick `session` at its rate on the monotonic clock until `duration` s of ticks (then it
    parks), `quit` (parks), an emergency stop (brakes) or the loss of the device (ends at
    once: see the module doc); Ctrl-C (KeyboardInterrupt) from the
    moment this is called parks first, then is raised again. The device is disarmed at the end
    (its drives hold). The session runs on its own time, tick k at k / rate; the clock only
    says when each tick goes (hil.timing.wait_until: sleep, then spin). A tick more than
    MAX_LAG late skips the ticks it missed (counted in SessionCounts.overruns: session time
    stays on the clock, no burst of stale setpoints). `ready` is called once, just before the
    first tick. Returns how late the ticks started (hil.timing.Lateness)."""
    late = session.lateness = Lateness(session.period)
    start = clock()

    def next_time() -> float:
        due = start + session.k * session.period
        wait_until(due, clock, lambda left: time.sleep(max(left, 0.0)))
        lag = clock() - due
        late.add(lag)
        if lag > MAX_LAG:
            session.k += int(lag * session.rate)
            session.counts.overruns += 1
        return session.k * session.period

    try:
        with gc_frozen():
            start = clock()
            if ready is not None:
                ready()
            while session.k * session.period < duration and not session.device_lost:
                if session.mode is Mode.STOPPED:
                    brake(session, next_time, park_timeout)
                    break
                if session.stopped_by == "quit" and session.parked:
                    break
                session.tick(next_time())
            if session.mode is not Mode.STOPPED and not session.device_lost:
                park(session, next_time, park_timeout)
    except KeyboardInterrupt:
        park(session, next_time, park_timeout)
        raise
    finally:
        session.device.hold()
    return late


def brake(session: LiveSession, next_time: Callable[[], float], timeout: float) -> None:
    """The emergency stop's ticks: the envelope brakes (Envelope.brake) until the platform is
    at rest, or `timeout` s of ticks."""
    for _ in range(int(math.ceil(timeout * session.rate))):
        if not np.any(session.envelope.last.qd) or session.device_lost:
            break
        session.tick(next_time())


def park(session: LiveSession, next_time: Callable[[], float], timeout: float) -> None:
    """Fade to neutral and hold (PARK), ticking until parked (or stopped) or `timeout` s of
    ticks; a second Ctrl-C during it becomes the emergency stop."""
    if session.parked or session.device_lost:
        return
    session.event(Event.PARK, next_time())
    for _ in range(int(math.ceil(timeout * session.rate))):
        if session.parked or session.device_lost:
            break
        try:
            session.tick(next_time())
        except KeyboardInterrupt:
            session.event(Event.ESTOP, session.k * session.period)
            brake(session, next_time, timeout)
            break


def make_session(scene: Scene, receiver: TelemetryReceiver, device: DeviceOut,
                 telemetry_rate: float, control: Control | None = None,
                 loss_timeout: float = LOSS_TIMEOUT, record: Record | None = None,
                 mode: str = "classical", synchronous: bool = False,
                 mpc_rate: float | None = None, observer: Latest | None = None,
                 device_timeout: float | None = None,
                 warn: Callable[[str], None] | None = None) -> LiveSession:
    """The live loop of a scene: its [cueing] washout stepped at `telemetry_rate`
    (cueing.washout_step.WashoutStepper; mode "optimal": the MPC without preview,
    live.optimal_stream.LiveOptimal, `synchronous` on a simulated clock), its envelope at the
    controller rate (live.envelope), setpoints at the controller rate (the device's). The
    MPC steps at `mpc_rate` (default: the scene's [cueing.optimal] rate, at least
    LIVE_RATE_MIN). `device_timeout` (default: the device's watchdog) and `warn` (default: a
    line on stderr): LiveSession's."""
    model, controller = scene.model, scene.require_controller()
    if mode == "optimal":
        rate = mpc_rate if mpc_rate is not None else max(scene.optimal.rate, LIVE_RATE_MIN)
        options = dataclasses.replace(scene.optimal, rate=rate)
        cue = OptimalStream(LiveOptimal(model, scene.cueing, model.home, model.gravity,
                                        controller, options, synchronous=synchronous))
    elif mode == "classical":
        h = 1.0 / telemetry_rate
        stepper = WashoutStepper(scene.cueing, model.home, model.gravity, h)
        cue = CueStream(stepper, h, np.asarray(model.home, float))
    else:
        raise CueError(f"cue-live: mode {mode!r} unknown: classical or optimal")
    envelope = Envelope(model, envelope_limits(model, controller), 1.0 / controller.rate)
    return LiveSession(model, receiver, cue, envelope, device, controller.rate, control,
                       loss_timeout, record, observer, scene.cueing.head, device_timeout, warn)


def summary_lines(session: LiveSession) -> list[str]:
    """The session's summary: ticks, modes, telemetry received and refused by kind, the
    envelope's interventions, the device's refusals, latency, the ticks' lateness."""
    late = session.lateness
    rx = session.receiver.counts
    refused = ", ".join(f"{k} {v}" for k, v in rx.refused.items() if v) or "none"
    lines = [f"cue-live ({session.cue.mode}): {session.counts.ticks} ticks at {session.rate:g} Hz "
             f"over {session.k * session.period:.3f} s, mode at the end "
             f"{session.mode.value}, {session.counts.fades} fades to neutral"
             + (f", stopped by {session.stopped_by}" if session.stopped_by else ""),
             f"telemetry: {rx.received} datagrams, {rx.accepted} accepted, "
             f"{rx.superseded} superseded by a newer one, refused: {refused}",
             session.cue.describe()]
    iv = session.envelope.interventions
    hits = ", ".join(f"{k} {v}" for k, v in iv.per_limit.items() if v) or "none"
    lines.append(f"envelope: {iv.samples} samples, {iv.limited} limited; limits hit: {hits}")
    dc = session.device.counts
    lines.append(f"device: {dc.setpoints} setpoints, {dc.states} states back, "
                 f"{len(dc.statustexts)} STATUSTEXT"
                 + (f" (last: {dc.statustexts[-1]!r})" if dc.statustexts else "")
                 + f", lost {session.counts.device_losses}"
                 + (f" (at {session.device_lost_at:.3f} s: no LEG_STATE for over "
                    f"{session.device_timeout:g} s, setpoints stopped)"
                    if session.device_lost else ""))
    lat = session.latency.summary()
    if lat["count"]:
        lines.append(f"latency (drain -> setpoint sent, {lat['count']} samples): p50 "
                     f"{lat['p50'] * 1e3:.3f} ms, p99 {lat['p99'] * 1e3:.3f} ms, "
                     f"max {lat['max'] * 1e3:.3f} ms")
    if late is not None and late.count:
        lines.append(f"ticks: {late.text()}; {session.counts.overruns} overruns")
    if session.control is not None and (session.counts.commands or session.control.unknown):
        taken = ", ".join(f"{k} {v}" for k, v in session.counts.commands.items()) or "none"
        lines.append(f"operator: {taken}; {session.control.unknown} unknown words ignored")
    return lines
