"""The view's scene as meshcat commands: the objects (set_object, in the three.js JSON that
meshcat-python's geometry classes lower to), the camera, lights, background and grid
(set_transform, set_property). The page hands each to meshcat's `Viewer.handle_command`.

Built here as plain dicts rather than through meshcat-python's classes: importing those starts
with meshcat's server side (zmq, tornado, IPython), which a file writer has no use for.

Paths: "/stewart/<key>" for the actual mechanism and "/ghost/<key>" for the reference pose,
with the keys of geometry.object_transforms; "/stewart/limits/<i>" marks a leg at a stroke limit;
"/cues/<name>/shaft" and "/cues/<name>/tip" are the specific-force arrows (geometry.CUES, with
geometry.arrow_transforms) and "/cues/head" the head they start from, hidden until a frame
has them. With the scene's [frames]: "/stewart/frames/pivot" the pivot point and
"/stewart/frames/<user|tool>/<x|y|z>" the two frames' triads (geometry.frame_transforms places
the nodes, geometry.triad_transforms the axes below them).
"""
from __future__ import annotations

import numpy as np

from stewart_sim.view.geometry import (
    CUES,
    TRIAD,
    ViewGeometry,
    frame_transforms,
    rotation,
    triad_transforms,
)

PLATE = 0x8fa3b8      # brushed aluminium, a little blue
BASE = 0x5b6470
PISTON = 0xd9dde2     # polished rod
JOINT = 0x2b2f36
LIMIT = 0xff8c00      # the stroke-limit mark
GHOST = 0xffffff
GHOST_OPACITY = 0.28
# the arrows: green for the vehicle's specific force, purple for the delivered one (neither is
# on the legs' blue-grey-red force map, nor the stroke-limit orange, nor the alarm red)
CUE_COLOURS = {"f_vehicle": 0x2e9e44, "f_delivered": 0x8e24aa}
# the vehicle's arrow is a wider translucent sleeve around the delivered one, so both show
# where they agree (a platform at rest for a vehicle at rest: both 1 g up)
CUE_WIDTH = {"f_vehicle": 1.8, "f_delivered": 1.0}
CUE_OPACITY = {"f_vehicle": 0.45, "f_delivered": 1.0}
HEAD = 0x202020
PIVOT = 0xffc107      # amber: a point, not a part of the machine
TRIAD_COLOURS = {"x": 0xe53935, "y": 0x43a047, "z": 0x1e88e5}   # x red, y green, z blue

def rgb(colour: int) -> list[float]:
    """0xRRGGBB as [r, g, b] in [0, 1] (meshcat's set_property "color" takes these, and alpha)."""
    return [((colour >> shift) & 0xFF) / 255 for shift in (16, 8, 0)]


def mesh(path: str, geometry: dict, colour: int, opacity: float = 1.0) -> dict:
    """The three.js Mesh object (JSON, version 4.5) with a Phong material to put at `path`
    (its uuids are made from the path: the same scene gives the same page)."""
    g = {"uuid": f"{path}#geometry", **geometry}
    m = {"uuid": f"{path}#material", "type": "MeshPhongMaterial", "color": colour,
         "reflectivity": 0.5, "shininess": 60, "side": 2, "transparent": opacity < 1.0,
         "opacity": opacity, "depthWrite": opacity >= 1.0}
    return {"metadata": {"version": 4.5, "type": "Object"},
            "geometries": [g], "materials": [m],
            "object": {"uuid": f"{path}#object", "type": "Mesh", "geometry": g["uuid"],
                       "material": m["uuid"], "matrix": np.eye(4).flatten().tolist()}}


def cylinder(height: float, radius: float) -> dict:
    """A cylinder along local y, centred (three.js CylinderGeometry)."""
    return {"type": "CylinderGeometry", "radiusTop": radius, "radiusBottom": radius,
            "height": height, "radialSegments": 48}


def sphere(radius: float) -> dict:
    return {"type": "SphereGeometry", "radius": radius, "widthSegments": 24,
            "heightSegments": 16}


def cone(height: float, radius: float) -> dict:
    """A cone along local y, centred, its point at +height/2 (three.js CylinderGeometry)."""
    return {"type": "CylinderGeometry", "radiusTop": 0.0, "radiusBottom": radius,
            "height": height, "radialSegments": 32}


def set_object(path: str, geometry: dict, colour: int, opacity: float = 1.0) -> dict:
    """meshcat's set_object of a mesh at `path`."""
    return {"type": "set_object", "path": path, "object": mesh(path, geometry, colour, opacity)}


def set_property(path: str, name: str, value) -> dict:
    return {"type": "set_property", "path": path, "property": name, "value": value}


def set_transform(path: str, matrix: np.ndarray) -> dict:
    """meshcat's set_transform: the 4x4 column by column (three.js Matrix4.fromArray)."""
    return {"type": "set_transform", "path": path,
            "matrix": np.asarray(matrix, dtype=float).T.flatten().tolist()}


def mechanism(prefix: str, g: ViewGeometry, ghost: bool) -> list[dict]:
    """set_object commands of the plates, the legs' two parts and the joints under `prefix`."""
    op = GHOST_OPACITY if ghost else 1.0
    colour = (lambda c: GHOST if ghost else c)
    cmds = [set_object(f"{prefix}/platform", cylinder(g.plate_thickness, g.platform_radius),
                       colour(PLATE), op)]
    if not ghost:
        cmds.append(set_object(f"{prefix}/base", cylinder(g.plate_thickness, g.base_radius), BASE))
    for i in range(1, 7):
        cmds.append(set_object(f"{prefix}/legs/{i}/cylinder",
                               cylinder(g.cylinder_length, g.cylinder_radius), colour(0xdddddd), op))
        cmds.append(set_object(f"{prefix}/legs/{i}/piston",
                               cylinder(g.piston_length, g.piston_radius), colour(PISTON), op))
        if not ghost:
            for end in ("base", "platform"):
                cmds.append(set_object(f"{prefix}/joints/{end}/{i}", sphere(g.joint_radius), JOINT))
            cmds.append(set_object(f"{prefix}/limits/{i}", sphere(2.4 * g.joint_radius), LIMIT, 0.6))
            cmds.append(set_property(f"{prefix}/limits/{i}", "visible", False))
    return cmds


def cue_arrows(g: ViewGeometry) -> list[dict]:
    """set_object commands of the two arrows and the head marker, hidden."""
    cmds = [set_object("/cues/head", sphere(1.6 * g.arrow_radius), HEAD),
            set_property("/cues/head", "visible", False)]
    for name in CUES:
        colour, op, r = CUE_COLOURS[name], CUE_OPACITY[name], CUE_WIDTH[name] * g.arrow_radius
        cmds += [set_object(f"/cues/{name}/shaft", cylinder(1.0, r), colour, op),
                 set_object(f"/cues/{name}/tip", cone(g.arrow_tip, 2.2 * r), colour, op),
                 set_property(f"/cues/{name}", "visible", False)]
    return cmds


def frame_marks(g: ViewGeometry) -> list[dict]:
    """The pivot's sphere and the user and tool frames' triads (nothing without [frames]),
    placed at home (the page moves the pivot and the tool frame with the platform)."""
    f = g.frames
    if f is None:
        return []
    cmds = [set_object("/stewart/frames/pivot", sphere(f["marker_radius"]), PIVOT)]
    axes = triad_transforms(f["axis_length"])
    for frame in ("user", "tool"):
        for axis in TRIAD:
            path = f"/stewart/frames/{frame}/{axis}"
            cmds += [set_object(path, cylinder(f["axis_length"], f["axis_radius"]),
                                TRIAD_COLOURS[axis]),
                     set_transform(path, axes[axis])]
    home = np.asarray(g.home, dtype=float)
    for key, T in frame_transforms(f, rotation(home), home[:3]).items():
        cmds.append(set_transform(f"/stewart/{key}", T))
    return cmds


def scene_commands(g: ViewGeometry, with_ghost: bool, with_cues: bool = False) -> list[dict]:
    """Every command that builds the scene, in order."""
    size = g.size
    z_mid = 0.55 * float(g.home[2])
    floor = float(np.min(g.base_joints[:, 2])) - 1.05 * g.plate_thickness
    # meshcat's camera lives in /Cameras/default/rotated (y up): a point (x, y, z) of N is
    # (x, z, -y) there. The orbit target is /Cameras/default's origin.
    eye = np.array([1.45, -1.9, 0.95]) * size
    cmds = [
        set_property("/Background", "top_color", [0.97, 0.98, 1.0]),
        set_property("/Background", "bottom_color", [0.80, 0.84, 0.90]),
        # the floor grid (5 x size wide) just under the base plate, not through it
        set_transform("/Grid", _translation([0.0, 0.0, floor]) @ np.diag([size / 4] * 3 + [1.0])),
        set_transform("/Axes", np.diag([size / 2, size / 2, size / 2, 1.0])),
        set_transform("/Cameras/default", _translation([0.0, 0.0, z_mid])),
        set_property("/Cameras/default/rotated/<object>", "position",
                     [float(eye[0]), float(eye[2]), float(-eye[1])]),
    ]
    cmds += mechanism("/stewart", g, ghost=False)
    cmds += frame_marks(g)
    if with_ghost:
        cmds += mechanism("/ghost", g, ghost=True)
    if with_cues:
        cmds += cue_arrows(g)
    return cmds


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def buffer_object(path: str, kind: str, positions: np.ndarray, colours: np.ndarray,
                  size: float | None = None) -> dict:
    """meshcat's set_object of three.js Points (`size`: each point's, m) or LineSegments
    (consecutive pairs of `positions`) at `path`, coloured per vertex: positions (N, 3) m,
    colours (N, 3) in [0, 1], written as float32 (the page's precision)."""
    def attribute(a: np.ndarray) -> dict:
        flat = np.asarray(a, dtype=np.float32).ravel()
        return {"itemSize": 3, "type": "Float32Array", "normalized": False,
                "array": [float(v) for v in flat]}

    g = {"uuid": f"{path}#geometry", "type": "BufferGeometry",
         "data": {"attributes": {"position": attribute(positions), "color": attribute(colours)}}}
    m = {"uuid": f"{path}#material", "vertexColors": True,
         **({"type": "PointsMaterial", "size": size, "sizeAttenuation": True}
            if kind == "Points" else {"type": "LineBasicMaterial", "linewidth": 1})}
    obj = {"metadata": {"version": 4.5, "type": "Object"}, "geometries": [g], "materials": [m],
           "object": {"uuid": f"{path}#object", "type": kind, "geometry": g["uuid"],
                      "material": m["uuid"], "matrix": np.eye(4).flatten().tolist()}}
    return {"type": "set_object", "path": path, "object": obj}


def _float32_list(a: np.ndarray) -> list[float]:
    """a as float32, each value written with the fewest digits that give back the same
    float32 (the page reads them into a Float32Array): the page's precision at about half
    the text of float64's digits."""
    return [float(str(v)) for v in np.asarray(a, dtype=np.float32).ravel()]


def triangle_mesh(path: str, positions: np.ndarray, normals: np.ndarray, triangles: np.ndarray,
                  colour: int, opacity: float = 1.0) -> dict:
    """meshcat's set_object of an indexed three.js Mesh at `path`: positions (V, 3) m (float32,
    the page's precision), normals (V, 3) (shading only: written to 1e-3), triangles (T, 3)
    vertex indices, counter-clockwise seen from the side the normals point to; a Phong
    material of `colour`, both sides lit, translucent below opacity 1."""
    index = np.asarray(triangles, dtype=np.int64).ravel()
    if index.size and not (0 <= index.min() and index.max() < len(positions)):
        raise ValueError(f"{path}: triangle indices outside the {len(positions)} vertices")
    obj = mesh(path, {"type": "BufferGeometry", "data": {
        "index": {"type": "Uint32Array", "array": index.tolist()},
        "attributes": {
            "position": {"itemSize": 3, "type": "Float32Array", "normalized": False,
                         "array": _float32_list(positions)},
            "normal": {"itemSize": 3, "type": "Float32Array", "normalized": False,
                       "array": np.round(np.asarray(normals, dtype=float), 3).ravel().tolist()}}}},
        colour, opacity)
    return {"type": "set_object", "path": path, "object": obj}
