"""Builds the C extensions with cffi: the plant's core (stewart_fmu/native) as
stewart_fmu.native._core, and the axis loop (controller/native/axis.c compiled with the core's
sources) as controller.native._axis; everything else is declared in pyproject.toml."""
from setuptools import setup

setup(cffi_modules=["stewart_fmu/native/build_core.py:ffibuilder",
                    "controller/native/build_axis.py:ffibuilder"])
