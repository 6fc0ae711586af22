"""`stewart-sim design`: a hexapod's geometry from its requirements (docs/guides/design.md)."""
