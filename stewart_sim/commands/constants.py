"""Module constants read from their source without importing the module (standard library only).

A command's help states defaults that are declared in a library module (controller.moves,
stewart_sim.studies.accuracy.study, ...); importing that module would import numpy, the C core and
the rest before `--help` could answer. The values are plain literals there, so the ast of the file
gives them: one declaration, read where it is written.
"""
from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

_ROOT = Path(__file__).resolve().parents[2]   # the directory holding our packages


def literals(module: str, *names: str) -> tuple[Any, ...]:
    """The values of the module-level `NAME = literal` assignments `names` of `module` (a dotted
    name of one of our modules, e.g. "controller.moves"), in the order asked."""
    path = _ROOT.joinpath(*module.split(".")).with_suffix(".py")
    found: dict[str, Any] = {}
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        else:
            continue
        for target in targets:
            if isinstance(target, ast.Name) and target.id in names:
                found[target.id] = ast.literal_eval(value)
    missing = [n for n in names if n not in found]
    if missing:
        raise LookupError(f"{module} assigns no literal {', '.join(missing)}")
    return tuple(found[n] for n in names)
