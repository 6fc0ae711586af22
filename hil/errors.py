"""Typed errors of the hil package."""
from __future__ import annotations

from stewart_fmu.errors import StewartError


class LinkError(StewartError):
    """A transport or link emulator cannot do what was asked (closed, misconfigured, OS error)."""


class DeviceError(StewartError):
    """The device cannot be built as asked (bad watchdog, telemetry rate, signing key)."""
