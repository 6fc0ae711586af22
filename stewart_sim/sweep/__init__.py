"""Design sweeps on Dask: `grid` (GRID.toml), `evaluate` (per point), `table` (chunk files), `run` (Dask), `plots`, `files` (the pipeline)."""
