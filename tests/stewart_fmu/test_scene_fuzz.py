"""A deterministic, bounded fuzz of scenes: every key of every shipped scene (and every first
element of its arrays) replaced by each hostile value (1e308, -1e308, 1e-300, 0, a negative, nan
and inf as TOML numbers and as strings, a 31-digit integer, 1 followed by 400 zeros, an array
nested 40 deep, wrong types, a string with escapes), written as a TOML file and loaded; the
micro scene's mutations also through the commands scene-info and inverse, and a chosen few of
them through run (0.05 s: RUN_CASES). Every outcome: the scene loads, or one SceneError naming a
dotted key; a command exits 0 or 2 with one line on stderr, never a traceback; what exit 0
writes holds only finite numbers. Every loop is bounded by the lists below; the whole test runs
a few minutes at most and has no wall-clock pass/fail. The issue's repros are tests beside it
(scene values: test_issue_repros_* below)."""
from __future__ import annotations

import copy
import csv
import math
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from stewart_fmu import SceneError, load_scene
from stewart_sim import cli
from tests.helpers import SCENE_FILES, SCENES_DIR, shipped_scenes

SHIPPED = shipped_scenes()
HOSTILE = [1e308, -1e308, 1e-300, 0, -1.5, math.nan, math.inf, -math.inf, "nan", "inf",
           10**30, 10**400, [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1.0]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]],
           True, {"a": 1.0}, [], "x\x1b[31m\n\t\\\"\u202e"]
# The loadable mutations of the micro scene that also run closed loop: one per table of the
# scene and each kind of hostile value that loads (a string with escapes in the name, -1.5,
# 1e-300, 0), named as _mutations labels them (index into HOSTILE after the '=').
RUN_CASES = ("name=16", "gravity[0]=4", "geometry.home[0]=2", "platform.mass=2",
             "legs.lower_mass=3", "drive.gear_ratio=2", "friction.viscous=3",
             "controller.phase_margin=2", "controller.motor.current_limit=2")


def _keys(data, prefix: str = ""):
    """(dotted key, path) of every value of a parsed scene, tables walked, arrays as values,
    plus each array's first element (path ending in index 0)."""
    for k, v in data.items():
        path = (*prefix, k) if isinstance(prefix, tuple) else (k,)
        if isinstance(v, dict):
            yield from _keys(v, path)
        else:
            yield ".".join(map(str, path)), path
            if isinstance(v, list) and v:
                yield ".".join(map(str, path)) + "[0]", (*path, 0)


def _mutated(data: dict, path, value) -> dict:
    out = copy.deepcopy(data)
    node = out
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = copy.deepcopy(value)
    return out


def _write(data: dict, path: Path) -> Path:
    path.write_text(tomlkit.dumps(data))
    return path


def _mutations(scene: Path):
    """Every (label, mutated dict) of one scene: each key x each hostile value."""
    import tomllib
    data = tomllib.loads(scene.read_text())
    for dotted, path in _keys(data):
        for k, value in enumerate(HOSTILE):
            yield f"{scene.stem}:{dotted}={k}", _mutated(data, path, value)


def _finite_csv(path: Path) -> None:
    """Every number of a CSV finite (the header skipped)."""
    with path.open() as f:
        rows = csv.reader(f)
        next(rows)
        for line, row in enumerate(rows, start=2):
            for cell in row:
                try:
                    x = float(cell)
                except ValueError:
                    continue
                assert math.isfinite(x), f"{path}: line {line}: {cell}"


def _command(argv: list[str], capsys) -> int:
    """cli.main, its exit status checked: 0, or 2 with one line on stderr (no traceback: an
    exception escaping main fails the test here)."""
    status = cli.main(argv)
    err = capsys.readouterr().err
    assert status in (0, 2), (argv, status, err)
    if status == 2:
        assert err.count("\n") == 1 and err.startswith("stewart-sim: error: "), (argv, err)
        assert "Traceback" not in err
    return status


@pytest.mark.parametrize("scene", SHIPPED, ids=lambda p: str(p.relative_to(SCENES_DIR)))
def test_every_key_of_every_scene_loads_or_is_refused_naming_a_key(tmp_path, scene):
    """load_scene of each mutation: a Model, or a SceneError whose key is a dotted key of the
    scene's tables (or the file), one line."""
    count = 0
    for label, data in _mutations(scene):
        count += 1
        try:
            model = load_scene(_write(data, tmp_path / "s.toml"))
        except SceneError as exc:
            assert "\n" not in str(exc) and exc.key, (label, str(exc))
            continue
        p = model.params   # leg_max is inf when the scene has no stroke
        assert np.all(np.isfinite(p) | (p == np.inf)), label
    assert count >= len(HOSTILE)


def test_micro_mutations_through_scene_info_inverse_and_run(tmp_path, capsys):
    """The micro scene's mutations through scene-info and inverse (a 21-sample trajectory), and
    RUN_CASES through run (0.05 s): exit 0 with finite outputs, or 2 with one line."""
    micro = SCENE_FILES["micro"]
    traj = tmp_path / "traj.csv"
    assert _command(["trajectory", str(micro), "--move", "demo", "--duration", "0.02",
                     "--out", str(traj)], capsys) == 0
    mutations = list(_mutations(micro))
    tried = {"scene-info": 0, "inverse": 0, "run": 0}
    loaded, ran = {}, 0
    for k, (label, data) in enumerate(mutations):
        scene = _write(data, tmp_path / f"m{k}.toml")
        tried["scene-info"] += 1
        if _command(["scene-info", str(scene)], capsys) == 2:
            continue   # refused at load: every command refuses it the same way
        loaded[label.split(":", 1)[1]] = scene
        out = tmp_path / f"f{k}.csv"
        tried["inverse"] += 1
        if _command(["inverse", str(scene), "--trajectory", str(traj), "--out", str(out),
                     "--no-view"], capsys) == 0:
            _finite_csv(out)
    assert set(RUN_CASES) <= set(loaded), set(RUN_CASES) - set(loaded)   # each one loads
    for k, scene in enumerate(loaded[case] for case in RUN_CASES):
        tried["run"] += 1
        folder = tmp_path / f"run{k}"
        if _command(["run", str(scene), "--out", str(folder), "--duration", "0.05",
                     "--no-view"], capsys) == 0:
            ran += 1
            _finite_csv(folder / "run.csv")
    print(f"scene fuzz: {len(mutations)} mutations of the micro scene, commands tried {tried}, "
          f"{ran} runs completed")
    assert tried["scene-info"] == len(mutations) and tried["run"] == len(RUN_CASES)


# --- the issue's repros of the scene values -----------------------------------------------------

def _replaced(tmp_path: Path, old: str, new: str) -> Path:
    text = SCENE_FILES["micro"].read_text()
    assert text.count(old) == 1, old
    path = tmp_path / "scene.toml"
    path.write_text(text.replace(old, new))
    return path


REPROS = [
    ("gear_ratio = 20.0", "gear_ratio = 1e308", "drive.gear_ratio", "must be <= 100000, got 1e+308"),
    ("pinion_radius = 0.005", "pinion_radius = 1e-300", "drive.pinion_radius", "must be >= 1e-06 m"),
    ("rate = 1000.0", "rate = " + "1" * 31, "controller.rate", "integer of 31 digits"),
    ("mass = 0.5", "mass = 1" + "0" * 400, "platform.mass", "integer of 401 digits"),
    ("mass = 0.5", "mass = 1" + "0" * 5000, "platform.mass", "integer of over 4000 digits"),
    ("lower_mass = 0.065", "lower_mass = 1e308", "legs.lower_mass", "must be <= 100000 kg"),
    ("bandwidth = 20.0", "bandwidth = 1e308", "controller.bandwidth", "must be <= 10000 Hz"),
    ("gravity = [0.0, 0.0, -9.81]", "gravity = " + "[" * 50000 + "]" * 50000, "gravity",
     "nested more than 16"),
]


@pytest.fixture(scope="module")
def micro_trajectory(tmp_path_factory) -> Path:
    """A short trajectory of the micro scene (the `inverse` repros' input)."""
    path = tmp_path_factory.mktemp("traj") / "t.csv"
    assert cli.main(["trajectory", str(SCENE_FILES["micro"]), "--move", "demo", "--duration",
                     "0.02", "--out", str(path)]) == 0
    return path


@pytest.mark.parametrize("old,new,key,why", REPROS, ids=[f"{r[2]}-{k}" for k, r in enumerate(REPROS)])
@pytest.mark.parametrize("command", ["scene-info", "inverse", "run"])
def test_issue_repros_scene_values(tmp_path, capsys, micro_trajectory, command, old, new, key,
                                   why):
    """Each example of the issue's scene-values row: one line naming the key and the reason,
    exit 2, nothing written (was: OverflowError, ZeroDivisionError, TypeError, RecursionError,
    "inf kg", a misleading singular Jacobian, LinAlgError)."""
    scene = _replaced(tmp_path, old, new)
    out = tmp_path / "out"
    extra = {"scene-info": [], "inverse": ["--trajectory", str(micro_trajectory), "--out",
                                           str(out), "--no-view"],
             "run": ["--out", str(out), "--duration", "0.05", "--no-view"]}[command]
    capsys.readouterr()
    assert cli.main([command, str(scene), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"scene key '{key}'" in err and why in err, err
    assert not out.exists()
