"""The Stewart platform plant: scenes, kinematics, Kane's equations, dynamics."""
from .dynamics import PARTS, forward_dynamics, inverse_dynamics, inverse_dynamics_parts, present_parts
from .errors import (
                       ForwardKinematicsError,
                       KinematicsError,
                       SceneError,
                       SingularityError,
                       StewartError,
                       StrokeLimitError,
                       TrajectoryError,
)
from .kinematics import check_poses, forward_kinematics, inverse_kinematics
from .model import Model
from .scene import load_scene, scene_from_dict

__all__ = [
    "PARTS", "ForwardKinematicsError", "KinematicsError", "Model", "SceneError",
    "SingularityError", "StewartError", "StrokeLimitError", "TrajectoryError", "check_poses",
    "forward_dynamics", "forward_kinematics", "inverse_dynamics", "inverse_dynamics_parts",
    "inverse_kinematics", "load_scene", "present_parts", "scene_from_dict",
]
