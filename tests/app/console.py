"""The console script `stewart-sim` as a child process, for the tests that signal it mid-run
(test_cli_edges.py: SIGINT, test_io_rules.py: SIGTERM and SIGHUP)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[2]
EXE = Path(sys.executable).parent / "stewart-sim"
WAIT = 120.0           # a bound on waiting for a command: a hang fails, no speed is judged


def console_env() -> dict[str, str]:
    """The environment in which the console script imports the packages of this tree
    (PYTHONPATH before the editable install's finder), as the in-process tests do."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        filter(None, [str(ROOT), os.environ.get("PYTHONPATH", "")]))}


def partials(out: Path) -> list[Path]:
    """The temporary directories of a result set being written into `out`."""
    return sorted(out.parent.glob(f".{out.name}.partial-*"))


def signal_when_ready(args: list[str], out: Path, ready: Callable[[Path], bool],
                      sig: int = signal.SIGINT) -> tuple[int, str]:
    """Run `stewart-sim ARGS`, send `sig` once ready(the first partial directory) holds, and
    return (status, stderr)."""
    proc = subprocess.Popen([str(EXE), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=console_env())
    try:
        deadline = time.monotonic() + WAIT
        while True:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the command never got going"
            parts = partials(out)
            if parts and ready(parts[0]):
                break
            time.sleep(0.01)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=WAIT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=WAIT)
    return proc.returncode, err
