"""The project's numba options (vision/jit.py): numpy's error model and IEEE sums."""

from __future__ import annotations

import math
import threading

import numpy as np

from vision.jit import kernel


@kernel
def _ratio_sum(a, b):  # type: ignore[no-untyped-def]
    s = 0.0
    for i in range(a.size):
        s += a[i] / b[i]
    return s


def test_kernel_divides_as_numpy_does() -> None:
    # error_model="numpy": 1/0 is inf and 0/0 NaN, not ZeroDivisionError
    assert _ratio_sum(np.array([1.0]), np.array([0.0])) == math.inf
    assert math.isnan(_ratio_sum(np.array([0.0]), np.array([0.0])))


def test_kernel_sums_in_order_without_fastmath() -> None:
    # no fastmath: a left-to-right sum, bit for bit what Python's loop gives
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=1001), rng.uniform(0.5, 2.0, size=1001)
    expect = 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        expect += x / y
    assert _ratio_sum(a, b) == expect


def test_kernel_runs_in_threads() -> None:
    a, b = np.ones(10_000), np.full(10_000, 4.0)
    out: list[float] = []
    threads = [threading.Thread(target=lambda: out.append(_ratio_sum(a, b))) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert out == [2500.0] * 4
