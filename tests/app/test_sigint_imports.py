"""Ctrl-C while a module is being imported: exit 130 and the one line, as anywhere else.

A real SIGINT is raised (signal.raise_signal) from inside the import system at a chosen point,
in a child process running the command line, so the moment is exact: no timing. Each point is
one where a KeyboardInterrupt raised on the spot did damage before stewart_sim/shell/interrupt.py
held it back until the import returned and cli.main installed it first: the parser's import
ended in a traceback, numpy turned it into an ImportError traceback,
matplotlib's ft2font was left half initialised ("Fatal Python error" and an abort at exit), and
one escaping an exec of source text (a dataclass) made Python end the process by SIGINT
instead of our exit status 130.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MICRO = ROOT / "scenes" / "micro_manipulator.toml"

# The child: arm the trigger, then run `stewart-sim ARGS`. A meta-path finder sees each import
# start; `when` says at which one (and, for a trace trigger, at which call inside it) SIGINT
# is raised, once.
CHILD = r'''
import signal, sys

point = sys.argv[1]
fired = []


def fire():
    if not fired:
        fired.append(point)
        signal.raise_signal(signal.SIGINT)


def in_ft2font_init(frame, event, arg):
    # Python code called by the C initialisation of matplotlib.ft2font (its enums)
    if event == "call" and frame.f_back is not None \
            and frame.f_back.f_code.co_name == "_call_with_frames_removed":
        sys.settrace(None)
        fire()


def in_exec_of_text(frame, event, arg):
    # the source text a dataclass compiles for its methods
    if event == "call" and frame.f_code.co_filename == "<string>" \
            and frame.f_code.co_name == "<module>":
        sys.settrace(None)
        fire()


class Trigger:
    def find_spec(self, name, path=None, target=None):
        if fired:
            return None
        if point == "numpy-c-init" and name == "numpy.exceptions":   # asked by numpy's C init
            fire()
        elif point == "parser" and name == "importlib.metadata":     # --version's, at start
            fire()
        elif point == "ft2font-c-init" and name == "matplotlib.ft2font":
            sys.settrace(in_ft2font_init)
        elif point == "dataclass-exec" and name == "stewart_sim.studies.paper":
            sys.settrace(in_exec_of_text)
        return None


sys.meta_path.insert(0, Trigger())
from stewart_sim.cli import main
status = main(sys.argv[2:])
assert fired, "the trigger never fired"
sys.exit(status)
'''


@pytest.mark.parametrize("point", ["parser", "numpy-c-init", "ft2font-c-init", "dataclass-exec"])
def test_sigint_inside_an_import_exits_130_with_one_line(point, tmp_path) -> None:
    """SIGINT at `point` of `paper`'s imports: status 130 (not an abort, not killed by
    SIGINT), stderr exactly the one line saying what was kept, the earlier set untouched."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.md").write_text("# earlier\n")
    # run as `python -m` (as `python -m stewart_sim`): there Python itself ends the process by
    # SIGINT, after our exit status was chosen, if a KeyboardInterrupt ever escaped an exec
    (tmp_path / "sigint_child.py").write_text(CHILD)
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": os.pathsep.join(
        filter(None, [str(ROOT), str(tmp_path), os.environ.get("PYTHONPATH", "")]))}
    proc = subprocess.run([sys.executable, "-m", "sigint_child", point, "paper", str(MICRO),
                           "--out", str(out)], capture_output=True, text=True, env=env,
                          timeout=600)
    assert proc.returncode == 130, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("stewart-sim: error: interrupted: nothing new written")
    assert {p.name: p.read_text() for p in out.iterdir()} == {"summary.md": "# earlier\n"}
    assert list(tmp_path.glob(".out.partial-*")) == []
