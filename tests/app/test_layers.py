"""The layers only look down: stewart_fmu < controller < hil < stewart_sim (the ast of every
module, imports inside functions included), no import cycles between our modules, and no
`_private` name imported across modules."""
import ast
from pathlib import Path

from tests.helpers import ROOT

RANK = {"stewart_fmu": 0, "controller": 1, "hil": 2, "stewart_sim": 3}


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in RANK:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = f
    return out


def _imports(name: str, path: Path):
    """(imported module, imported names, line) of every import in the file, made absolute."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, (), node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            yield base, tuple(a.name for a in node.names), node.lineno


def _edges():
    mods = _modules()
    for name, path in mods.items():
        for target, names, line in _imports(name, path):
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in mods]
            # `from pkg import module` depends on the module, not on the package's __init__
            for c in subs or ([target] if target in mods else []):
                yield name, c, names, line, path


def test_no_import_looks_up_the_layers():
    up = [f"{path.relative_to(ROOT)}:{line} -> {target}"
          for name, target, _, line, path in _edges()
          if RANK[target.split(".")[0]] > RANK[name.split(".")[0]]]
    assert up == []


def test_our_modules_import_no_cycle():
    graph: dict[str, set[str]] = {}
    for name, target, _, _, _ in _edges():
        if target != name and not name.startswith(target + "."):  # a package's own __init__
            graph.setdefault(name, set()).add(target)
    done, stack, cycles = set(), [], []

    def visit(node: str) -> None:
        if node in stack:
            cycles.append(stack[stack.index(node):] + [node])
            return
        if node in done:
            return
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            visit(nxt)
        stack.pop()
        done.add(node)

    for node in sorted(graph):
        visit(node)
    assert cycles == []


def test_no_private_name_crosses_a_module():
    crossing = [f"{path.relative_to(ROOT)}:{line} imports {n} from {target}"
                for name, target, names, line, path in _edges() if target != name
                for n in names if n.startswith("_") and not n.startswith("__")]
    assert crossing == []


def test_the_application_is_imported_by_nothing():
    assert [(n, t) for n, t, _, _, _ in _edges()
            if t.startswith("stewart_sim") and not n.startswith("stewart_sim")] == []
