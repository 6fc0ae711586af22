"""The mechanism's workspace (`stewart-sim workspace`): each pose's margins against every limit
(--check), the travel along a direction (--reach), the per-axis ranges of a datasheet
(--ranges) and the constant-orientation workspace (--map), all from the one feasibility engine
(stewart_fmu.reach, native/src/reach.c)."""
