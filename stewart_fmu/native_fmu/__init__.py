"""The self-contained native FMU (FMI 2.0 and 3.0): the C core and FMI layer compiled into the
FMU's binary, with its sources; no Python at run time. See export.export_fmu."""
from .export import BuildError, CompilerNotFoundError, export_fmu

__all__ = ["BuildError", "CompilerNotFoundError", "export_fmu"]
