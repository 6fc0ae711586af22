"""The plant without a controller: reference trajectories (references), forces along a
trajectory (inverse_forces), motion from rack forces (forward)."""
