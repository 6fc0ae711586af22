"""The FMU's Windows binary: the same C sources cross-compiled for 64-bit Windows with mingw-w64
(Debian's gcc-mingw-w64-x86-64-win32, one part of its mingw-w64), put beside the host's binary.

Flags: the host build's (export.CFLAGS: C99, -O2, -ffp-contract=off, no -march) less -fPIC (a
PE DLL is relocatable without it), plus -static-libgcc, so that the DLL imports nothing but
KERNEL32.dll and msvcrt.dll, which every Windows has, and -s (the symbol table of the static
runtime would triple its size). It exports the functions marked FMI_EXPORT (fmi/fmi_export.h:
dllexport) and nothing else. Its sin, cos and pow are mingw-w64's (x87), linked in statically
(none is imported from msvcrt.dll): Windows computes them as wine does, and a few results differ
from glibc's by one unit in the last place (docs/guides/fmu-and-ssp.md: "Windows against Linux,
measured").
"""
from __future__ import annotations

import shutil
from pathlib import Path

MINGW_CC = "x86_64-w64-mingw32-gcc"
DEBIAN_PACKAGE = "gcc-mingw-w64-x86-64-win32"   # the Makefile's system-packages installs it
# The DLL's platform as Python reports it there (platform.system(), platform.machine()): the
# binaries folder comes from export.platform_folder, which names every platform's.
SYSTEM, MACHINE = "Windows", "AMD64"


def find_mingw() -> str | None:
    """The mingw-w64 C compiler on the PATH, or None."""
    return shutil.which(MINGW_CC)


def missing_note() -> str:
    """The one line export-fmu prints when it leaves the Windows binary out."""
    return (f"export-fmu: no Windows binary in the FMU: {MINGW_CC} not found "
            f"(Debian: apt-get install {DEBIAN_PACKAGE})")


def command(compiler: str, cflags: list[str], sources: list[str], dll: Path) -> list[str]:
    """The mingw-w64 command line that builds `dll` from `sources` (C files) with the host's
    `cflags`."""
    flags = [f for f in cflags if f != "-fPIC"]
    return [compiler, *flags, "-shared", "-static-libgcc", "-s", "-o", str(dll), *sources, "-lm"]
