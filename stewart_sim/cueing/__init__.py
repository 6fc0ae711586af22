"""Motion cueing: vehicle motion in, platform poses out (washout), and what a person on the
platform perceives (vestibular) and whether the mechanism can fly it (feasibility)."""
