"""examples/: every Python snippet of the guides (docs/) is one of these files, verbatim, and each
runs to completion in a fresh interpreter (from another directory, bounded time)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import doc_page_with, doc_pages

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
# s per example: a guard against a hang, not a speed test; a 2-core machine with other work on
# it runs an example several times slower than a quiet one (the identification example with
# excite's trajectories: 79 s quiet, 147-280 s at load average 3 to 10)
TIMEOUT = 900


def guide_snippets() -> list[str]:
    """The ```python blocks of the getting-started page and the guides (the contract's Python
    lines are signatures, not a program)."""
    text = "".join(page for name, page in doc_pages().items()
                   if name.startswith("guides/") or name == "getting-started.md")
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_every_guide_snippet_is_an_example():
    examples = {p.read_text(encoding="utf-8") for p in EXAMPLES}
    snippets = guide_snippets()
    assert snippets, "the guides have no ```python blocks"
    for snippet in snippets:
        assert snippet in examples, f"a guide's snippet is not an examples/ file:\n{snippet[:300]}"


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


def docs_printed(example: str) -> list[str]:
    """The lines the docs page holding `example`'s code says it printed: the `- ` items of the
    "It printed" list that follows the snippet of examples/<example>, each a line of its output
    in backquotes."""
    code = (ROOT / "examples" / example).read_text(encoding="utf-8")
    _, text = doc_page_with(code)
    after = text[text.index(code) + len(code):]
    block = after[after.index("It printed"):].split("\n\n")[0]
    return re.findall(r"^- `(.*)`$", block, flags=re.M)


@pytest.mark.numerics
def test_the_identification_example_prints_the_documented_figures(tmp_path):
    """Every line the identification guide states for examples/identify_machine.py was
    printed, word for word and figure for figure (the identified frictions and drive masses
    against the truth, the held-out error): its trajectories are the same files in every
    floating-point environment, and its figures, printed to two or three digits, the same in
    each one tried."""
    stated = docs_printed("identify_machine.py")
    assert len(stated) >= 4, stated
    proc = run_example(ROOT / "examples" / "identify_machine.py", tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    printed = {line.strip() for line in proc.stdout.splitlines()}
    for line in stated:
        assert line in printed, f"the guide says the example printed {line!r}; it printed:\n" \
                                f"{proc.stdout}"


def _env() -> dict:
    import os
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    env.setdefault("MPLBACKEND", "Agg")
    return env
