"""Words that point at things that exist: every reference a comment or a docstring makes, in
Python and in C, resolves in this tree, and no history word is left in one.

What is a reference (prose around it is never checked):
- a dotted name whose first part is one of our packages (`stewart_fmu.plant.Plant`), or a bare
  module of ours (`kinematics.condition_number`, `model.rack_ratio`) or a C source's stem
  (`kane.X`: there is no Python module `kane`): the module must exist and the next name must be
  defined at its top level (or, for a bare module, be a member of one of its classes, as in
  `model.params`, a Model's attribute); a class's member is checked one level down. Bare names
  that are also standard-library modules (`io`, `html`) are left alone.
- a file name `name.py`, `name.c`, `name.h` or `NAME.md`: a file of that name is in the
  repository (outside files a comment cites by name are listed in OUTSIDE_FILES; lower-case
  `.md`, `.csv`, ... names are the files commands write).
- a path (`stewart_fmu/native/src/step.c`, `docs/scene-format.md`) whose first part is a folder
  of the repository, or `shared/`: it exists from the repository root or from a folder above
  the file that names it. `shared/` is not in the repository: cite docs/conventions.md.
History words, in comments, docstrings and the names of tests: "numba", "pythonfmu", issue or
pull-request numbers ("issue 12", "#12", "PR 12", "gh-12"), commit ids (seven or more hex digits,
letters and digits both), and the phrases that tell what code was rather than what it is: "used
to", "formerly", "previously", "the old", "it (they, this, that, which) replaced".
"""
from __future__ import annotations

import ast
import io
import re
import subprocess
import sys
import tokenize
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # not tests.helpers': this test imports nothing of ours


PACKAGES = ("stewart_fmu", "controller", "hil", "stewart_sim")
# Files of other projects that comments cite by name (the anchors our designs follow).
OUTSIDE_FILES = frozenset({"command_line.py", "config.h", "fmi2Functions.c", "mjxmacro.h"})
OUTSIDE_PATHS = frozenset({"message_definitions/v1.0/*.xml"})  # in pymavlink's sdist
GENERATED = frozenset({"hil/mavlink_stewart.py"})  # pymavlink's output, checked by regeneration
FILE_EXTENSIONS = frozenset({"py", "c", "h", "md", "toml", "csv", "png", "html", "js", "json",
                             "xml", "txt", "so", "o", "fmu", "zip", "npz", "yml", "cfg", "in",
                             "parquet"})
CHECKED_EXTENSIONS = frozenset({"py", "c", "h"})

# `[controller.motor]` is a scene table and 'table.key' a string, not modules: a name right after
# "[" or a quote is not checked
DOTTED = re.compile(r"""(?<![\w./\\\['"-])[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+""")
PATH = re.compile(r"(?<![\w./:\\*-])[\w.*-]+(?:/[\w.*-]+)+/?")
HISTORY = re.compile(r"\bnumba\b|\bpythonfmu\b|\bissues?\s*#?\d+|\bpull request\s*#?\d+"
                     r"|(?-i:\bPR)(?:\s*#|\s+)\d+|\bgh-\d+\b|(?<![\w#&/])#\d+\b"
                     r"|(?-i:(?<![\w.#+-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])"
                     r"[0-9a-f]{7,40}(?![\w.]))"
                     r"|\bused to\b|\bformerly\b|\bpreviously\b|\bthe old\b"
                     r"|\b(?:it|they|this|that|which)\s+replaced\b", re.IGNORECASE)
SKIPPED = (".git", ".venv", "build", "results", "__pycache__", ".pytest_cache")


@cache
def _tracked() -> tuple[str, ...]:
    """The repository's files: git's, new ones included; without git, the tree less SKIPPED and
    build outputs (cffi's generated _core.c, _axis.c)."""
    try:
        out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"],
                             cwd=ROOT, capture_output=True, text=True, check=True).stdout
        out = out.split("\n")
    except (OSError, subprocess.CalledProcessError):
        out = [p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*") if p.is_file()
               and not set(p.relative_to(ROOT).parts) & set(SKIPPED) and ".egg-info" not in str(p)
               and p.suffix not in (".so", ".o") and not (p.suffix == ".c" and p.name[0] == "_")]
    return tuple(sorted({f for f in out if f and (ROOT / f).is_file()}))


@cache
def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of our packages."""
    out = {}
    for f in _tracked():
        parts = f.removesuffix(".py").split("/")
        if f.endswith(".py") and parts[0] in PACKAGES:
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = ROOT / f
    return out


@cache
def _compiled() -> frozenset[str]:
    """The C extension modules our cffi build scripts name (built in place, not in git)."""
    found = (re.findall(r'set_source\(\s*"([\w.]+)"', (ROOT / f).read_text(encoding="utf-8"))
             for f in _tracked() if f.endswith(".py") and f.split("/")[0] in PACKAGES)
    return frozenset(name for names in found for name in names)


@cache
def _classes() -> dict[str, tuple[str, ...]]:
    """Class name -> our modules that define a class of that name at their top level."""
    out: dict[str, list[str]] = {}
    for module in _modules():
        for name, node in _module_names(module).items():
            generated = _modules()[module].relative_to(ROOT).as_posix() in GENERATED
            if isinstance(node, ast.ClassDef) and not generated:
                out.setdefault(name, []).append(module)
    return {k: tuple(v) for k, v in out.items()}


@cache
def _bare() -> dict[str, tuple[str, ...]]:
    """Leaf name -> our modules of that name, and the stems of our C sources (no module)."""
    out: dict[str, list[str]] = {}
    for name in _modules():
        if "." in name:
            out.setdefault(name.rpartition(".")[2], []).append(name)
    for f in _tracked():
        if f.endswith((".c", ".h")):
            out.setdefault(Path(f).stem, [])
    return {k: tuple(v) for k, v in out.items() if k not in sys.stdlib_module_names}


@cache
def _folders() -> frozenset[str]:
    return frozenset(p for f in _tracked() for p in f.split("/")[:-1]) | {"shared"}


@cache
def _basenames() -> frozenset[str]:
    return frozenset(Path(f).name for f in _tracked())


def _assigned(target: ast.expr) -> list[str]:
    if isinstance(target, ast.Name):
        return [target.id]
    if isinstance(target, (ast.Tuple, ast.List)):
        return [n for t in target.elts for n in _assigned(t)]
    return []


def _names(body: list[ast.stmt]) -> dict[str, ast.AST]:
    """Names a block of statements binds (into if/try/with blocks, not into functions)."""
    out: dict[str, ast.AST] = {}
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out[node.name] = node
        elif isinstance(node, ast.Assign):
            out.update((n, node) for t in node.targets for n in _assigned(t))
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
            out.update((n, node) for n in _assigned(node.target))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            out.update(((a.asname or a.name).split(".")[0], node) for a in node.names)
        elif isinstance(node, ast.For):
            out.update((n, node) for n in _assigned(node.target))
        for block in ("body", "orelse", "finalbody", "handlers"):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                for sub in getattr(node, block, []):
                    out.update(_names([sub]) if isinstance(sub, ast.stmt) else _names(sub.body))
    return out


@cache
def _module_names(module: str) -> dict[str, ast.AST]:
    tree = ast.parse(_modules()[module].read_text(encoding="utf-8"))
    names = _names(tree.body)
    names.update((m.rpartition(".")[2], tree) for m in _modules() if m.rpartition(".")[0] == module)
    return names


def _members(cls: ast.ClassDef, module: str,
             seen: frozenset[str] = frozenset()) -> tuple[set[str], bool]:
    """A class's members (its body, every self.x it assigns, those of its bases in the module),
    and whether that is all of them (False when a base is defined elsewhere)."""
    out, complete = set(_names(cls.body)), True
    for node in ast.walk(cls):
        if (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
                and isinstance(node.value, ast.Name) and node.value.id == "self"):
            out.add(node.attr)
    for base in cls.bases:
        found = _module_names(module).get(base.id) if isinstance(base, ast.Name) else None
        if not isinstance(found, ast.ClassDef) or base.id in seen:
            complete = False
            continue
        more, whole = _members(found, module, seen | {cls.name})
        out, complete = out | more, complete and whole
    return out, complete


def _resolve(module: str, rest: list[str], lenient: bool) -> str | None:
    """Why `module.rest` does not resolve, or None when it does."""
    while rest and f"{module}.{rest[0]}" in _modules():
        module, rest = f"{module}.{rest[0]}", rest[1:]
    if not rest or f"{module}.{rest[0]}" in _compiled():
        return None
    names = _module_names(module)
    found = names.get(rest[0])
    if found is None:
        # a bare module's name is also its instances' (`model.params`): a member of its classes
        if lenient and any(rest[0] in _members(c, module)[0]
                           for c in names.values() if isinstance(c, ast.ClassDef)):
            return None
        return f"{module} has no {rest[0]}"
    if isinstance(found, ast.ClassDef) and len(rest) > 1:
        members, complete = _members(found, module)
        if complete and rest[1] not in members:
            return f"{module}.{rest[0]} has no {rest[1]}"
    return None


def _check_dotted(ref: str) -> str | None:
    parts = ref.split(".")
    if parts[-1] in FILE_EXTENSIONS and len(parts) == 2:
        checked = parts[-1] in CHECKED_EXTENSIONS or (parts[-1] == "md" and parts[0].isupper())
        if checked and ref not in _basenames() | OUTSIDE_FILES:
            return f"no file {ref} in the repository"
        return None
    if parts[0] in PACKAGES:
        return _resolve(parts[0], parts[1:], lenient=False)
    if parts[0] in _classes():
        why = [_resolve(m, parts, lenient=False) for m in _classes()[parts[0]]]
        return None if None in why else "; ".join(w for w in why if w)
    cls = next((i for i, p in enumerate(parts) if p in _classes()), 0)
    if cls > 0 and parts[0] not in _bare():  # `stepper.Plant`: a module of ours that is gone
        return f"no module of ours {'.'.join(parts[:cls])}"
    if parts[0] in _bare():
        candidates = _bare()[parts[0]]
        if not candidates:
            return f"no Python module {parts[0]}"
        why = [_resolve(c, parts[1:], lenient=True) for c in candidates]
        return None if None in why else "; ".join(w for w in why if w)
    return None


def _check_path(path: str, source: Path) -> str | None:
    path = path.rstrip(".")
    if path.split("/")[0] not in _folders() or path in OUTSIDE_PATHS:
        return None
    if path.startswith("shared/"):
        return "shared/ is not in the repository (cite docs/conventions.md)"
    first = path.split("/")[0]
    bases = [ROOT, *[p for p in source.parents if ROOT in p.parents],
             *{(ROOT / f).parents[len(f.split("/")) - 1 - f.split("/").index(first)]
               for f in _tracked() if first in f.split("/")[:-1]}]
    if "*" in path and any(next(base.glob(path.rstrip("/")), None) for base in bases):
        return None
    if "*" not in path and any((base / path).exists() for base in bases):
        return None
    return f"no path {path}"


def _python_comments(path: Path):
    """(line, text) of every `#` comment and every docstring line of a Python file."""
    text = path.read_text(encoding="utf-8")
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], tok.string
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = node.body[0] if node.body else None
            if (isinstance(doc, ast.Expr) and isinstance(doc.value, ast.Constant)
                    and isinstance(doc.value.value, str)):
                for i, line in enumerate(doc.value.value.splitlines()):
                    yield doc.lineno + i, line


def _c_comments(path: Path):
    """(line, text) of every line of every /* */ and // comment of a C file (strings skipped)."""
    text = path.read_text(encoding="utf-8")
    i, line, n = 0, 1, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i) or text.startswith("//", i):
            block = text[i + 1] == "*"
            end = text.find("*/", i + 2) + 2 if block else text.find("\n", i)
            end = n if end < 2 else end
            for k, part in enumerate(text[i:end].split("\n")):
                yield line + k, part
            line += text.count("\n", i, end)
            i = end
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            line += text.count("\n", i, j)
            i = j + 1
        else:
            line += c == "\n"
            i += 1


def _sources() -> list[tuple[str, Path]]:
    """The Python and C files to scan (not this one: its examples are stale on purpose)."""
    out = []
    for f in _tracked():
        if f.endswith(".py") and f not in GENERATED and ROOT / f != Path(__file__).resolve():
            out.append((f, ROOT / f))
        elif f.endswith((".c", ".h")):
            out.append((f, ROOT / f))
    return out


def _scan():
    """(file, line, what, why) of every reference that does not resolve, and the count checked."""
    failures, checked = [], 0
    for rel, path in _sources():
        comments = _python_comments(path) if rel.endswith(".py") else _c_comments(path)
        for line, text in comments:
            for m in HISTORY.finditer(text):
                failures.append((rel, line, m.group(), "a history word"))
            for m in PATH.finditer(text):
                if m.group().split("/")[0] in _folders():
                    checked += 1
                    why = _check_path(m.group(), path)
                    if why:
                        failures.append((rel, line, m.group(), why))
            for m in DOTTED.finditer(PATH.sub(" ", text)):
                parts = m.group().split(".")
                file_name = len(parts) == 2 and parts[1] in FILE_EXTENSIONS
                if (parts[0] in PACKAGES or parts[0] in _bare() or file_name
                        or any(p in _classes() for p in parts)):
                    checked += 1
                    why = _check_dotted(m.group())
                    if why:
                        failures.append((rel, line, m.group(), why))
    return failures, checked


def test_every_reference_in_comments_resolves():
    failures, checked = _scan()
    report = [f"{rel}:{line}: {what}: {why}" for rel, line, what, why in failures]
    print(f"{checked} references checked, {len(failures)} failures")
    print("\n".join(report))
    assert checked > 300
    assert report == []


def test_no_test_is_named_for_history():
    """A test's name says what it holds, not what the code once was (HISTORY, words as `_`)."""
    named = [f"{rel}: {name}" for rel, path in _sources() if rel.startswith("tests/")
             and rel.endswith(".py")
             for name in re.findall(r"^\s*def (test_\w+)", path.read_text(encoding="utf-8"), re.M)
             if HISTORY.search(name.replace("_", " "))]
    assert named == []


def test_the_resolver_tells_good_from_stale():
    assert _check_dotted("stewart_fmu.plant.Plant") is None
    assert _check_dotted("kinematics.inverse_kinematics") is None
    assert _check_dotted("model.params") is None
    assert _check_dotted("numpy.linalg") is None
    assert _check_dotted("e.g") is None
    assert _check_dotted("stewart_fmu.native._core.lib") is None
    assert _check_dotted("Plant.do_step") is None and _check_dotted("Plant.no_such_member")
    assert _check_dotted("stewart_fmu.model._no_such_name")
    assert _check_dotted("kane.STROKE") and _check_dotted("integrators._derivative")
    assert _check_dotted("linalg.py") and _check_dotted("CONVENTIONS.md")
    assert _check_dotted("README.md") is None and _check_dotted("summary.md") is None
    assert _check_dotted("stepper.Plant.do_step") and _check_dotted("stepper.py")
    failures = []
    for text in ("see stepper.py", "CONVENTIONS.md", "as numba does", "shared/CONVENTIONS.md"):
        failures += [m.group() for m in DOTTED.finditer(PATH.sub(" ", text)) if _check_dotted(m.group())]
    assert failures == ["stepper.py", "CONVENTIONS.md"]
    assert _check_path("stewart_fmu/native/src/step.c", ROOT / "README.md") is None
    assert _check_path("include/stewart.h", ROOT / "stewart_fmu/native/fmi/model.c") is None
    assert _check_path("shared/CONVENTIONS.md", ROOT / "README.md")
    assert _check_path("docs/no-such-page.md", ROOT / "README.md")
    assert HISTORY.search("the numba kernels") and HISTORY.search("see issue 12")
    assert HISTORY.search("(#12)") and HISTORY.search("PR 7") and HISTORY.search("gh-3")
    assert not HISTORY.search("leg l1, 2 # comment") and not HISTORY.search("pr2 = p99")
    for text in ("recorded at commit 5a10cb2", "it used to answer", "formerly a module",
                 "as previously", "the old device", "the Python kernel it replaced"):
        assert HISTORY.search(text), text
    for text in ("0x7fffffff", "a sha256 of 64 digits " + "ab12" * 16, "1e-12 relative",
                 "-abcd1234", "dotted keys replaced", "replaced by the previous one",
                 "an existing file survives"):
        assert not HISTORY.search(text), text
