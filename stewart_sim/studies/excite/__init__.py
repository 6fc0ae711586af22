"""Excitation trajectories for identification (`stewart-sim excite`): fourier.py (the
trajectory), bounds.py (the limits it must keep), design.py (the optimisation), report.py (the
files and the printed summary)."""
