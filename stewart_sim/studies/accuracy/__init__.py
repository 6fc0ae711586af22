"""Work-precision of the integrators: `study` returns the data, `report` writes its files."""
