"""Global-space trajectories, per-axis drive controllers and the co-simulation master."""
