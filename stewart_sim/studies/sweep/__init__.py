"""Design sweeps on Dask: `grid` (GRID.toml), `evaluate` (per point), `table` (the table), `chunks` (chunk files, checked on resume), `run` (Dask), `plots`, `files` (the pipeline)."""
