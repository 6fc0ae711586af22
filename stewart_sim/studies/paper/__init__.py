"""The paper's Section 3 rerun: `study` returns the data, `report` writes its files, `files`
runs both into a directory; `demonstration` is what `stewart-sim demo` writes around it."""
