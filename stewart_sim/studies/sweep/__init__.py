"""Design sweeps on Dask: `grid` (GRID.toml), `evaluate` (per point), `result_table` (the
table), `chunks` (chunk files, checked on resume), `dask_run` (Dask), `plots`, `files` (the
pipeline)."""
