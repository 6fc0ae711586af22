"""Constant-load control against Kane feedforward over gear ratios: `study` (data), `report`
(its files) and `files` (the `compare` command: every scene studied, then reported)."""
