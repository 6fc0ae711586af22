"""Constant-load control against Kane feedforward over gear ratios: `study` and `report`."""
