"""The plants the co-simulation master can drive (`PlantPort`): the in-process component
(stewart_fmu.plant.Plant) and an exported FMU through fmpy. Both see the same calls."""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Protocol

import numpy as np

from stewart_fmu.errors import StewartError
from stewart_fmu.fmu.variables import VR_L, VR_LDOT, VR_Q, VR_Q0, VR_QD0, VR_SIGMA, VR_TAU
from stewart_fmu.integrators import IntegratorOptions
from stewart_fmu.model import Model
from stewart_fmu.plant import Plant, StepRejected


class PlantStepError(StewartError):
    """The plant refused a step (stroke, singularity) during a closed-loop run."""


class PlantPort(Protocol):
    """What the master needs of a plant."""

    def start(self, q0: np.ndarray, qd0: np.ndarray, t0: float,
              torque0: np.ndarray) -> None: ...  # torque0: held from the start
    def step(self, t: float, h: float, torque: np.ndarray) -> None: ...
    def measure(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...  # l, ldot, q


class InProcessPlant:
    """stewart_fmu.plant.Plant behind the PlantPort calls."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None):
        self.plant = Plant(model, options)

    def start(self, q0, qd0, t0, torque0) -> None:
        self.plant.setup_experiment(t0)
        self.plant.enter_initialization_mode()
        self.plant.set_initial(q0, qd0)
        self.plant.set_torque(torque0)
        self.plant.exit_initialization_mode()

    def step(self, t, h, torque) -> None:
        self.plant.set_torque(torque)
        try:
            self.plant.do_step(t, h)
        except StepRejected as exc:
            raise PlantStepError(str(exc)) from None

    def measure(self):
        out = self.plant.outputs
        return out.lengths, out.rates, out.q


class FmuPlant:
    """The exported FMU driven through fmpy's FMU2Slave."""

    def __init__(self, path: str | Path):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(str(path))
        self.unzipdir = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName="plant")
        six = range(6)  # value references of the one table (stewart_fmu.fmu.variables)
        self.vr_tau, self.vr_q0, self.vr_qd0 = ([base + i for i in six]
                                                for base in (VR_TAU, VR_Q0, VR_QD0))
        self.vr_out = [base + i for base in (VR_L, VR_LDOT, VR_Q) for i in six]
        self.vr_sigma = [VR_SIGMA + i for i in six]

    def start(self, q0, qd0, t0, torque0) -> None:
        f = self.fmu
        f.instantiate()
        f.setupExperiment(startTime=t0)
        f.enterInitializationMode()
        f.setReal(self.vr_q0, list(map(float, q0)))
        f.setReal(self.vr_qd0, list(map(float, qd0)))
        f.setReal(self.vr_tau, list(map(float, torque0)))
        # the controllers drive the torques alone: the rack-force inputs, which start at the
        # force holding home (for importers that set nothing), are zeroed
        f.setReal(self.vr_sigma, [0.0] * 6)
        f.exitInitializationMode()

    def step(self, t, h, torque) -> None:
        from fmpy.fmi1 import FMICallException

        self.fmu.setReal(self.vr_tau, list(map(float, torque)))
        try:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        except FMICallException as exc:
            raise PlantStepError(f"FMU refused the step at t = {t!r} s: {exc}") from None

    def measure(self):
        v = np.array(self.fmu.getReal(self.vr_out))
        return v[:6], v[6:12], v[12:18]

    def close(self) -> None:
        """Terminate, free the instance and delete the unzipped FMU."""


        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipdir, ignore_errors=True)
