"""The immutable model: parameters built once from a scene (MuJoCo's mjModel, Pinocchio's Model).

Only the bodies and effects the scene declares are present: `legs`, `drive`, `friction` and
`transmission` are None when their table is absent, and the compiled kernels then skip that
work entirely.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .native.core import NativeParams
from .reach_params import ClearanceParams, FrameParams, JointParams, pack_reach
from .table import ELASTIC, N_ELASTIC, N_PARAMS, offset

# Layout of Model.params, the flat float64 vector the compiled kernels read: the offsets of
# the table (native/include/stewart_table.h, STEWART_PARAMS), read from the core.
P_HAS_LEGS, P_HAS_DRIVE, P_HAS_FRICTION = offset("HAS_LEGS"), offset("HAS_DRIVE"), offset("HAS_FRICTION")
P_GRAVITY = offset("GRAVITY")
P_MASS, P_INERTIA = offset("MASS"), offset("INERTIA")
P_LOWER, P_UPPER = offset("LOWER"), offset("UPPER")      # mass, com, transverse, axial
P_DRIVE_MASS = offset("DRIVE_MASS")                      # reflected drive inertia m_d
P_VISCOUS, P_COULOMB = offset("VISCOUS"), offset("COULOMB")
P_LEG_MIN, P_LEG_MAX = offset("LEG_MIN"), offset("LEG_MAX")
P_CHAR_LENGTH = offset("CHAR_LENGTH")
P_BASE, P_PLATFORM = offset("BASE"), offset("PLATFORM")
P_HAS_TRANSMISSION = offset("HAS_TRANSMISSION")
P_STIFFNESS, P_DAMPING = offset("STIFFNESS"), offset("DAMPING")
P_HAS_PAYLOAD, P_PAYLOAD_MASS = offset("HAS_PAYLOAD"), offset("PAYLOAD_MASS")
P_PAYLOAD_COM, P_PAYLOAD_INERTIA = offset("PAYLOAD_COM"), offset("PAYLOAD_INERTIA")


@dataclass(frozen=True)
class LegParams:
    """Both rigid parts of every leg (the same for all six legs)."""

    lower_mass: float
    lower_com: float
    lower_inertia: tuple[float, float]  # (transverse, axial) about the part's CoM
    upper_mass: float
    upper_com: float
    upper_inertia: tuple[float, float]


def rack_ratio(gear_ratio: float, pinion_radius: float) -> float:
    """zeta / r (1/m): rack force per motor torque, and motor speed per rack speed."""
    return gear_ratio / pinion_radius


PerLeg = float | tuple[float, ...]   # one value for all six legs, or six (legs 1..6)


def per_leg(value: PerLeg) -> np.ndarray:
    """The six legs' values of a per-leg parameter, (6,) float64."""
    return np.broadcast_to(np.asarray(value, dtype=float), (6,)).copy()


def is_per_leg(value: PerLeg) -> bool:
    """Whether the scene gave six values (else one for all legs)."""
    return np.ndim(value) == 1


@dataclass(frozen=True)
class DriveParams:
    """Servomotor, gearbox and rack-and-pinion of every leg; the rotor inertia per leg (six
    values) or one for all."""

    gear_ratio: float
    rotor_inertia: PerLeg
    pinion_radius: float

    @property
    def force_per_torque(self) -> float:
        """zeta / r: the rack force a motor torque gives (N per N m)."""
        return rack_ratio(self.gear_ratio, self.pinion_radius)

    @property
    def reflected_masses(self) -> np.ndarray:
        """m_d,i = zeta^2 I_i / r^2 of the six legs (Eq. 14 with the paper's typo corrected)."""
        return self.gear_ratio**2 * per_leg(self.rotor_inertia) / self.pinion_radius**2

    @property
    def reflected_mass(self) -> float:
        """One leg's m_d: the largest of the six (all of them when the scene gives one rotor
        inertia); what a single axis model takes (controller.drive.axis_model)."""
        return float(np.max(self.reflected_masses))


@dataclass(frozen=True)
class FrictionParams:
    """Viscous and Coulomb friction of the prismatic joints: per leg (six values) or one for
    all, as the scene gives them."""

    viscous: PerLeg
    coulomb: PerLeg

    @property
    def viscous_legs(self) -> np.ndarray:
        """The six legs' viscous friction (N s/m)."""
        return per_leg(self.viscous)

    @property
    def coulomb_legs(self) -> np.ndarray:
        """The six legs' Coulomb friction (N)."""
        return per_leg(self.coulomb)


@dataclass(frozen=True)
class TransmissionParams:
    """Compliant transmission between each motor and its leg, reflected to the leg axis."""

    stiffness: float   # N / m
    damping: float     # N s / m


@dataclass(frozen=True)
class StiffnessParams:
    """[stiffness]: the legs' axial springs (per leg) and the joints' flexure stiffness
    (stewart_table.h STEWART_ELASTIC says how they combine)."""

    leg: PerLeg                       # N/m between the joints
    joint_bending: float | None = None   # N m/rad, each joint; None: ball joints
    joint_torsion: float | None = None   # N m/rad, each joint about the leg; None: free

    @property
    def leg_legs(self) -> np.ndarray:
        """The six legs' axial stiffness (N/m)."""
        return per_leg(self.leg)


@dataclass(frozen=True)
class PayloadParams:
    """[payload]: a rigid body fixed to the platform."""

    mass: float                 # kg
    com: tuple[float, float, float]          # m, in C
    inertia: tuple[float, ...]  # kg m^2 about its com in C: Ixx, Iyy, Izz (, Ixy, Ixz, Iyz)

    @property
    def inertia_tensor(self) -> np.ndarray:
        """The symmetric 3x3 inertia tensor about the payload's com, in C's axes."""
        i = np.zeros(6)
        i[:len(self.inertia)] = self.inertia
        return np.array([[i[0], i[3], i[4]], [i[3], i[1], i[5]], [i[4], i[5], i[2]]])


@dataclass(frozen=True)
class Model:
    """Immutable parameters of one Stewart mechanism."""

    name: str
    gravity: np.ndarray          # (3,) in N
    base_joints: np.ndarray      # (6, 3) a_i in N
    platform_joints: np.ndarray  # (6, 3) p_i in C
    home: np.ndarray             # (6,) pose
    leg_min: float | None
    leg_max: float | None
    platform_mass: float
    platform_inertia: np.ndarray  # (3,) principal moments in C
    legs: LegParams | None
    drive: DriveParams | None
    friction: FrictionParams | None
    extra: Mapping[str, Any] = field(default_factory=dict)  # project tables (controller, ...)
    source: str | None = None
    transmission: TransmissionParams | None = None   # project table [transmission]
    joints: JointParams | None = None          # [joints]: the joints' cones (reach_params.py)
    clearance: ClearanceParams | None = None   # [clearance]: leg capsules, obstacles
    frames: FrameParams | None = None          # [frames]: pivot point, user and tool frames
    stiffness: StiffnessParams | None = None   # [stiffness]: the legs' and joints' springs
    payload: PayloadParams | None = None       # [payload]: a body fixed to the platform (in params)
    params: np.ndarray = field(init=False, repr=False)
    reach: np.ndarray = field(init=False, repr=False)   # packed reach vector (reach.c)
    native: NativeParams = field(init=False, repr=False, compare=False)  # params for the C core
    # [stiffness] and [payload] for the stiffness and modes kernels (STEWART_ELASTIC layout)
    elastic: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("gravity", "base_joints", "platform_joints", "home", "platform_inertia"):
            arr = np.array(getattr(self, name), dtype=float)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "extra", MappingProxyType(dict(self.extra)))
        object.__setattr__(self, "params", _pack(self))
        object.__setattr__(self, "native", NativeParams(self.params))
        object.__setattr__(self, "reach", pack_reach(self.params, self.home, self.joints,
                                                     self.clearance))
        object.__setattr__(self, "elastic", _pack_elastic(self))

    @property
    def characteristic_length(self) -> float:
        """Mean platform-joint radius: makes the Jacobian's rotational columns metres."""
        return float(np.mean(np.linalg.norm(self.platform_joints, axis=1)))

    @property
    def effects(self) -> tuple[str, ...]:
        """The optional effects this model computes."""
        return tuple(n for n in ("legs", "drive", "friction", "transmission")
                     if getattr(self, n) is not None)

    @property
    def state_size(self) -> int:
        """Length of the plant's state: (q, qd), plus the motor side (s, sd) with a transmission."""
        return 24 if self.transmission is not None else 12


def _pack(m: Model) -> np.ndarray:
    """Flatten the model into the kernels' parameter vector (see the P_* layout)."""
    p = np.zeros(N_PARAMS)
    p[P_HAS_LEGS] = m.legs is not None
    p[P_HAS_DRIVE] = m.drive is not None
    p[P_HAS_FRICTION] = m.friction is not None
    p[P_GRAVITY:P_GRAVITY + 3] = m.gravity
    p[P_MASS] = m.platform_mass
    p[P_INERTIA:P_INERTIA + 3] = m.platform_inertia
    if m.legs is not None:
        lg = m.legs
        p[P_LOWER:P_LOWER + 4] = (lg.lower_mass, lg.lower_com, *lg.lower_inertia)
        p[P_UPPER:P_UPPER + 4] = (lg.upper_mass, lg.upper_com, *lg.upper_inertia)
    if m.drive is not None:
        p[P_DRIVE_MASS:P_DRIVE_MASS + 6] = m.drive.reflected_masses
    if m.friction is not None:
        p[P_VISCOUS:P_VISCOUS + 6] = m.friction.viscous_legs
        p[P_COULOMB:P_COULOMB + 6] = m.friction.coulomb_legs
    if m.transmission is not None:
        p[P_HAS_TRANSMISSION] = 1.0
        p[P_STIFFNESS], p[P_DAMPING] = m.transmission.stiffness, m.transmission.damping
    if m.payload is not None:
        p[P_HAS_PAYLOAD], p[P_PAYLOAD_MASS] = 1.0, m.payload.mass
        p[P_PAYLOAD_COM:P_PAYLOAD_COM + 3] = m.payload.com
        p[P_PAYLOAD_INERTIA:P_PAYLOAD_INERTIA + len(m.payload.inertia)] = m.payload.inertia
    p[P_LEG_MIN] = m.leg_min if m.leg_min is not None else 0.0
    p[P_LEG_MAX] = m.leg_max if m.leg_max is not None else np.inf
    p[P_CHAR_LENGTH] = m.characteristic_length
    p[P_BASE:P_BASE + 18] = m.base_joints.ravel()
    p[P_PLATFORM:P_PLATFORM + 18] = m.platform_joints.ravel()
    p.flags.writeable = False
    return p


def _pack_elastic(m: Model) -> np.ndarray:
    """[stiffness] as the stiffness kernels read it (STEWART_ELASTIC; the payload is in params)."""
    e = np.zeros(N_ELASTIC)

    def put(name: str, value) -> None:
        entry = ELASTIC[name]
        e[entry.offset:entry.offset + entry.count] = value

    if m.stiffness is not None:
        s = m.stiffness
        put("HAS_STIFFNESS", 1.0)
        put("LEG", s.leg_legs)
        put("BENDING", s.joint_bending or 0.0)
        put("TORSION", s.joint_torsion or 0.0)
    e.flags.writeable = False
    return e
