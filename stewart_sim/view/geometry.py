"""What the 3D view draws of a scene, and where every object sits for a pose.

The mechanism is drawn as the contract describes it (docs/conventions.md): a base plate through
the base joints a_i, a platform plate through the platform joints p_i (in C, moved by the pose
q = (x, y, z, thx, thy, thz), R = Rz Ry Rx), and each leg as its two rigid parts: the cylinder
(lower part A_i) from a_i along u_i and the piston (upper part B_i) from the platform joint
x + R p_i back along u_i.

Part lengths (the scene gives none, so this is the view's choice, to scale with the stroke):
the cylinder is `leg_min` long (the retracted leg: the body's length) and the piston is the
stroke `leg_max - leg_min` long, so the two parts just meet at full extension and the piston's
lower end shows how much stroke is used. A scene without stroke limits gets 0.75 and 1.25 times
its home leg lengths as the limits for this purpose.

Specific-force arrows (a cueing run's, or a live cueing loop's): the vehicle's and the one the
platform delivers, each a vector in the platform frame felt at the pilot's head (the scene's
[cueing] head), drawn from the head point x + R head along R f, `arrow_scale` metres per m/s^2:
a shaft (a cylinder of unit length, stretched) and a cone of `arrow_tip` at its end.

Frames (when the scene has [frames], stewart_fmu.frames): the pivot point, a sphere at
x + R pivot on the platform; the tool frame's triad at x + R t_tool, axes R R_tool (moving with
the platform); the user frame's triad at its pose on the base (fixed). A triad is three
cylinders of `frames["axis_length"]` from its origin along its x, y and z axes.

The page (stewart_sim/view/page.js) computes the same transforms per frame; `object_transforms`
and `arrow_transforms` are the references the browser tests hold it to. Every matrix is 4x4, homogeneous, in N (metres),
for meshcat's objects, whose cylinders have their axis along their local y (three.js).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller.capability import drive_bounds
from controller.config import ControllerConfig
from stewart_fmu.kinematics import inverse_kinematics
from stewart_fmu.model import Model
from stewart_fmu.reach_params import COND_LIMIT
from stewart_fmu.rotations import euler_motion
from stewart_sim.scene.cueing_config import cueing_config
from stewart_sim.view.colours import nice_ceiling

# cond(J) (scaled, stewart_fmu.kinematics) above which a pose is marked near-singular: the
# engine's cond(J) limit, the emulated device's default SP_COND_MAX (hil.params.COND_MAX).
COND_WARN = COND_LIMIT
# A leg within this fraction of its stroke of leg_min or leg_max is marked at its limit.
STROKE_MARGIN = 0.01
# m/s^2: the arrows' scale is chosen so that a specific force of this size (about 1 g, what a
# person at rest feels) is drawn about half the platform's radius long, in a round number.
ARROW_REFERENCE = 9.81
CUES = ("f_vehicle", "f_delivered")   # the arrows' names: the snapshot's and the state's keys


@dataclass(frozen=True, eq=False)
class ViewGeometry:
    """Everything the page needs of a scene to draw it (metres, newtons)."""

    name: str
    base_joints: np.ndarray       # (6, 3) a_i in N
    platform_joints: np.ndarray   # (6, 3) p_i in C
    home: np.ndarray              # (6,) pose
    leg_min: float                # stroke limits (the scene's, or 0.75 / 1.25 x home lengths)
    leg_max: float
    stroke_limits: bool           # whether the scene declares leg_min and leg_max
    cylinder_length: float        # lower part A_i: leg_min
    piston_length: float          # upper part B_i: leg_max - leg_min
    cylinder_radius: float
    piston_radius: float
    joint_radius: float
    base_radius: float            # plate radii: through the joints, with a margin
    platform_radius: float
    plate_thickness: float
    force_scale: float | None     # the drive's peak force (N), for the live colour bar, or None
    head: np.ndarray              # (3,) the pilot's head in C (m): where the arrows start
    arrow_scale: float            # m of arrow per m/s^2 of specific force
    arrow_radius: float           # m, the shaft's
    arrow_tip: float              # m, the cone's length (its base radius: 2.2 x the shaft's)
    cond_warn: float = COND_WARN
    stroke_margin: float = STROKE_MARGIN
    # [frames] (None: the scene has none): "pivot" (3, in C), "tool" (pose in C), "user" (pose
    # in N), "axis_length", "axis_radius" and "marker_radius" (m), plain lists and numbers
    frames: dict | None = None

    @property
    def size(self) -> float:
        """A length that frames the mechanism (base radius or home height, the larger)."""
        return max(self.base_radius, float(self.home[2]))

    def to_json(self) -> dict:
        """Plain lists and numbers (the page's JSON)."""
        out = {}
        for name, value in vars(self).items():
            out[name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


def view_geometry(model: Model, *, controller: ControllerConfig | None) -> ViewGeometry:
    """The view's geometry of a scene (see the module doc for the parts' lengths); its
    [controller] (None: the scene has none) gives the force scale, with its [drive]."""
    home_lengths = inverse_kinematics(model, model.home, with_cond=False).lengths
    declared = model.leg_min is not None and model.leg_max is not None
    lo = model.leg_min if model.leg_min is not None else 0.75 * float(np.min(home_lengths))
    hi = model.leg_max if model.leg_max is not None else 1.25 * float(np.max(home_lengths))
    base_r = float(np.max(np.linalg.norm(model.base_joints[:, :2], axis=1)))
    plat_r = float(np.max(np.linalg.norm(model.platform_joints[:, :2], axis=1)))
    # Radii in proportion to the platform's size: legs read as legs, not as rods or pillars.
    cyl_r = 0.07 * plat_r
    radius = 1.15 * plat_r
    return ViewGeometry(
        name=model.name, base_joints=np.array(model.base_joints),
        platform_joints=np.array(model.platform_joints), home=np.array(model.home),
        leg_min=float(lo), leg_max=float(hi), stroke_limits=declared,
        cylinder_length=float(lo), piston_length=float(hi - lo),
        cylinder_radius=cyl_r, piston_radius=0.55 * cyl_r, joint_radius=1.25 * cyl_r,
        base_radius=1.15 * base_r, platform_radius=radius,
        plate_thickness=0.12 * plat_r, force_scale=drive_peak_force(model, controller),
        head=np.array(cueing_config(model).head, dtype=float),
        arrow_scale=nice_ceiling(0.5 * radius / ARROW_REFERENCE), arrow_radius=0.4 * cyl_r,
        arrow_tip=0.12 * radius, frames=frames_geometry(model, radius, cyl_r))


def frames_geometry(model: Model, plate_radius: float, leg_radius: float) -> dict | None:
    """The scene's [frames] as the view draws them (None without [frames]): triads half the
    platform's radius long, the pivot a sphere a little smaller than a joint."""
    f = model.frames
    if f is None:
        return None
    return {"pivot": [float(v) for v in f.pivot], "tool": f.tool_pose.tolist(),
            "user": [float(v) for v in f.user], "axis_length": 0.5 * plate_radius,
            "axis_radius": 0.25 * leg_radius, "marker_radius": 0.9 * leg_radius}


def drive_peak_force(model: Model, controller: ControllerConfig | None) -> float | None:
    """The peak rack force of the scene's drives (Kf I_max, N: controller.capability), when the
    scene has a [drive] and a [controller] (its motor); else None."""
    drive = drive_bounds(model, controller)
    return None if drive is None else float(drive.force)


def rotation(q) -> np.ndarray:
    """R = Rz(thz) Ry(thy) Rx(thx) of one pose (stewart_fmu.rotations)."""
    Q = np.asarray(q, dtype=float).reshape(1, 6)
    R, om, al = np.empty((1, 3, 3)), np.empty((1, 3)), np.empty((1, 3))
    zero = np.zeros_like(Q)
    euler_motion(Q, zero, zero, R, om, al)
    return R[0]


def axis_to(u: np.ndarray) -> np.ndarray:
    """The smallest rotation taking the y axis onto the unit vector u (Rodrigues); a half turn
    about x when u is -y. Legs are axisymmetric: the spin about their axis is not drawn."""
    y = np.array([0.0, 1.0, 0.0])
    c = float(np.dot(y, u))
    if c < -1.0 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(y, u)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def homogeneous(R: np.ndarray, p) -> np.ndarray:
    """The 4x4 matrix of rotation R and translation p."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


# The plates are meshcat cylinders (axis along local y) turned to stand on z.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def object_transforms(geometry: ViewGeometry, q) -> dict[str, np.ndarray]:
    """Every moving and fixed object's 4x4 transform in N for pose q: "base", "platform",
    "legs/<i>/cylinder", "legs/<i>/piston" (i = 1..6), the joints "joints/base/<i>" and
    "joints/platform/<i>". Each part is centred on its own length, so its ends are at the
    joint (cylinder at a_i, piston at x + R p_i) and at the part's length along the leg."""
    q = np.asarray(q, dtype=float)
    R = rotation(q)
    x = q[:3]
    g = geometry
    top = np.mean(g.base_joints[:, 2])
    under = np.mean(g.platform_joints[:, 2])
    # Each plate has its inner face on its joints' plane (the base below its joints, the
    # platform above its own): the joints sit on the faces the legs leave from.
    half = g.plate_thickness / 2
    out = {"base": homogeneous(_Y_TO_Z, [0.0, 0.0, top - half]),
           "platform": homogeneous(R @ _Y_TO_Z, x + R @ [0.0, 0.0, under + half])}
    for i in range(6):
        a = g.base_joints[i]
        p = x + R @ g.platform_joints[i]
        u = (p - a) / np.linalg.norm(p - a)
        turn = axis_to(u)
        out[f"legs/{i + 1}/cylinder"] = homogeneous(turn, a + u * g.cylinder_length / 2)
        out[f"legs/{i + 1}/piston"] = homogeneous(turn, p - u * g.piston_length / 2)
        out[f"joints/base/{i + 1}"] = homogeneous(np.eye(3), a)
        out[f"joints/platform/{i + 1}"] = homogeneous(np.eye(3), p)
    if g.frames is not None:
        out.update(frame_transforms(g.frames, R, x))
    return out


TRIAD = ("x", "y", "z")   # a triad's axes, its cylinders' names


def frame_transforms(frames: dict, R: np.ndarray, x: np.ndarray) -> dict[str, np.ndarray]:
    """The frames' nodes at the pose (R, x): "frames/pivot" (the pivot's point, axes of N),
    "frames/tool" (the tool frame: origin x + R t, axes R R_tool), "frames/user" (the user
    frame's pose in N, fixed). A triad's axes hang below its node (triad_transforms)."""
    tool = np.asarray(frames["tool"], dtype=float)
    user = np.asarray(frames["user"], dtype=float)
    return {"frames/pivot": homogeneous(np.eye(3), x + R @ np.asarray(frames["pivot"])),
            "frames/tool": homogeneous(R @ rotation(tool), x + R @ tool[:3]),
            "frames/user": homogeneous(rotation(user), user[:3])}


def triad_transforms(length: float) -> dict[str, np.ndarray]:
    """Each axis of a triad in its frame: the cylinder (along local y, centred) turned onto
    the axis and moved half its length along it, so it runs from the origin to `length`."""
    out = {}
    for k, name in enumerate(TRIAD):
        e = np.eye(3)[k]
        out[name] = homogeneous(axis_to(e), e * length / 2)
    return out


def arrow_transforms(geometry: ViewGeometry, q, f) -> dict[str, np.ndarray] | None:
    """The arrow of specific force f (m/s^2, in C) at pose q: "shaft" (the unit cylinder
    stretched along local y to its length) and "tip" (the cone, shortened with an arrow shorter
    than it), from the head point x + R head along R f, geometry.arrow_scale m per m/s^2; None
    when f is zero (nothing to draw)."""
    q = np.asarray(q, dtype=float)
    R = rotation(q)
    g = geometry
    d = R @ np.asarray(f, dtype=float)
    size = float(np.linalg.norm(d))
    if not size > 0:
        return None
    u = d / size
    length = size * g.arrow_scale
    tip = min(g.arrow_tip, length)
    start = q[:3] + R @ g.head
    turn = axis_to(u)
    stretch = np.diag([1.0, length - tip, 1.0])
    return {"shaft": homogeneous(turn @ stretch, start + u * (length - tip) / 2),
            "tip": homogeneous(turn @ np.diag([1.0, tip / g.arrow_tip, 1.0]),
                               start + u * (length - tip / 2))}


def part_ends(transform: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """The two end points of a part of `length` along its local y, centred (for tests and
    checks): transform applied to (0, -length/2, 0) and (0, +length/2, 0)."""
    lo = transform @ np.array([0.0, -length / 2, 0.0, 1.0])
    hi = transform @ np.array([0.0, length / 2, 0.0, 1.0])
    return lo[:3], hi[:3]


def at_stroke_limit(geometry: ViewGeometry, lengths) -> np.ndarray:
    """Which legs are within stroke_margin of the stroke of either limit (bool, same shape)."""
    l = np.asarray(lengths, dtype=float)
    if not geometry.stroke_limits:
        return np.zeros(l.shape, dtype=bool)
    band = geometry.stroke_margin * (geometry.leg_max - geometry.leg_min)
    return (l <= geometry.leg_min + band) | (l >= geometry.leg_max - band)
