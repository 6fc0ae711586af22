"""The stiffness and the modes of a scene at a pose, and their map over a grid of poses
(`stewart-sim modes`): inputs checked (study), results written as one set (report)."""
