"""`stewart-sim design --resume` (stewart_sim.studies.design.checkpoint): a search stopped by
Ctrl-C (exit 130, the line naming what the checkpoint kept, no result set written) or run for
fewer generations, then resumed, gives the uninterrupted run's candidates, front and chosen
design byte for byte; a checkpoint of another requirement, a damaged one, or none, is one line,
exit 2, nothing written."""
from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from stewart_sim.studies.design import checkpoint as CP
from stewart_sim.studies.design import spec as S
from stewart_sim.studies.design.candidate import requirement_names
from tests.app.test_design import EXAMPLE, cli, design_file

SIZE = ("--population", "20", "--generations", "8")   # the example's CI size
SAME = ("candidates.csv", "pareto.csv", "best.toml")   # summary.md holds the run's seconds
ONE = {"OPENBLAS_NUM_THREADS": "1"}


def _design(out, *extra, env=ONE):
    return cli("design", EXAMPLE, "--out", out, "--workers", "2", *extra, env=env)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("resume") / "full"
    r = _design(out, *SIZE)
    assert r.returncode == 0, r.stderr
    return out


def _same_set(a, b):
    for name in SAME:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_a_shorter_run_resumed_to_the_same_generations_is_the_uninterrupted_one(
        uninterrupted, tmp_path):
    out = tmp_path / "half"
    assert _design(out, "--population", "20", "--generations", "4").returncode == 0
    r = _design(out, *SIZE, "--resume", env={"OPENBLAS_NUM_THREADS": "2"})
    assert r.returncode == 0, r.stderr
    told = [line for line in r.stdout.splitlines() if line.endswith("(from the checkpoint)")]
    assert [line.split(":")[0] for line in told] == [f"generation {g}/8" for g in range(1, 5)]
    _same_set(uninterrupted, out)


def test_ctrl_c_keeps_the_generations_done_and_resume_finishes_the_same_search(
        uninterrupted, tmp_path):
    out = tmp_path / "stopped"
    cmd = [sys.executable, "-m", "stewart_sim", "design", str(EXAMPLE), "--out", str(out),
           "--workers", "2", *SIZE]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, **ONE, "PYTHONUNBUFFERED": "1"})
    try:
        for line in p.stdout:            # stop once generation 2 is in the checkpoint
            if line.startswith("generation 2/8"):
                p.send_signal(signal.SIGINT)
                break
        _, err = p.communicate(timeout=300)
    finally:
        p.kill()
    assert p.returncode == 130, err
    spec = S.with_search(S.load(EXAMPLE), population=20)
    cp = CP.load(out / CP.CHECKPOINT_FILE, spec, requirement_names(spec))
    kept = cp.generations
    assert 2 <= kept < 8
    line = err.strip().splitlines()[-1]
    assert f"kept the {kept} generations evaluated ({20 * kept} candidates)" in line
    assert "--resume" in line
    # nothing of the result set in DIR: the checkpoint alone
    assert sorted(p.name for p in out.iterdir()) == [CP.CHECKPOINT_FILE]
    r = _design(out, *SIZE, "--resume")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("(from the checkpoint)") == kept
    _same_set(uninterrupted, out)


def test_another_requirement_a_damaged_checkpoint_or_none_is_refused(uninterrupted, tmp_path):
    import shutil

    out = tmp_path / "other"
    shutil.copytree(uninterrupted, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def refused(r, *words):
        assert r.returncode == 2
        err = r.stderr.strip().splitlines()
        assert len(err) == 1 and all(w in err[0] for w in words), r.stderr
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before

    # another seed, another population, another requirement in the file
    refused(_design(out, *SIZE, "--seed", "2", "--resume"), "another requirement")
    refused(_design(out, "--population", "24", "--generations", "8", "--resume"),
            "another requirement")
    changed = design_file(tmp_path, requirements={"first_resonance": 101.0})
    refused(cli("design", changed, "--out", out, *SIZE, "--resume"),
            "another requirement")
    # damaged: not an NPZ, a pickled array in it, generations out of order
    path = out / CP.CHECKPOINT_FILE
    good = path.read_bytes()
    path.write_bytes(good[: len(good) // 2])
    before[CP.CHECKPOINT_FILE] = path.read_bytes()
    refused(_design(out, *SIZE, "--resume"), "not a design checkpoint")
    with np.load(io.BytesIO(good), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for bad, why in ((dict(arrays, X=arrays["X"].astype(object)), "not a design checkpoint"),
                     (dict(arrays, generation=arrays["generation"][::-1].copy()), "out of form")):
        buf = io.BytesIO()
        np.savez(buf, **bad)
        path.write_bytes(buf.getvalue())
        before[CP.CHECKPOINT_FILE] = path.read_bytes()
        refused(_design(out, *SIZE, "--resume"), why)
    meta = json.loads(str(arrays["meta"]))
    buf = io.BytesIO()
    np.savez(buf, **dict(arrays, meta=np.array(json.dumps({**meta, "pymoo": "0.0"}))))
    path.write_bytes(buf.getvalue())
    before[CP.CHECKPOINT_FILE] = path.read_bytes()
    refused(_design(out, *SIZE, "--resume"), "pymoo")
    # none at all
    empty = tmp_path / "empty"
    r = _design(empty, *SIZE, "--resume")
    assert r.returncode == 2 and "no checkpoint to resume from" in r.stderr
    assert not empty.exists()


def test_the_requirements_hash_holds_every_motion_sample():
    """Two loads of a requirement hash alike; one sample of a motion to fly changed deep inside
    (where a printed array shows '...') changes it, and so does the seed, not the generations."""
    from dataclasses import replace

    path = EXAMPLE.parent / "motion_simulator.toml"
    spec = S.load(path)
    assert CP.requirement_hash(spec) == CP.requirement_hash(S.load(path))
    m = spec.flight.motions[0]
    assert m.q.size > np.get_printoptions()["threshold"]   # printed, it would be summarised
    q = m.q.copy()
    q[len(q) // 2, 2] += 1e-9
    moved = replace(spec, flight=replace(spec.flight, motions=(replace(m, q=q),
                                                               *spec.flight.motions[1:])))
    assert CP.requirement_hash(moved) != CP.requirement_hash(spec)
    assert CP.requirement_hash(S.with_search(spec, seed=spec.search.seed + 1)) \
        != CP.requirement_hash(spec)
    assert CP.requirement_hash(S.with_search(spec, generations=spec.search.generations + 1)) \
        == CP.requirement_hash(spec)
