"""Kinematic calibration (`calibrate`): study.py (the estimate from poses and leg lengths,
observability, pose selection; data) + report.py (its files)."""
