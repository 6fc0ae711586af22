"""Poses in the frames a user thinks in (native/src/frames.c does the arithmetic).

A pose q = (x, y, z, thx, thy, thz) of the contract is C's origin in N and R = Rz Ry Rx. The
scene's [frames] (stewart_fmu/scene_reach.py) names three more frames a pose may be given in:

- pivot: the pivot point's position in N, and C's angles (rotations about the pivot);
- tool: the tool frame's pose in N (a pose on the platform, in C; default the pivot, axes of C);
- user: the tool frame's pose in the user frame (a pose on the base, in N).

A pose in a frame whose rotations are zero keeps its angles exactly; positions round trip to a
few units in the last place of the largest of the pose's and the frames' coordinates.

Motions (a trajectory's poses with their rates and accelerations, the angles' being Euler-angle
rates) convert with motion_to_platform / motion_from_platform: the frame's point moves as a
point of the rigid platform and its Euler rates are those of its angles (stewart.h,
stewart_frame_motion_from_platform).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .errors import StewartError
from .io import POSE
from .native import core
from .reach_params import FRAME_NAMES, FrameParams

_ZERO6 = np.zeros(6)


def default_frame(model) -> str:
    """The frame poses are given in when a command is not told: the scene's [frames] default."""
    return model.frames.default if model.frames is not None else "platform"


def chosen_frame(model, frame: str | None) -> str:
    """`frame` (a command's --frame), or the scene's default when None; StewartError naming an
    unknown frame."""
    frame = default_frame(model) if frame is None else frame
    frame_change(model, frame)
    return frame


def frame_change(model, frame: str) -> np.ndarray | None:
    """The frame's (mov, fix) of frames.c, 12 doubles (None: the platform's own pose);
    StewartError naming an unknown frame."""
    if frame not in FRAME_NAMES:
        raise StewartError(f"frame {frame!r}: unknown frame (known: {', '.join(FRAME_NAMES)})")
    if frame == "platform":
        return None
    f = model.frames if model.frames is not None else FrameParams()
    if frame == "pivot":
        mov, fix = np.array([*f.pivot, 0.0, 0.0, 0.0]), _ZERO6
    else:
        mov = f.tool_pose
        fix = np.asarray(f.user, dtype=float) if frame == "user" else _ZERO6
    return np.ascontiguousarray(np.concatenate([mov, fix]), dtype=float)


def _convert(fn, model, poses, frame: str) -> np.ndarray:
    change = frame_change(model, frame)
    arr = np.ascontiguousarray(poses, dtype=float)
    if change is None:
        return arr.copy()
    flat = arr.reshape(-1, 6)
    out = np.empty_like(flat)
    b = core.ffi.from_buffer
    fn(b(change[:6]), b(change[6:]), flat.shape[0], b(flat), b(out))
    return out.reshape(arr.shape)


def to_platform(model, poses, frame: str) -> np.ndarray:
    """The contract's poses q (N, 6) (or (6,)) of poses given in `frame`."""
    return _convert(core.lib.stewart_frame_to_platform, model, poses, frame)


def from_platform(model, poses, frame: str) -> np.ndarray:
    """The poses q (N, 6) (or (6,)) of the contract written in `frame`."""
    return _convert(core.lib.stewart_frame_from_platform, model, poses, frame)


class Motion(NamedTuple):
    """Poses with their rates and accelerations, each (N, 6) in the contract's columns (the
    angles' rates are Euler-angle rates); qdd None: no accelerations."""
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray | None


def _motion(fn, model, q, qd, qdd, frame: str) -> Motion:
    change = frame_change(model, frame)
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (q, qd, qdd) if a is not None]
    if len({a.shape for a in arrays}) != 1 or arrays[0].shape[-1:] != (6,):
        raise ValueError("motion: q, qd and qdd must be arrays (N, 6) (or (6,)) of one shape")
    shape = arrays[0].shape
    arrays = [a.reshape(-1, 6) for a in arrays]
    if change is None:
        outs = [a.copy() for a in arrays]
        return Motion(*(o.reshape(shape) for o in outs), *([None] if qdd is None else []))
    outs = [np.empty_like(a) for a in arrays]
    b = core.ffi.from_buffer
    acc_in, acc_out = (b(arrays[2]), b(outs[2])) if qdd is not None else (core.ffi.NULL,) * 2
    done = fn(b(change[:6]), b(change[6:]), arrays[0].shape[0], b(arrays[0]), b(arrays[1]),
              acc_in, b(outs[0]), b(outs[1]), acc_out)
    if done < 0:
        k = -done - 1
        raise StewartError(f"sample {k}: the {frame} frame's conversion meets gimbal lock "
                           "(|cos thy| ~ 0): its Euler-angle rates are not defined")
    outs = [o.reshape(shape) for o in outs]
    return Motion(outs[0], outs[1], outs[2] if qdd is not None else None)


def motion_to_platform(model, q, qd, qdd, frame: str) -> Motion:
    """The contract's motion (C in N) of a motion given in `frame` (q, qd, qdd (N, 6); qdd may
    be None); StewartError naming an unknown frame or the first sample at gimbal lock."""
    return _motion(core.lib.stewart_frame_motion_to_platform, model, q, qd, qdd, frame)


def motion_from_platform(model, q, qd, qdd, frame: str) -> Motion:
    """The motion in `frame` of the contract's motion (C in N): q, qd, qdd (N, 6), qdd may be
    None; StewartError naming an unknown frame or the first sample at gimbal lock."""
    return _motion(core.lib.stewart_frame_motion_from_platform, model, q, qd, qdd, frame)


def table_from_platform(model, table: np.ndarray, frame: str) -> np.ndarray:
    """A copy of a named table (stewart_fmu.io.named_array) whose poses are C's, written in
    `frame`: each pose x..thz (and x_ref..thz_ref) with its rates dx..dthz and accelerations
    ddx..ddthz when the table has them (d/dd before the name, the suffix kept); every other
    column as it is."""
    return _table(model, table, frame, from_platform, motion_from_platform)


def table_to_platform(model, table: np.ndarray, frame: str) -> np.ndarray:
    """The inverse of table_from_platform: a copy of a table whose poses (and their rates and
    accelerations) are given in `frame`, with C's in their columns."""
    return _table(model, table, frame, to_platform, motion_to_platform)


def _table(model, table: np.ndarray, frame: str, poses, motions) -> np.ndarray:
    frame_change(model, frame)
    out = table.copy()
    if frame == "platform":
        return out
    names = table.dtype.names
    for suffix in ("", "_ref"):
        groups = [[p + c + suffix for c in POSE] for p in ("", "d", "dd")]
        present = []            # the pose, then its rates, then their accelerations
        for g in groups:
            if not all(c in names for c in g):
                break
            present.append(g)
        if not present:
            continue
        cols = [np.column_stack([table[c] for c in g]).astype(float) for g in present]
        if len(cols) == 1:
            converted = [poses(model, cols[0], frame)]
        else:
            converted = motions(model, cols[0], cols[1], cols[2] if len(cols) > 2 else None,
                                frame)
        for g, arr in zip(present, converted):
            for k, c in enumerate(g):
                out[c] = arr[:, k]
    return out
