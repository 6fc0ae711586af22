"""Builds the C core (stewart_fmu/native) as the cffi extension stewart_fmu.native._core;
everything else is declared in pyproject.toml.

build_py also ships the package stewart_fmu.native (its Python wrapper, core.py), which
pyproject.toml's [tool.setuptools] packages list does not name: without it a wheel (a
non-editable install) would carry the compiled _core but not the wrapper. Once that list
names "stewart_fmu.native", this command can go.
"""
from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithNative(build_py):
    def finalize_options(self):
        super().finalize_options()
        if self.packages is not None and "stewart_fmu.native" not in self.packages:
            self.packages.append("stewart_fmu.native")


setup(cffi_modules=["stewart_fmu/native/build_core.py:ffibuilder"],
      cmdclass={"build_py": BuildPyWithNative})
