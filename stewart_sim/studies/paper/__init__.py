"""The paper's Section 3 rerun: `study` returns the data, `report` writes its files."""
