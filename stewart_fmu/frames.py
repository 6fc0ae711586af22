"""Poses in the frames a user thinks in (native/src/frames.c does the arithmetic).

A pose q = (x, y, z, thx, thy, thz) of the contract is C's origin in N and R = Rz Ry Rx. The
scene's [frames] (stewart_fmu/scene_reach.py) names three more frames a pose may be given in:

- pivot: the pivot point's position in N, and C's angles (rotations about the pivot);
- tool: the tool frame's pose in N (a pose on the platform, in C; default the pivot, axes of C);
- user: the tool frame's pose in the user frame (a pose on the base, in N).

A pose in a frame whose rotations are zero keeps its angles exactly; positions round trip to a
few units in the last place of the largest of the pose's and the frames' coordinates.
"""
from __future__ import annotations

import numpy as np

from .errors import StewartError
from .native import core
from .reach_params import FRAME_NAMES, FrameParams

_ZERO6 = np.zeros(6)


def default_frame(model) -> str:
    """The frame poses are given in when a command is not told: the scene's [frames] default."""
    return model.frames.default if model.frames is not None else "platform"


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
