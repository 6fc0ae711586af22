"""The mechanism's workspace (`stewart-sim workspace`): each pose's margins against every limit
(--check), the travel along a direction (--reach), the per-axis ranges of a datasheet
(--ranges), the constant-orientation workspace (--map) and where the rack force binds over it
with a payload and an acceleration envelope (--load, rack_force.py), all from the one
feasibility engine (stewart_fmu.reach, native/src/reach.c)."""
