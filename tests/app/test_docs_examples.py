"""The shell examples of the documentation run (docs/: every ```sh, ```console, ```bash or
```shell block): each `stewart-sim` command of a block exits 0, in-process through
stewart_sim.cli.main, page by page in a fresh directory where `scenes/` is the repository's (the
blocks of one page run in order, so a later block reads what an earlier one wrote). A block that
cannot run here is marked just before its fence with `<!-- not run: REASON -->`; any other block
(a `make` target, another program) without the mark fails the test, naming the page and the line.
Synopses (`SCENE`, `[--option]`) are ```text blocks, not examples."""
from __future__ import annotations

import re
import shlex

import pytest

from stewart_sim import cli
from tests.helpers import ROOT, doc_pages

pytestmark = pytest.mark.docs_examples

SHELL = ("sh", "console", "bash", "shell")
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
NOT_RUN = re.compile(r"<!--\s*not run:\s*(.*?)\s*-->\s*\Z", re.S)


def shell_blocks(page: str) -> list[tuple[int, str, str | None]]:
    """(line, text, reason not run or None) of every shell block of a page, in order."""
    out = []
    for m in FENCE.finditer(page):
        if m.group(1) not in SHELL:
            continue
        before = page[:m.start()].rstrip("\n")
        reason = NOT_RUN.search(before[before.rfind("\n\n") + 1:] if "\n\n" in before else before)
        out.append((page.count("\n", 0, m.start()) + 1, m.group(2),
                    reason.group(1) if reason else None))
    return out


def commands(block: str) -> list[str]:
    """The command lines of a block: continuation lines joined, `# ...` comments and a console's
    output lines left out (a console block's commands start with `$ `)."""
    lines = block.replace("\\\n", " ").splitlines()
    if any(line.startswith("$ ") for line in lines):
        lines = [line[2:] for line in lines if line.startswith("$ ")]
    return [c for c in (shlex.split(line, comments=True) for line in lines) if c]


PAGES = {name: blocks for name, page in doc_pages().items() if (blocks := shell_blocks(page))}


def test_the_guides_have_examples_that_run():
    runnable = [c for blocks in PAGES.values() for _, block, reason in blocks if reason is None
                for c in commands(block)]
    assert len(runnable) >= 10, runnable
    for name, blocks in PAGES.items():
        for line, _, reason in blocks:
            assert reason is None or len(reason) > 10, f"docs/{name}:{line}: say why not run"


def test_every_not_run_mark_is_on_a_shell_block():
    marks = sum(len(re.findall(r"<!--\s*not run:", page)) for page in doc_pages().values())
    marked = sum(1 for blocks in PAGES.values() for b in blocks if b[2] is not None)
    assert marks == marked


@pytest.mark.parametrize("name", sorted(PAGES))
def test_the_shell_examples_of_a_page_run(name, tmp_path, monkeypatch, capsys):
    (tmp_path / "scenes").symlink_to(ROOT / "scenes", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    for line, block, reason in PAGES[name]:
        if reason is not None:
            continue
        for argv in commands(block):
            where = f"docs/{name}:{line}: {shlex.join(argv)}"
            assert argv[0] == "stewart-sim", \
                f"{where}: not a stewart-sim command; mark the block <!-- not run: REASON -->"
            status = cli.main(argv[1:])
            assert status == 0, f"{where} exited {status}:\n{capsys.readouterr().err[-2000:]}"
