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
TIMEOUT = 120  # s per example


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


# A number of a printed line: not a digit of a name such as run2.csv.
NUMBER = r"(?<![\w.])\d+(?:\.\d+)?(?:e[-+]?\d+)?(?!\w)"


def docs_printed(example: str) -> list[tuple[str, list[tuple[float, float]]]]:
    """The lines the docs page holding `example`'s code says it printed, each with the range of
    each of its numbers over the floating-point environments tried: the `- ` items of the "It
    printed" list that follows the snippet of examples/<example>, a line of its output in
    backquotes, then "— over the kernels tried: LO to HI, ..." (a number without a range:
    exactly as written)."""
    code = (ROOT / "examples" / example).read_text(encoding="utf-8")
    _, text = doc_page_with(code)
    after = text[text.index(code) + len(code):]
    block = after[after.index("It printed"):].split("\n\n")[0]
    stated = []
    for line, spans in re.findall(r"^- `(.*)`(?: — over the kernels tried: (.*))?$", block, flags=re.M):
        ranges = [tuple(float(x) for x in span.split(" to ")) for span in spans.split(", ")] \
            if spans else [(float(x), float(x)) for x in re.findall(NUMBER, line)]
        stated.append((line, ranges))
    return stated


def _figures(line: str, printed: set[str]) -> list[float] | None:
    """The numbers of the printed line that reads as `line` but for its numbers (None: none)."""
    words = f"({NUMBER})".join(re.escape(part) for part in re.split(NUMBER, line))
    for out in printed:
        m = re.fullmatch(words, out)
        if m:
            return [float(x) for x in m.groups()]
    return None


@pytest.mark.numerics
def test_the_identification_example_prints_the_documented_figures(tmp_path):
    """Every line the identification guide states for examples/identify_machine.py was printed
    (the identified frictions and drive masses against the truth, the held-out error), each of
    its figures within the range the guide states for it over the floating-point environments
    tried."""
    stated = docs_printed("identify_machine.py")
    assert len(stated) >= 4, stated
    proc = run_example(ROOT / "examples" / "identify_machine.py", tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    printed = {line.strip() for line in proc.stdout.splitlines()}
    for line, ranges in stated:
        assert len(ranges) == len(re.findall(NUMBER, line)), (line, ranges)
        # the guide's own figures lie in their ranges
        assert all(lo <= float(x) <= hi for x, (lo, hi) in zip(re.findall(NUMBER, line), ranges))
        got = _figures(line, printed)
        assert got is not None, f"the guide says the example printed {line!r}; it printed:\n" \
                                f"{proc.stdout}"
        assert all(lo <= x <= hi for x, (lo, hi) in zip(got, ranges)), (line, got, ranges)


def _env() -> dict:
    import os
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH", "")]))
    env.setdefault("MPLBACKEND", "Agg")
    return env
