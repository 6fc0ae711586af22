"""Identification of the dynamic parameters (`identify`): base.py (the base parameters of a
stacked regressor), with the rest of the pipeline beside it."""
