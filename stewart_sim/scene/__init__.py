"""A scene and what is built from it alone: its tables read once (load), described
(describe), the [cueing] and [case] tables (cueing_config, case_config), and the paper's six
moves on its model (paper_moves)."""
