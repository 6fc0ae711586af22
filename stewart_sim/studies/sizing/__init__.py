"""Actuator sizing (`stewart-sim size`): `motions` (platform trajectories, vehicle motions cued),
`catalogue` (drives.csv), `demand` (what a motion asks of each leg's drive), `study` (the scene's
drive checked, the catalogue swept on Dask and ranked), `plots`, `report` (the files)."""
