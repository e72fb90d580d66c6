"""Compiled kernels: :func:`kernel` is numba's ``njit`` with this project's options, for the
per-frame loops whose numpy form spends its time in thousands of small array calls.

- ``cache=True``: compiled once per machine and source version (under ``__pycache__``),
  so a run's frame workers and CLI calls load the machine code instead of compiling it.
- ``nogil=True``: a kernel releases the GIL, so frames measured in threads run in parallel.
- ``error_model="numpy"``: division by zero gives inf/NaN as numpy does, not an exception.
- no ``fastmath``: IEEE arithmetic, so a kernel and the numpy form it replaces differ only
  by the order of their sums.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])


def kernel(fn: F) -> F:
    """``fn`` compiled by numba (nopython mode) with the options above."""
    return cast(F, numba.njit(cache=True, nogil=True, error_model="numpy")(fn))
