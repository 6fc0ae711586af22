"""A PIPython script for a PI hexapod, run against the GCS twin (docs/guides/gcs-twin.md).

The twin is started here as `stewart-sim device SCENE --gcs 127.0.0.1:0` would start it (its
first line says the port); with one already running, connect to its port instead.
"""
import time
from pathlib import Path

from pipython import GCSDevice, pitools
from pipython.pidevice.interfaces.pisocket import PISocket

from hil.spawn import device_process, parse_gcs

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "micro_manipulator.toml"

with device_process(SCENE, "gcs") as first:       # "gcs 127.0.0.1:PORT"
    host, port = parse_gcs(first)
    # PIPython's own socket gateway: GCSDevice().ConnectTCPIP alone would load PI's GCS library.
    # No `with`: PIPython closes the socket when the object goes, and its __exit__ would close
    # it a second time, which raises in PIPython's __del__.
    pi = GCSDevice(gateway=PISocket(autoconnect=False))
    pi.ConnectTCPIP(host, port)
    print(pi.qIDN().strip())
    pitools.startup(pi, refmodes="FRF")        # stop all, servo on, reference, wait
    pi.MOV({"X": 2.0, "Y": -1.5, "Z": 1.0, "U": 0.5, "V": -0.25, "W": 1.0})   # mm, deg
    pitools.waitontarget(pi)
    print("POS?", {axis: round(value, 4) for axis, value in pi.qPOS().items()})
    pi.MVR("Z", -0.5)
    pitools.waitontarget(pi, "Z")

    # the pivot 12 mm above C's origin (PI sets it only while U V W are 0), then a turn about it
    pitools.moveandwait(pi, {"U": 0.0, "V": 0.0, "W": 0.0})
    pi.SPI({"R": 0.0, "S": 0.0, "T": 12.0})
    print("SPI?", dict(pi.qSPI()))
    print("VMO?", pi.qVMO({"U": 2.0, "V": -1.0}), pi.qVMO({"X": 80.0, "Z": 55.0}))
    print("TRA? W", round(pi.qTRA({"W": 1.0})["W"], 3), "deg at the first limit")
    pitools.moveandwait(pi, {"U": 2.0, "V": -1.0})
    print("POS?", {axis: round(value, 4) for axis, value in pi.qPOS().items()})

    # the data recorder: X, leg 1's length and rack force, the time; every 5th servo tick
    pi.DRC([1, 2, 3, 4], ["X", "1", "1", "X"], [2, 2, 100, 8])
    pi.DRT(0, 1)                               # start with the next command that moves
    pi.RTR(5)
    pitools.moveandwait(pi, "X", 0.0)
    n = pi.qDRL(1)[1]
    header = pi.qDRR([1, 2, 3, 4], 1, n)       # the data arrive in PIPython's own thread
    while pi.bufstate is not True:             # PIPython raises on its own timeout
        time.sleep(0.05)
    x_mm, leg1_mm, force1_n, t_s = pi.bufdata
    print(f"recorded {header['NDATA']} points every {header['SAMPLE_TIME']} s: X from "
          f"{x_mm[0]:.3f} to {x_mm[-1]:.3f} mm, leg 1 {min(leg1_mm):.3f} to "
          f"{max(leg1_mm):.3f} mm, its rack force within {max(map(abs, force1_n)):.3f} N")
