"""PI's own client, PIPython from the registry and unmodified, drives the twin over GCS 2.0:
through `stewart-sim device --gcs` (the device in its own process, as a controller on the
network would be) and in process (to hold the data recorder against the device's own record).
Its calls are the ones lab scripts make: connect, qIDN, FRF and pitools.waitonreferencing, MOV,
pitools.waitontarget, qPOS, MVR, STP, the errors it raises (its own ERR? after every command),
the data recorder with qDRR's background read. Waits are PIPython's own, with bounded timeouts;
the assertions are on values, never on how long anything took."""
from __future__ import annotations

import contextlib
import gc
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pymavlink")
pipython = pytest.importorskip("pipython")
from pipython import GCSDevice, GCSError, datarectools, pitools  # noqa: E402
from pipython.pidevice.interfaces.pisocket import PISocket  # noqa: E402

from hil.device import Device  # noqa: E402
from hil.gcs.controller import ONT_TOLERANCE  # noqa: E402
from hil.gcs.tcp_transport import gcs_link  # noqa: E402
from hil.serve import serve_in_thread  # noqa: E402
from hil.spawn import device_process, parse_gcs  # noqa: E402
from stewart_fmu.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "micro_manipulator.toml"
WAIT = 60          # s: PIPython's own wait timeouts (a bound, not a measurement)
AXES = ["X", "Y", "Z", "U", "V", "W"]

# PIPython closes its socket in __exit__ and again in __del__, where the second close raises
# (EBADF) and Python reports it as unraisable: PIPython's, not the twin's. Each test collects
# its client (`release`) so that this happens, and is ignored, within the test.
unraisable = pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")


def release() -> None:
    gc.collect()


def connect(port: int) -> GCSDevice:
    pi = GCSDevice(gateway=PISocket(autoconnect=False))
    pi.ConnectTCPIP("127.0.0.1", port)
    return pi


@contextlib.contextmanager
def twin_in_process(device: Device):
    """The device served in a thread behind a GCS server on a free loopback port (yielded),
    stopped and closed on the way out."""
    link = gcs_link(device, "127.0.0.1", 0)
    thread, stop, _ = serve_in_thread(device, link)
    try:
        yield link.server.address[1]
    finally:
        stop.set()
        thread.join(10)
        link.close()


def wait_data(pi: GCSDevice) -> np.ndarray:
    deadline = time.monotonic() + WAIT
    while pi.bufstate is not True:
        assert time.monotonic() < deadline, "qDRR's data never came"
        time.sleep(0.02)
    return np.array(pi.bufdata)


@unraisable
def test_a_lab_script_over_the_device_command():
    with device_process(SCENE, "gcs") as first:
        host, port = parse_gcs(first)
        with connect(port) as pi:
            assert type(pi.gcsdevice).__name__ == "GCS2Device"
            assert pi.devname == "STEWART-SIM-TWIN" and pi.qIDN().startswith("stewart-sim")
            assert pi.axes == AXES and pi.qCST()["X"] == "STEWART-SIM-TWIN"
            assert not any(pi.qFRF().values()) and not any(pi.qSVO().values())
            # a move before referencing: PI's error 5, raised by PIPython's own ERR?
            with pytest.raises(GCSError) as exc:
                pi.MOV("X", 1.0)
            assert exc.value.val == 5
            pi.FRF()
            pitools.waitonreferencing(pi, timeout=WAIT, polldelay=0.05)
            assert all(pi.qFRF().values()) and all(pi.qSVO().values())
            pos = pi.qPOS()
            assert all(abs(pos[a]) <= ONT_TOLERANCE for a in AXES)

            target = {"X": 2.0, "Y": -1.5, "Z": 1.0, "U": 0.5, "V": -0.25, "W": 1.0}
            pi.MOV(target)
            assert pi.IsMoving()["X"]
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            pos = pi.qPOS()
            assert all(abs(pos[a] - target[a]) <= ONT_TOLERANCE for a in AXES)
            assert pi.qMOV() == target and not any(pi.IsMoving().values())

            pi.MVR("Z", -0.5)
            pitools.waitontarget(pi, "Z", timeout=WAIT, polldelay=0.05)
            assert abs(pi.qPOS("Z")["Z"] - 0.5) <= ONT_TOLERANCE
            assert pi.qMOV("Z")["Z"] == 0.5

            # refused: beyond the travel range (7), an unknown axis (15); nothing moves
            high = pi.qPLM("X")["X"]
            for args, code in ((("X", high + 1.0), 7), (("Q", 1.0), 15)):
                with pytest.raises(GCSError) as exc:
                    pi.MOV(*args)
                assert exc.value.val == code
            assert pi.qMOV() == {**target, "Z": 0.5} and pi.qERR() == 0
            assert pi.qNLM("X")["X"] < 0 < high

            # stop mid-move: error 10 as PI raises it; the platform holds where it braked
            pi.VLS(20.0)
            assert pi.qVLS() == 20.0
            pi.MOV("Z", 20.0)
            deadline = time.monotonic() + WAIT
            while pi.qPOS("Z")["Z"] < 2.0:
                assert time.monotonic() < deadline, "the move never got under way"
                time.sleep(0.01)
            with pytest.raises(GCSError) as exc:
                pi.STP()
            assert exc.value.val == 10
            held = pi.qMOV("Z")["Z"]
            assert 2.0 < held < 20.0
            pitools.waitontarget(pi, "Z", timeout=WAIT, polldelay=0.05)
            assert abs(pi.qPOS("Z")["Z"] - held) <= ONT_TOLERANCE
            pi.StopAll(noraise=True)

            # the recorder: actual X, leg 1 length, rack force 1, time; started by the MOV
            pi.DRC([1, 2, 3, 4], ["X", "1", "1", "X"], [2, 2, 100, 8])
            pi.DRT(0, 1)
            pi.RTR(5)
            pi.MOV("X", 0.0)
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            n = pi.qDRL(1)[1]
            assert n > 20
            header = pi.qDRR([1, 2, 3, 4], 1, n)
            data = wait_data(pi)
            assert header["NDATA"] == n and header["SAMPLE_TIME"] == 0.005
            assert data.shape == (4, n)
            x, leg, force, t = data
            assert x[0] == pytest.approx(2.0, abs=0.01) and abs(x[-1]) < 0.01
            assert np.allclose(np.diff(t), 0.005)
            assert np.all((leg > 75) & (leg < 185)) and np.all(np.abs(force) < 160)
            assert pi.qERR() == 0
        del pi
        release()


@unraisable
def test_hostile_lines_against_the_device_command_then_a_clean_script():
    """Seeded hostile lines (tests/hil/test_gcs.py's generator: binary, unknown commands,
    absurd numbers, overlong lines, control bytes) from a raw socket to `device --gcs`, then
    PIPython: the twin still answers, unreferenced, at its home, and refuses a move with 5."""
    import random
    import socket

    from tests.hil.test_gcs import _hostile_lines

    rng = random.Random(3805)
    lines = _hostile_lines(rng, 2000) + [b"MOV X " + b"9" * 5000, b"\x05\x07\x18"]
    with device_process(SCENE, "gcs") as first:
        host, port = parse_gcs(first)
        with socket.create_connection((host, port), timeout=10) as raw:
            raw.sendall(b"\n".join(lines) + b"\nERR?\n*IDN?\n")
            got = b""
            deadline = time.monotonic() + WAIT
            while b"stewart-sim" not in got:
                assert time.monotonic() < deadline, "the twin stopped answering"
                got += raw.recv(1 << 16)
        with connect(port) as pi:
            assert pi.qERR() == 0 and not any(pi.qFRF().values())
            assert all(abs(v) < 1e-9 for v in pi.qPOS().values())
            with pytest.raises(GCSError) as exc:
                pi.MOV("Z", 1.0)
            assert exc.value.val == 5
        del pi
        release()


class Keep:
    def __init__(self) -> None:
        self.by_tick = {}

    def publish(self, snap) -> None:
        self.by_tick[snap.tick] = snap


@unraisable
def test_recorded_table_equals_the_devices_own_record_and_pipythons_datarecorder_runs():
    model = load_scene(SCENE)
    device = Device(model)
    keep = Keep()
    device.observe(keep, hz=device.rate)
    with twin_in_process(device) as port:
        with connect(port) as pi:
            # PIPython's samples start a controller so: stop all, servo, reference, wait
            pitools.startup(pi, refmodes="FRF")
            assert all(pi.qFRF().values())
            assert pitools.getmaxtravelrange(pi, "Y")["Y"] == pi.qPLM("Y")["Y"]
            pi.DRC([1, 2, 3, 4], ["Y", "3", "6", "Y"], [2, 2, 100, 8])
            pi.DRT(0, 1)                       # the next command that moves starts it
            pitools.moveandwait(pi, "Y", -1.0, timeout=WAIT)
            n = pi.qDRL(1)[1]
            pi.qDRR([1, 2, 3, 4], 1, n)
            y, leg3, force6, t = wait_data(pi)
            # PIPython's own Datarecorder (its samples' way): servo time and table size from
            # SPA?/HPA? and HDR?, sample rate by RTR, armed by DRC/DRT, read by DRR?
            # `with`: PIPython keeps every Datarecorder's callback in a class-wide list until
            # it exits, and calls it when any later PISocket connects
            with datarectools.Datarecorder(pi) as drec:
                assert drec.servotime == 1.0 / device.rate and drec.maxnumvalues == 16384
                drec.numvalues, drec.samplefreq = 400, 200
                drec.options = (datarectools.RecordOptions.ACTUAL_POSITION_2,
                                datarectools.RecordOptions.COMMANDED_POSITION_1)
                drec.sources = ("Z", "Z")
                drec.trigsources = datarectools.TriggerSources.POSITION_CHANGING_COMMAND_1
                drec.arm()
                pi.MOV("Z", 0.5)
                header, (z_actual, z_commanded) = drec.getdata(timeout=WAIT)
                assert header["NDATA"] == 400 and header["SAMPLE_TIME"] == 0.005
                assert z_commanded[0] == pytest.approx(0.0, abs=1e-3) and z_commanded[-1] == 0.5
                assert abs(z_actual[-1] - 0.5) <= ONT_TOLERANCE
                assert np.all(np.diff(z_commanded) >= 0)       # the quintic only rises
            assert pi.qERR() == 0
        del pi
        release()
    assert n > 100
    for k in range(n):
        snap = keep.by_tick[round(t[k] * device.rate)]
        assert y[k] == (snap.q[1] - model.home[1]) * 1e3
        assert leg3[k] == snap.lengths[2] * 1e3
        assert force6[k] == snap.forces[5]
    assert y[-1] == pytest.approx(-1.0, abs=ONT_TOLERANCE)


@unraisable
def test_pivot_rotation_vmo_and_tra_through_pipython(capsys):
    """PIPython's qSPI/SPI, qVMO and qTRA against the twin in process (so the plant's own pose
    can be read): the platform turns about the pivot set, VMO? answers what MOV then does, and
    TRA? ends where `stewart-sim workspace --reach` does from home."""
    from scipy.spatial.transform import Rotation

    from tests.hil.test_gcs import _reach_step

    model = load_scene(SCENE)
    device = Device(model)
    with twin_in_process(device) as port:
        with connect(port) as pi:
            # TRA? before referencing, from the plant at home (it starts there; at rest it
            # drifts by rounding only, orders of magnitude below the bisection's 1e-9)
            assert np.all(np.abs(np.asarray(device.snapshot().q) - model.home) <= 1e-15)
            x_end = pi.qTRA("X", 1.0)["X"]
            step = _reach_step(capsys, SCENE, [1.0, 0, 0, 0, 0, 0])
            assert abs(x_end - step * 1e3) <= 2e-9 * 1e3
            pitools.startup(pi, refmodes="FRF")
            assert pi.qSPI() == {"R": 0.0, "S": 0.0, "T": 0.0}
            pi.SPI({"R": 2.0, "T": 12.0})
            assert pi.qSPI() == {"R": 2.0, "S": 0.0, "T": 12.0}
            turn = {"U": 1.5, "V": -2.0, "W": 2.5}
            assert pi.qVMO(turn) is True
            pi.MOV(turn)
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            q = np.asarray(device.snapshot().q)
            p = np.array([2.0, 0.0, 12.0]) / 1e3
            pivot_n = q[:3] + Rotation.from_euler("xyz", q[3:]).as_matrix() @ p
            assert np.all(np.abs(pivot_n - (model.home[:3] + p)) <= ONT_TOLERANCE / 1e3)
            with pytest.raises(GCSError) as exc:        # rotated: PI's error 9
                pi.SPI("T", 0.0)
            assert exc.value.val == 9
            # a target inside each axis's range but not together: VMO? False, MOV refused (7)
            high = pi.qPLM()
            target = {"X": 0.9 * high["X"], "Z": 0.9 * high["Z"], "U": 0.0, "V": 0.0, "W": 0.0}
            assert pi.qVMO(target) is False
            with pytest.raises(GCSError) as exc:
                pi.MOV(target)
            assert exc.value.val == 7
            assert pi.qMOV() == {"X": 0.0, "Y": 0.0, "Z": 0.0, **turn}
            # TRA? from the turned pose: the end is on the line, beyond where the platform is
            end = pi.qTRA({"W": 1.0})["W"]
            assert turn["W"] < end < 180.0
            assert pi.qERR() == 0
        del pi
        release()


@unraisable
def test_coordinate_systems_through_pipython():
    """PIPython's KSW, KST, KEN, qKET, qKLT, KRM: with a work system (5 mm along X, turned 30 deg
    about Z) and a tool 10 mm above C enabled, MOV moves the tool in the work system's axes,
    checked on the plant's own pose."""
    from scipy.spatial.transform import Rotation

    model = load_scene(SCENE)
    device = Device(model)
    with twin_in_process(device) as port:
        with connect(port) as pi:
            pitools.startup(pi, refmodes="FRF")
            pi.KSW("WORK", {"X": 5.0, "W": 30.0})
            pi.KST("TIP", {"Z": 10.0})
            pi.KEN("WORK")
            pi.KEN("TIP")
            assert pi.qKET() == {"KSW": "WORK", "KST": "TIP"}
            assert pi.qKLT("TIP").split() == ["X=0.0", "Y=0.0", "Z=10.0", "U=0.0", "V=0.0",
                                              "W=0.0"]
            target = {"X": 1.0, "Y": 0.0, "Z": 10.0, "U": 0.0, "V": 0.0, "W": -30.0}
            pi.MOV(target)
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            q = np.asarray(device.snapshot().q)
            r = Rotation.from_euler("xyz", q[3:])
            tip = q[:3] + r.apply([0.0, 0.0, 0.01]) - model.home[:3]
            w = Rotation.from_euler("z", 30, degrees=True)
            expected = (np.array([5.0, 0.0, 0.0]) + w.apply([1.0, 0.0, 10.0])) / 1e3
            # on target is per axis of the enabled work system (X, Y turned 30 deg about Z), so
            # the tip's error is read along those axes, not along N's
            assert np.all(np.abs(w.inv().apply(tip - expected)) <= ONT_TOLERANCE / 1e3)
            # the tool's axes: the work system's turned back by W = -30 deg, i.e. the platform's
            assert np.degrees(np.linalg.norm(r.as_rotvec())) <= 2 * ONT_TOLERANCE
            with pytest.raises(GCSError) as exc:        # enabled: in use
                pi.KRM("WORK")
            assert exc.value.val == 532
            pi.MOV({"X": 1.0, "Y": 0.0, "Z": 0.0, "W": 0.0})     # off a turned work frame
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            pi.KEN("ZERO")
            assert pi.qKET() == {"ZERO": "ZERO"}
            pi.KRM("WORK")
            pi.KRM("TIP")
            assert pi.qERR() == 0
        del pi
        release()


@unraisable
def test_directed_coordinate_system_through_pipython():
    """PIPython's KSD, KEN, qKET, qKLT: a directed system 10 mm above C turned 30 deg about Z
    reads 0 at ZERO; MOV X 1 moves that point 1 mm along its own X, checked on the plant's pose."""
    from scipy.spatial.transform import Rotation

    model = load_scene(SCENE)
    device = Device(model)
    with twin_in_process(device) as port:
        with connect(port) as pi:
            pitools.startup(pi, refmodes="FRF")
            pi.KSD("D", {"Z": 10.0, "W": 30.0})
            pi.KEN("D")
            assert pi.qKET() == {"KSD": "D"}
            assert pi.qKEN() == {"D": "KSD"}
            klt = dict(row.split("=") for row in pi.qKLT("D").split())
            assert list(klt) == AXES
            assert np.allclose([float(v) for v in klt.values()], [0, 0, 10, 0, 0, 30],
                               rtol=0.0, atol=1e-12)
            assert all(abs(v) <= 1e-9 for v in pi.qPOS(AXES).values())
            pi.MOV({"X": 1.0})
            pitools.waitontarget(pi, timeout=WAIT, polldelay=0.05)
            q = np.asarray(device.snapshot().q)
            r = Rotation.from_euler("xyz", q[3:])
            point = q[:3] + r.apply([0.0, 0.0, 0.01]) - model.home[:3] - [0.0, 0.0, 0.01]
            expected = Rotation.from_euler("z", 30, degrees=True).apply([1.0, 0.0, 0.0]) / 1e3
            assert np.all(np.abs(point - expected) <= ONT_TOLERANCE / 1e3)
            assert np.degrees(np.linalg.norm(r.as_rotvec())) <= 2 * ONT_TOLERANCE
            pi.KEN("ZERO")
            assert pi.qKEN() == {}
            pi.KRM("D")
            assert pi.qERR() == 0
        del pi
        release()
