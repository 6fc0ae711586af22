"""Builds the C core (stewart_fmu/native) as the cffi extension stewart_fmu.native._core;
everything else is declared in pyproject.toml."""
from setuptools import setup

setup(cffi_modules=["stewart_fmu/native/build_core.py:ffibuilder"])
