"""Builds the C extensions with cffi: the plant's core (stewart_fmu/native) as
stewart_fmu.native._core, and the axis loop (controller/native/axis.c compiled with the core's
sources) as controller.native._axis; everything else is declared in pyproject.toml.

build_py also ships the packages stewart_fmu.native (the core's Python wrapper, core.py) and
controller.native, which pyproject.toml's [tool.setuptools] packages list does not name:
without them a wheel (a non-editable install) would carry the compiled modules but not their
packages. Once that list names them, this command can go.
"""
from setuptools import setup
from setuptools.command.build_py import build_py


NATIVE_PACKAGES = ("stewart_fmu.native", "controller.native")


class BuildPyWithNative(build_py):
    def finalize_options(self):
        super().finalize_options()
        for package in NATIVE_PACKAGES:
            if self.packages is not None and package not in self.packages:
                self.packages.append(package)


setup(cffi_modules=["stewart_fmu/native/build_core.py:ffibuilder",
                   "controller/native/build_axis.py:ffibuilder"],
      cmdclass={"build_py": BuildPyWithNative})
