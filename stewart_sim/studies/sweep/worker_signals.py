"""Dask preload of the local cluster's worker processes (stewart_sim/studies/sweep/cluster.py):
a worker ignores SIGINT. A terminal's Ctrl-C goes to the whole process group, the workers
included; the command (their parent) closes them in order, and a worker that took the signal
itself died printing a KeyboardInterrupt traceback of its own. A worker still importing
Dask when the signal comes (the first seconds of a start-up) has no preload yet and can die:
the command then reports the interrupt, as cluster.dask_client does."""
from __future__ import annotations

import signal
import threading


def dask_setup(worker) -> None:
    """Called by Dask in each worker process as it starts (its main thread runs the worker)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
