"""PI's GCS 2.0 over TCP in front of the one emulated device (`stewart-sim device --gcs`, alone
or beside its MAVLink link).

A lab script written for a PI hexapod (PIPython's `GCSDevice` over a TCP socket) drives the
twin: axes X Y Z (mm) and U V W (deg) as PI's hexapods define them (hil.gcs.axes states the map
onto the contract's pose), referencing, absolute and relative moves, on-target and motion
status, stop and halt, the system velocity, the travel range, the pivot point, work and tool
coordinate systems, the workspace queries VMO? and TRA? (the feasibility engine,
stewart_fmu.reach), the data recorder and the few read-only parameters PIPython's data recorder
tools read, each with PI's syntax, answers and error codes (docs/guides/gcs-twin.md: what
differs from a real controller). Nothing here simulates: every move becomes the device's own
input (LEG_SETPOINT, arm, home through `Device.receive`), so its modes, bounds, watchdog and
faults apply as they do to a MAVLink host.

Modules: errors (PI's codes), axes (the pose map), parser (GCS lines and answers), move_path (a
move as setpoints, and the check of its path), travel_query (TRA? on the engine's travel),
coordinate_systems (KSW/KST/KLN/KEN/KRM/KET?/KLT?), recorder (DRC/DRT/RTR/DRR?), controller
(the controller's state and its per-tick step), command_set (the command table), server (the
TCP line server), tcp_transport (the server as hil.serve's transport).
"""
