"""The acquisition package's exceptions: one small tree, messages built by the constructors."""

from __future__ import annotations


class DaqError(Exception):
    """Base class of every error raised by ``daq``."""


class DaqInputError(DaqError, ValueError):
    """A setting or argument ``daq`` cannot use (message names the parameter, expected vs got).

    Also a ``ValueError``, so callers that validate configuration by catching
    ``ValueError`` (``pipelines.rig``) keep working.
    """


class DeviceError(DaqError):
    """A device failed or refused a setting (message names the device)."""


class DeviceTimeoutError(DeviceError):
    """A device delivered nothing within the timeout."""

    def __init__(self, device: str, timeout_s: float) -> None:
        self.device = device
        self.timeout_s = timeout_s
        super().__init__(f"{device}: no data within {timeout_s:g} s (device timeout)")


class DriverUnavailableError(DaqError):
    """A vendor driver (e.g. ``nidaqmx``) is not installed."""

    def __init__(self, package: str, hint: str) -> None:
        self.package = package
        super().__init__(f"the '{package}' driver package is not installed; {hint}")


class LogError(DaqError):
    """A run log that cannot be read: truncated, corrupt, or not a beambench log."""

    def __init__(self, path: str, problem: str, *, suggest_recover: bool = True) -> None:
        self.path = path
        self.problem = problem
        hint = " (try beambench recover)" if suggest_recover else ""
        super().__init__(f"{path}: {problem}{hint}")
