"""The Dask client a study runs on: a running scheduler (`scheduler` = "tcp://HOST:PORT") or a
new LocalCluster of worker processes (one thread each) on this machine, closed with the client.
Shared by the design sweep (stewart_sim/studies/sweep/dask_run.py) and the actuator sizing's
catalogue sweep (stewart_sim/studies/sizing/study.py)."""
from __future__ import annotations

import logging
import math
import os

from stewart_fmu.errors import SweepError
from stewart_sim.shell.interrupt import signals_held

CONNECT_TIMEOUT = 30.0   # s to reach a scheduler or start the local cluster

# The local cluster's Dask settings. A study keeps a few tasks per worker in flight itself (the
# sweep's sized tasks): the scheduler sends them on at once (no queue of its own, whose round
# trip would leave a worker idle between tasks). The rest is Dask's own periodic work, which
# takes cores from the workers on a small machine (an idle 2-worker cluster took 15 % of a core
# with Dask's defaults, 6 % with the first three below, measured): each worker's statistical
# profiler (a look at its threads' stacks every 10 ms; the dashboard's profile page stays
# empty), and the system and memory monitors every 2 s and 1 s instead of 0.5 s and 0.1 s (a
# worker past its memory limit is still stopped, up to 1 s later). Each event loop's watchdog
# ticks every second instead of every 20 ms: a worker's tick takes the GIL from the task it
# runs (evaluation 2-3 % slower at 20 ms, measured), and a blocked loop is still reported.
# The workers' environment is Dask's without MALLOC_TRIM_THRESHOLD_ (None: not set): setting it
# at all turns off glibc's adaptive mmap threshold, and a closed-loop point then took 69-71 ms
# instead of 63-65 ms (measured in one process with and without it); one BLAS thread per worker
# process as Dask has it.
LOCAL_CLUSTER = {
    "distributed.scheduler.worker-saturation": math.inf,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.tick.interval": "1s",
    "distributed.nanny.pre-spawn-environ": {"MALLOC_TRIM_THRESHOLD_": None, "OMP_NUM_THREADS": 1,
                                            "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
}


# Only for the workers a command starts itself: a `dask worker` started by hand keeps Ctrl-C.
WORKER_PRELOAD = {"distributed.worker.preload": ["stewart_sim.studies.sweep.worker_signals"]}


def dask_environment() -> dict[str, str]:
    """LOCAL_CLUSTER as DASK_* environment variables, for a scheduler and workers started by
    hand (`dask scheduler`, `dask worker`): the same settings on a cluster of one's own."""
    return {"DASK_" + key.upper().replace(".", "__").replace("-", "_"): _env_text(value)
            for key, value in LOCAL_CLUSTER.items()}


def _env_text(value) -> str:
    """A setting as Dask reads it from a variable (a Python literal; a table with its keys in
    double quotes, which a shell's single quotes keep as they are)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f'"{k}": {v!r}' for k, v in value.items()) + "}"
    return str(value)


def dask_client(scheduler: str | None, workers: int | None):
    """A dask.distributed Client on the scheduler, or on a new local cluster of `workers`
    processes (default: one per core); use it as a context manager (`with dask_client(...) as
    client`), which closes a local cluster with it. An unreachable scheduler is a SweepError."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as exc:
            raise SweepError(None, f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    import dask

    n = workers or os.cpu_count() or 1
    # A stop signal waits for the start-up to end (seconds): cut in two, LocalCluster leaves
    # workers that Dask's exit handler fails to close, with a traceback. Whole, the cluster is
    # closed here and the interrupt goes on. A terminal's Ctrl-C also reaches the workers (one
    # process group), so a start-up that fails after one came is that interrupt.
    with signals_held() as held, dask.config.set(LOCAL_CLUSTER), dask.config.set(WORKER_PRELOAD):
        try:
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=":0",
                                   silence_logs=logging.CRITICAL)
            owned = OwnedClient(Client(cluster, timeout=CONNECT_TIMEOUT), cluster)
        except Exception:
            if not held:
                raise
            owned = None
    if held:
        if owned is not None:
            owned.__exit__(None, None, None)
        raise KeyboardInterrupt
    return owned


class OwnedClient:
    """A client that closes its local cluster with it (context manager)."""

    def __init__(self, client, cluster):
        self.client, self.cluster = client, cluster

    def __enter__(self):
        return self.client

    def __exit__(self, *exc) -> None:
        self.client.close()
        self.cluster.close()


def main() -> None:
    """`python -m stewart_sim.studies.sweep.cluster`: dask_environment as shell `export` lines, for
    `eval "$(...)"` before starting `dask scheduler` and `dask worker` by hand."""
    import shlex

    for name, value in dask_environment().items():
        print(f"export {name}={shlex.quote(value)}")


if __name__ == "__main__":
    main()
