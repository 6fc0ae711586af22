"""The layers only look down: stewart_fmu < controller < hil < stewart_sim (the ast of every
module, imports inside functions included), no import cycles between our modules, and no
`_private` name imported across modules. Inside stewart_sim: at most TOP_ENTRIES entries at its
top, its subpackages in one ORDER that no import climbs back up, and no module name with two
meanings across the four packages (a name used twice is a role of ROLES, or a command's)."""
import ast
import functools
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


@functools.cache
def _edges() -> tuple:
    """(importer, imported module, imported names, line, importer's path) of every import."""
    mods = _modules()
    out = []
    for name, path in mods.items():
        for target, names, line in _imports(name, path):
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in mods]
            # `from pkg import module` depends on the module, not on the package's __init__
            for c in subs or ([target] if target in mods else []):
                out.append((name, c, names, line, path))
    return tuple(out)


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


# --- the layout of stewart_sim ----------------------------------------------------------------

APP = ROOT / "stewart_sim"
TOP_ENTRIES = 12   # at most, at the top of stewart_sim (files and subpackages)

# stewart_sim's subpackages from the bottom up: a module imports only from its own unit or from
# one below it (the command line on top; `studies` is only a container, its studies are units)
ORDER = ("shell",         # argument types, terminal, Ctrl-C, result sets, progress, run length,
                          # Markdown escaping and the PNG figures every report shares
         "scene",         # a scene's tables read once, described; the [cueing] and [case]
                          # tables; the paper's six moves on a scene's model
         "view",          # the 3D pages (and the live view server)
         "studies.workspace",  # the feasibility engine over a scene: checks, reach, ranges, maps
         "open_loop",     # reference trajectories, forces along them, motion from forces
         "closed_loop",   # the closed-loop run: in process, as an FMU, over a link
         "cueing",        # offline motion cueing: washout, perception, feasibility, MPC
         "live",          # the live motion simulator and what only it uses
         "studies.cases", "studies.paper", "studies.accuracy", "studies.calibrate",
         "studies.compare", "studies.sweep", "studies.sizing", "studies.identify",
         "studies.excite",
         "studies.modes",  # the stiffness and the modes at a pose, their map
         "studies.design",  # geometry from requirements: the engine, the modes, the sweep's cluster
         "commands",      # one module per command
         "cli", "__main__")
CONTAINERS = ("stewart_sim", "stewart_sim.studies")   # packages that only hold units

# A module name used more than once across stewart_fmu, controller, hil and stewart_sim is a
# role, with one meaning wherever it is used:
ROLES = {
    "study": "a study's computation: data in, data out, no files written",
    "report": "a study's files: what it writes (CSV, PNG, Markdown, printed lines) from the "
              "data its study returns",
    "files": "a result set on disk: the files a command writes, each atomically",
    "plots": "the matplotlib figures of its package, written as PNG",
    "errors": "the typed exceptions of its package",
    "address": "a network address given on the command line, checked before any socket opens",
    "design": "free parameters chosen against stated goals (a controller's gains tuned to a "
              "crossover and margin; an excitation's coefficients optimised for the regressor's "
              "condition)",
    "fmu": "the package's model exported as an FMI co-simulation FMU",
    "native": "the package's C sources and the module compiled from them",
    "scene": "a scene file read and checked: the plant's tables into a Model (stewart_fmu), "
             "the project's tables above it (stewart_sim)",
}
# A module of stewart_sim/commands is named for its command (the command line's word); it shares
# that name with the one module or package elsewhere that holds what the command does
COMMAND_NAMES = {
    "accuracy": "stewart_sim/studies/accuracy", "calibrate": "stewart_sim/studies/calibrate",
    "compare": "stewart_sim/studies/compare", "excite": "stewart_sim/studies/excite",
    "identify": "stewart_sim/studies/identify", "paper": "stewart_sim/studies/paper",
    "sweep": "stewart_sim/studies/sweep", "view": "stewart_sim/view", "workspace": "stewart_sim/studies/workspace",
    "modes": "stewart_sim/studies/modes",
    "device": "hil/device.py",                 # the emulated device the command serves
    "trajectory": "controller/trajectory.py",  # the reference trajectories the command writes
}


def _unit(module: str) -> str | None:
    rest = module.removeprefix("stewart_sim.")
    return next((u for u in sorted(ORDER, key=len, reverse=True)
                 if rest == u or rest.startswith(u + ".")), None)


def test_the_top_of_stewart_sim_holds_at_most_twelve_entries():
    entries = sorted(p.name for p in APP.iterdir()
                     if p.name != "__pycache__" and not p.name.startswith("."))
    assert len(entries) <= TOP_ENTRIES, entries


def test_every_stewart_sim_module_has_a_place_in_the_order():
    assert [m for m in _modules() if m.startswith("stewart_sim")
            and m not in CONTAINERS and _unit(m) is None] == []


def test_no_import_climbs_back_up_the_order_of_stewart_sim():
    up = [f"{path.relative_to(ROOT)}:{line} -> {target}"
          for name, target, _, line, path in _edges()
          if name.startswith("stewart_sim.") and target.startswith("stewart_sim.")
          and _unit(name) and _unit(target)
          and ORDER.index(_unit(target)) > ORDER.index(_unit(name))]
    assert up == []
    # the containers import nothing of ours
    assert [(n, t) for n, t, _, _, _ in _edges() if n in CONTAINERS] == []


def _names() -> dict[str, list[str]]:
    """Module name -> where it is: every .py file (but __init__, __main__) and every package."""
    out: dict[str, list[str]] = {}
    for pkg in RANK:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            if f.name == "__init__.py" and f.parent != ROOT / pkg:
                out.setdefault(f.parent.name, []).append(str(f.parent.relative_to(ROOT)))
            elif f.name not in ("__init__.py", "__main__.py"):
                out.setdefault(f.stem, []).append(str(f.relative_to(ROOT)))
    return out


def test_no_module_name_means_two_things():
    twice = {}
    for name, where in _names().items():
        if len(where) < 2 or name in ROLES:
            continue
        if name in COMMAND_NAMES and sorted(where) == sorted(
                [f"stewart_sim/commands/{name}.py", COMMAND_NAMES[name]]):
            continue
        twice[name] = where
    assert twice == {}


def test_the_allowances_are_in_use():
    names = _names()
    assert [r for r in ROLES if len(names.get(r, ())) < 2] == []
    assert [c for c, other in COMMAND_NAMES.items()
            if f"stewart_sim/commands/{c}.py" not in names.get(c, ())
            or other not in names.get(c, ())] == []
