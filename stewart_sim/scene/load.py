"""A scene read once, every table checked once: the Model and the typed project tables.

stewart_fmu.scene reads the file and builds the Model (the plant tables; the project tables it
only lets through); here the tables above the plant are read, checked and parsed, once, by
their owners into the objects their readers take: [controller] ->
controller.config.ControllerConfig, [cueing] -> CueingConfig and OptimalOptions, [case] ->
stewart_sim.scene.case_config.Case, [solver] -> the plant's IntegratorOptions, [sensors] (what
the emulated device reports) -> hil.sensors.SensorConfig. Every command loads its scene here, so a
bad key in any table fails every command at once, with one line naming the dotted key
(SceneKeyError), before any work; the commands then pass the typed objects down.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from hil.sensors import SensorConfig, sensor_config
from stewart_fmu import table as fmu_table
from stewart_fmu.errors import SceneError, SceneKeyError, StewartError
from stewart_fmu.integrators import COMPILED, IntegratorOptions
from stewart_fmu.model import Model
from stewart_fmu.scene import load_scene
from stewart_fmu.stability import default_options
from stewart_sim.scene.case_config import Case, case_of
from stewart_sim.scene.cueing_config import CueingConfig, OptimalOptions, cueing_tables

if TYPE_CHECKING:   # the [controller] reader imports control: only when the table is there
    from controller.config import ControllerConfig

# [solver]: the in-process plant's integrator, with the names and bounds of the FMU's solver.*
# parameters (stewart_fmu.table); absent keys keep stability.default_options of the model
SOLVER_KEYS = ("method", "rtol", "atol", "max_step")


@dataclass(frozen=True)
class Scene:
    """A scene file's Model and its project tables, each parsed once (None: table absent)."""

    model: Model
    controller: "ControllerConfig | None"
    cueing: CueingConfig
    optimal: OptimalOptions
    case: "Case | None"
    solver: IntegratorOptions
    has_solver: bool = False   # the scene has a [solver] table (not only the defaults)
    sensors: SensorConfig = SensorConfig()   # [sensors]: read by the device only (hil.sensors)

    def require_controller(self) -> "ControllerConfig":
        """The [controller] table (SceneError when the scene has none)."""
        if self.controller is None:
            raise SceneError("controller", "the scene has no [controller] table (motor and "
                                           "design targets): see controller/config.py",
                             self.model.source)
        return self.controller

    def require_case(self) -> "Case":
        """The [case] table (StewartError when the scene has none)."""
        if self.case is None:
            raise StewartError(f"scene {self.model.source or self.model.name} has no [case] "
                               "table")
        return self.case


def load(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scene:
    """Read the scene file once and parse every table (SceneError names the dotted key)."""
    return scene_of(load_scene(path, overrides))


def scene_of(model: Model) -> Scene:
    """The typed project tables of a Model built by stewart_fmu.scene."""
    extra = model.extra
    controller = case = None
    if "controller" in extra:
        from controller.config import controller_config

        controller = controller_config(model)
    if "case" in extra:
        case = case_of(model)
    cueing, optimal = cueing_tables(model)
    return Scene(model, controller, cueing, optimal, case, solver_options(model),
                 "solver" in extra, sensor_config(model))


def solver_options(model: Model) -> IntegratorOptions:
    """[solver] over stability.default_options(model): method (one of the compiled methods, as
    the FMU's solver.method), rtol, atol, max_step (finite, > 0)."""
    options = default_options(model)
    table = model.extra.get("solver")
    if table is None:
        return options
    if not isinstance(table, Mapping):
        raise SceneKeyError("solver", f"must be a table, got {table!r}", model.source)
    for key in sorted(set(table) - set(SOLVER_KEYS)):
        raise SceneKeyError(f"solver.{key}", f"unknown key (allowed: {sorted(SOLVER_KEYS)})",
                            model.source)
    values: dict[str, Any] = {}
    for key in SOLVER_KEYS[1:]:
        if key in table:
            x = table[key]
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) \
                    or x <= 0:
                raise SceneKeyError(f"solver.{key}", f"must be a finite number > 0, got {x!r}",
                                    model.source)
            beyond = fmu_table.bound_reason(fmu_table.SOLVER_GROUPS[key], x)   # the FMU's bounds
            if beyond is not None:
                raise SceneKeyError(f"solver.{key}", beyond, model.source)
            values[key] = float(x)
    if "method" in table:
        if table["method"] not in COMPILED:
            raise SceneKeyError("solver.method", f"must be one of {list(COMPILED)}, got "
                                f"{table['method']!r}", model.source)
        values["method"] = table["method"]
    return replace(options, **values)
