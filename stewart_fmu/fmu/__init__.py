"""The plant as a self-contained FMU (FMI 2.0 and 3.0): `variables` (the one table of names,
value references, units), `model_description` (modelDescription.xml), `export` (the scene's C
file, the C core and FMI layer compiled into the FMU's binary, with its sources; no Python at
run time)."""
