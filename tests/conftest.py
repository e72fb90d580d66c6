"""Shared test configuration."""

from __future__ import annotations

import pytest

from pipelines.blas_threads import limit_blas_threads


def pytest_configure(config: pytest.Config) -> None:
    # as the command line does: one BLAS thread, so that a busy second core (CI runs
    # other jobs) cannot make small factorisations 10-100x slower
    limit_blas_threads()
