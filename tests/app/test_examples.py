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


@pytest.mark.parametrize("example", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(example, tmp_path):
    proc = subprocess.run([sys.executable, str(example)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=TIMEOUT, env=_env())
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip()


def _env() -> dict:
    import os
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    env.setdefault("MPLBACKEND", "Agg")
    return env
