"""Errors the command line turns into one ``error: ...`` line and exit status 2."""

from __future__ import annotations


class BeambenchError(Exception):
    """Bad input or an unusable file: the user can fix it. Exit status 2, no traceback."""


class RigError(BeambenchError):
    """A rig configuration file that cannot be used, naming the file and the key."""

    def __init__(self, path: str, key: str | None, problem: str) -> None:
        self.path = path
        self.key = key
        self.problem = problem
        where = f"{path}: [{key}]" if key else f"{path}:"
        super().__init__(f"{where} {problem}")


class DampingFitError(BeambenchError):
    """A run that cannot determine the damping (``process --fit-damping``: a hub standing
    still, too short, no strains)."""
