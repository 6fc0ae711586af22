"""Run MAVProxy speaking our dialect: `python mavproxy_stewart.py [mavproxy options]`.

MAVProxy's --dialect NAME imports ``pymavlink.dialects.v20.NAME``; our generated module
``hil.mavlink_stewart`` is registered under that name (``stewart``) before mavutil is imported,
so MAVProxy decodes LEG_STATE, DRIVE_STATUS... like any common message (a common-only ground
station sees them as unknown, and pymavlink leaves unknown frames out of its sequence count,
which it then reports as loss). MAVLink 2 only (MAVLINK20=1).
"""
import os
import runpy
import sys

import pymavlink.dialects.v20 as v20

from hil import mavlink_stewart

sys.modules["pymavlink.dialects.v20.stewart"] = mavlink_stewart
v20.stewart = mavlink_stewart
os.environ["MAVLINK20"] = "1"
os.environ["MAVLINK_DIALECT"] = "stewart"
sys.argv = ["mavproxy.py", "--dialect=stewart"] + sys.argv[1:]
runpy.run_module("MAVProxy.mavproxy", run_name="__main__", alter_sys=True)
