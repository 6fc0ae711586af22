"""Sphinx configuration of the documentation site (`make docs`: _build/html beside this file).

Pages are Markdown (MyST); the command reference is generated from the command line's parser
(sphinx-argparse, docs/reference/commands.md) and the API reference from the docstrings
(autodoc, docs/reference/api.md)."""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the packages of this tree, installed or not

project = "stewart-sim"
author = "the stewart-sim developers"
copyright = "2026, the stewart-sim developers"

extensions = ["myst_parser", "sphinxarg.ext", "sphinx.ext.autodoc"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "**/*.csv"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
# The contract (contract.md, a copy word for word) shows the scene schema as ```toml with
# placeholders (`[[x, y, z], ...]`) that are not TOML: Pygments retries it in relaxed mode and
# says so. That one message is not a fault of the page.
suppress_warnings = ["misc.highlighting_failure"]  # links to a page's sections (`page.md#a-section`)

html_theme = "furo"
# text as written: `--validate` stays two hyphens (help texts, option names in prose)
smartquotes = False
html_title = "stewart-sim"
html_static_path: list[str] = []

autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": True}
autodoc_typehints = "description"
autodoc_preserve_defaults = True
nitpicky = False

# The API reference of controller and hil: one section per module, the module list taken from
# the packages when the site is built (so a module added, moved or renamed needs no edit here).
# Not documented: C extension modules and their build scripts (native), private modules, and
# hil/mavlink_stewart.py (pymavlink's generated dialect: its own reference is the XML).
API_PACKAGES = {"controller": "Controller", "hil": "Hardware in the loop"}
API_SKIPPED = ("hil.mavlink_stewart",)
GENERATED = Path(__file__).resolve().parent / "reference" / "generated"


def _public_modules(package: str) -> list[str]:
    import importlib
    import pkgutil

    found = pkgutil.walk_packages(importlib.import_module(package).__path__, package + ".")
    return sorted(m.name for m in found if m.name not in API_SKIPPED
                  and not any(p.startswith("_") or p == "native" for p in m.name.split(".")))


def _write_api_pages() -> None:
    GENERATED.mkdir(parents=True, exist_ok=True)
    for package, title in API_PACKAGES.items():
        lines = [f"# {title}: `{package}`", "", "```{eval-rst}", f".. automodule:: {package}", "```"]
        for module in _public_modules(package):
            lines += ["", f"## `{module}`", "", "```{eval-rst}", f".. automodule:: {module}", "```"]
        page = GENERATED / f"{package}.md"
        text = "\n".join(lines) + "\n"
        if not page.exists() or page.read_text(encoding="utf-8") != text:
            page.write_text(text, encoding="utf-8")


_write_api_pages()


# The command line's help texts are plain text (what `--help` prints), not reStructuredText:
# sphinx-argparse parses them as reST, where `|x|` is a substitution and `*` emphasis. They are
# shown as written.
def _plain_paragraphs(items, markdown_help, settings=None):
    from docutils import nodes

    out = []
    for item in items:
        default = re.fullmatch(r"Default: ``(.*)``", item, re.S) if isinstance(item, str) else None
        if default:  # the one piece sphinx-argparse writes as reST itself
            value = default.group(1).replace(r"\`", "`")
            out.append(nodes.paragraph("", "Default: ", nodes.literal(text=value)))
        else:
            out += [nodes.paragraph(text=item)] if isinstance(item, str) else list(item)
    return out


def _plain_paragraph(self, text):
    from docutils import nodes

    return nodes.paragraph(text=text)


def _argparse_plain_text() -> None:
    import sphinxarg.ext

    sphinxarg.ext.render_list = _plain_paragraphs
    sphinxarg.ext.ArgParseDirective._nested_parse_paragraph = _plain_paragraph


_argparse_plain_text()


# Docstrings are plain text (the project writes them to be read in the source), not reST. Each
# is turned into reST that shows it as written: `name` becomes an inline literal, every other
# character reST would read as markup is escaped, and a paragraph with an indented or a list
# line keeps its layout as a literal block.
_INLINE = re.compile(r"``?([^`\n]+)``?")
_MARKUP = re.compile(r"([\\*|_`\[\]<>:])")


def _escaped(text: str) -> str:
    parts = _INLINE.split(text)  # even: prose, odd: `name`
    return "".join(_MARKUP.sub(r"\\\1", p) if i % 2 == 0 else f"\\ ``{p.strip()}``\\ "
                   for i, p in enumerate(parts))


def _is_layout(paragraph: list[str]) -> bool:
    first = len(paragraph[0]) - len(paragraph[0].lstrip())
    return any(len(line) - len(line.lstrip()) != first or re.match(r"\s*([-*+]|\d+[.)])\s", line)
               or re.fullmatch(r"\s*([=~^\-])\1{2,}[=~^\- ]*", line) for line in paragraph)


def _plain_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    out: list[str] = []
    paragraph: list[str] = []
    for line in [*lines, ""]:
        if line.strip():
            paragraph.append(line)
            continue
        if paragraph and _is_layout(paragraph):
            out += ["::", "", *("    " + p for p in paragraph), ""]
        elif paragraph:
            out += [_escaped(p.strip()) for p in paragraph] + [""]
        paragraph = []
    lines[:] = out


def setup(app) -> None:
    app.connect("autodoc-process-docstring", _plain_docstring)
