"""pytest fixtures and the session summary of worst residuals; the helpers themselves live in
tests/helpers.py (tests import them from there, never from this file)."""
from __future__ import annotations

import os

import pytest

from stewart_fmu import Model, scene_from_dict
from tests.browser import launch_browser
from tests.helpers import RESIDUALS, level_dict, level_model, scene_dict


# Files whose every test asserts what an optimiser, a threshold crossing or a convergence
# decides (identification, calibration, excitation, feasibility, the cueing's QP and envelope):
# marked `numerics`, so `make test-numerics` runs them again in a second floating-point
# environment. Single tests elsewhere carry @pytest.mark.numerics themselves.
NUMERICS_FILES = frozenset({
    "test_calibrate.py", "test_excite.py", "test_identify.py", "test_identify_estimate.py",
    "test_identify_refine.py", "test_cueing_feasibility.py", "test_cueing_optimal.py",
    "test_cueing_optimal_live.py", "test_cueing_envelope.py", "test_cueing_head.py",
    "test_size.py", "test_sweep_adaptive.py", "test_extreme_cases.py", "test_envelope_reach.py",
})


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.path.name in NUMERICS_FILES:
            item.add_marker(pytest.mark.numerics)


@pytest.fixture
def micro_dict() -> dict:
    """The micro-manipulator scene as tomllib parses it (a fresh copy per test)."""
    return scene_dict("micro")


@pytest.fixture
def sim_dict() -> dict:
    """The motion-simulator scene as tomllib parses it (a fresh copy per test)."""
    return scene_dict("sim")


@pytest.fixture
def micro_model() -> Model:
    """The full micro-manipulator Model."""
    return level_model("micro", "full")


@pytest.fixture
def sim_model() -> Model:
    """The full motion-simulator Model."""
    return level_model("sim", "full")


@pytest.fixture
def make_level():
    """Helper fixture: make_level(scene_dict, level) -> (dict with tables dropped, Model)."""
    def make(data: dict, level: str):
        d = level_dict(data, level)
        return d, scene_from_dict(d)
    return make


@pytest.fixture(scope="session")
def browser():
    """One headless Chromium (Playwright) for the session; installs Debian's chromium when
    there is none and we may (tests/browser.py), else skips the test saying why."""
    with launch_browser() as b:
        yield b


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not os.environ.get("STEWART_RESIDUALS") or not RESIDUALS:
        return
    tr = terminalreporter
    tr.section("worst residuals (value / tolerance)")
    for name in sorted(RESIDUALS):
        worst, tol = RESIDUALS[name]
        tr.write_line(f"{name:72s} {worst:9.2e} / {tol:7.0e}")
