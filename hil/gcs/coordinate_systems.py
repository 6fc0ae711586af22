"""PI's coordinate systems on the twin: KSW (work), KST (tool), KSD (directed), KLN (linking),
KEN (enabling), KET? and KLT?; the root ZERO is the system of hil.gcs.axes.

A coordinate system is a pose in GCS units (X Y Z mm, U V W deg, PI's rotation order) relative
to its parent (ZERO unless KLN links it to another of its kind): a work system (KSW) is fixed in
space, in its parent's coordinates; a tool system (KST) is fixed to the platform, relative to
its parent tool (ZERO's tool: the pivot point with the platform's axes). With a work system W
and a tool system M enabled (at most one of each; KEN ZERO disables both), POS?, MOV and every
axis value are the pose of M seen from W:

    T_f = T_W^-1 T_z T_M

(T_z: the ZERO coordinates of hil.gcs.axes.Frame; each chain composed into one pose). The
arithmetic is stewart_fmu.frames' (native/src/frames.c: a moving frame fixed to the platform
seen from a fixed frame), on the ZERO coordinates as the pose and the chains as its tool and
user frames; the angles are turned between PI's order and the contract's at the boundary.

A directed system D (KSD: X Y Z a point relative to the platform, U V W the turn of its axes)
is a work and a tool system that coincide while the platform is at ZERO: enabled, it is both W
and M (T_f = T_D^-1 T_z T_D), so POS? reads 0 at ZERO and U V W turn about D's origin along
D's axes. It replaces an enabled work and tool system, and they it (docs/guides/gcs-twin.md
names the sources and what is the twin's choice).
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import numpy as np

from hil.gcs import errors as E
from hil.gcs.axes import (MM_PER_M, Frame, contract_angles, contract_matrices, gcs_angles,
                          gcs_matrices)
from stewart_fmu.frames import from_platform, to_platform
from stewart_fmu.reach_params import FrameParams

ZERO = "ZERO"
WORK, TOOL, DIRECTED = "KSW", "KST", "KSD"
TYPES = (WORK, TOOL, DIRECTED)
MAX_SYSTEMS = 32            # defined systems besides ZERO
VALUE_MAX = (1000.0,) * 3 + (360.0,) * 3    # mm, deg: the largest |value| of a definition
_NAME = re.compile(r"[A-Z][A-Z0-9_]{0,15}\Z")


@dataclass
class System:
    kind: str
    values: np.ndarray          # (6,) mm and deg, relative to the parent
    parent: str = ZERO


def to_contract(g: np.ndarray) -> np.ndarray:
    """GCS poses (N, 6) (mm, deg, PI's order) as contract poses (m, rad, Rz Ry Rx)."""
    g = np.atleast_2d(g)
    return np.concatenate([g[:, :3] / MM_PER_M,
                           contract_angles(gcs_matrices(*np.radians(g[:, 3:]).T))], axis=1)


def to_gcs(q: np.ndarray) -> np.ndarray:
    """Contract poses (N, 6) as GCS poses (the inverse of to_contract, |V| < 90 deg)."""
    q = np.atleast_2d(q)
    return np.concatenate([q[:, :3] * MM_PER_M,
                           np.degrees(gcs_angles(contract_matrices(*q[:, 3:].T)))], axis=1)


class Enabled:
    """The ZERO frame seen through an enabled work W and tool M (both GCS poses relative to
    ZERO): hil.gcs.axes.Frame's interface (to_pose, from_pose, placements) in T_f's units."""

    def __init__(self, zero: Frame, model, work: np.ndarray, tool: np.ndarray) -> None:
        self.zero, self.pivot = zero, zero.pivot
        self.work, self.tool = np.array(work, dtype=float), np.array(tool, dtype=float)
        w, m = to_contract(work)[0], to_contract(tool)[0]
        self._frames = dataclasses.replace(model, frames=FrameParams(user=tuple(w),
                                                                     tool=tuple(m)))

    def _to_zero(self, g: np.ndarray) -> np.ndarray:
        return to_gcs(to_platform(self._frames, to_contract(g), "user"))

    def to_pose(self, g: np.ndarray) -> np.ndarray:
        q = self.zero.to_pose(self._to_zero(g))
        return q if np.ndim(g) == 2 else q[0]

    def from_pose(self, q: np.ndarray) -> np.ndarray:
        z = np.atleast_2d(self.zero.from_pose(q))
        g = to_gcs(from_platform(self._frames, to_contract(z), "user"))
        return g if np.ndim(q) == 2 else g[0]

    def placements(self, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.zero.placements(self._to_zero(np.atleast_2d(g)))


class Systems:
    """The defined systems, their links and which are enabled (see the module doc)."""

    def __init__(self) -> None:
        self.systems: dict[str, System] = {}
        self.enabled: dict[str, str] = {}       # kind -> name

    def define(self, kind: str, name: str, pairs: list[tuple[int, float]]) -> None:
        """KSW/KST: a new system, or new values of one not enabled (its other values kept)."""
        name = self.checked_name(name)
        if name == ZERO:
            raise E.GcsError(E.CS_WRITE_PROTECTED, "ZERO")
        old = self.systems.get(name)
        if old is not None and old.kind != kind:
            raise E.GcsError(E.CS_IN_USE, f"{name} is a {old.kind}")
        if name in self.in_use():
            raise E.GcsError(E.CS_IN_USE, f"{name} is enabled or in an enabled chain")
        if old is None and len(self.systems) >= MAX_SYSTEMS:
            raise E.GcsError(E.CS_UNUSED_MUST_BE_DELETED, f"{MAX_SYSTEMS} systems defined")
        values = np.zeros(6) if old is None else old.values.copy()
        for i, v in pairs:
            if not abs(v) <= VALUE_MAX[i]:
                raise E.GcsError(E.PARAM_OUT_OF_RANGE, f"value {i} beyond {VALUE_MAX[i]}")
            values[i] = v
        if abs(values[4]) >= 90.0:
            raise E.GcsError(E.PARAM_OUT_OF_RANGE, "V at +-90 deg or beyond (gimbal lock)")
        self.systems[name] = System(kind, values, ZERO if old is None else old.parent)

    def link(self, child: str, parent: str) -> None:
        """KLN: `parent` becomes `child`'s parent (ZERO or a system of the same kind)."""
        child, parent = self.existing(child), self.existing(parent)
        if child == ZERO:
            raise E.GcsError(E.CS_WRITE_PROTECTED, "ZERO")
        if child == parent:
            raise E.GcsError(E.CS_LINKED_TO_ITSELF, child)
        if parent != ZERO and self.systems[parent].kind != self.systems[child].kind:
            raise E.GcsError(E.CS_MAY_NOT_BE_LINKED, f"{child} to {parent}")
        if child in self.in_use():
            raise E.GcsError(E.CS_IN_USE, child)
        if child in self.chain(parent):
            raise E.GcsError(E.CS_CYCLIC, f"{child} to {parent}")
        self.systems[child].parent = parent

    def enable(self, name: str) -> None:
        """KEN: enable a system (replacing the enabled one of its kind); ZERO disables all. A
        directed system is a work and a tool system at once: it replaces both, and they it."""
        name = self.existing(name)
        if name == ZERO:
            self.enabled.clear()
            return
        kind = self.systems[name].kind
        if kind == DIRECTED:
            self.enabled.clear()
        else:
            self.enabled.pop(DIRECTED, None)
        self.enabled[kind] = name

    def remove(self, name: str) -> None:
        """KRM: a system neither in use nor a parent."""
        name = self.existing(name)
        if name == ZERO:
            raise E.GcsError(E.CS_WRITE_PROTECTED, "ZERO")
        if name in self.in_use() or any(s.parent == name for s in self.systems.values()):
            raise E.GcsError(E.CS_IN_USE, name)
        del self.systems[name]

    def chain(self, name: str) -> list[str]:
        """`name` and its ancestors up to (without) ZERO."""
        out: list[str] = []
        while name != ZERO and len(out) <= MAX_SYSTEMS:
            out.append(name)
            name = self.systems[name].parent
        return out

    def in_use(self) -> set[str]:
        return {n for e in self.enabled.values() for n in self.chain(e)}

    def composed(self, name: str, end: str = ZERO) -> np.ndarray:
        """The pose (GCS, relative to `end`) of `name`'s chain from `name` up to `end` (error 542
        when `end` is not on it)."""
        chain = self.chain(name)
        if end != ZERO:
            if end not in chain:
                raise E.GcsError(E.CS_NOT_SAME_CHAIN, f"{name} and {end}")
            chain = chain[:chain.index(end)]
        r, p = np.eye(3), np.zeros(3)
        for n in chain:                     # T = T_parent ... T_n: apply from the top down
            v = self.systems[n].values
            rn = gcs_matrices(*np.radians(v[3:]))[0]
            p, r = v[:3] + rn @ p, rn @ r
        return np.concatenate([p, np.degrees(gcs_angles(r[None])[0])])

    def frame(self, zero: Frame, model) -> Frame | Enabled:
        """The frame POS? and MOV speak in: ZERO's, or the enabled work and tool's."""
        if not self.enabled:
            return zero
        if DIRECTED in self.enabled:
            pose = self.composed(self.enabled[DIRECTED])
            return Enabled(zero, model, pose, pose)
        work = self.composed(self.enabled[WORK]) if WORK in self.enabled else np.zeros(6)
        tool = self.composed(self.enabled[TOOL]) if TOOL in self.enabled else np.zeros(6)
        return Enabled(zero, model, work, tool)

    def existing(self, name: str) -> str:
        name = self.checked_name(name)
        if name != ZERO and name not in self.systems:
            raise E.GcsError(E.CS_DOES_NOT_EXIST, name)
        return name

    @staticmethod
    def checked_name(name: str) -> str:
        up = name.upper()
        if not _NAME.match(up):
            raise E.GcsError(E.CS_INVALID_NAME, name[:20])
        return up
