"""examples/: every Python snippet of README.md is one of these files, verbatim, and each runs
to completion in a fresh interpreter (from another directory, bounded time)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
TIMEOUT = 120  # s per example


def readme_snippets() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_every_readme_snippet_is_an_example():
    examples = {p.read_text(encoding="utf-8") for p in EXAMPLES}
    snippets = readme_snippets()
    assert snippets, "README.md has no ```python blocks"
    for snippet in snippets:
        assert snippet in examples, f"README snippet is not an examples/ file:\n{snippet[:300]}"


_OUTPUTS: dict[Path, subprocess.CompletedProcess] = {}


def run_example(example: Path, cwd: Path) -> subprocess.CompletedProcess:
    """The example run once per session (test_example_runs and the figure checks share it)."""
    if example not in _OUTPUTS:
        _OUTPUTS[example] = subprocess.run([sys.executable, str(example)], cwd=cwd,
                                           capture_output=True, text=True, timeout=TIMEOUT,
                                           env=_env())
    return _OUTPUTS[example]


@pytest.mark.parametrize("example", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(example, tmp_path):
    proc = run_example(example, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip()


def readme_printed(example: str) -> list[str]:
    """The lines README.md says `example` printed: the `- ` items of the "It printed:" list
    that follows the snippet of examples/<example>, each one a line of its output."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = (ROOT / "examples" / example).read_text(encoding="utf-8")
    after = text[text.index(code) + len(code):]
    block = after[after.index("It printed"):].split("\n\n")[0]
    return [m.strip().rstrip(";.") for m in re.findall(r"^- `(.*)`", block, flags=re.M)]


@pytest.mark.numerics
def test_the_identification_example_prints_the_readme_figures(tmp_path):
    """Every figure README.md states for examples/identify_machine.py is a line it printed
    (the identified frictions and drive masses against the truth, the held-out error)."""
    stated = readme_printed("identify_machine.py")
    assert len(stated) >= 4, stated
    proc = run_example(ROOT / "examples" / "identify_machine.py", tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    printed = {line.strip() for line in proc.stdout.splitlines()}
    for line in stated:
        assert line in printed, f"README says the example printed {line!r}; it printed:\n" \
                                f"{proc.stdout}"


def _env() -> dict:
    import os
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    env.setdefault("MPLBACKEND", "Agg")
    return env
