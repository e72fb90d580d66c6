"""The sampling kernels (vision/sampling.py) against the numpy definitions they replace:
equal to the last bit (the same arithmetic in the same order; a median is an order
statistic, or numpy's mean of two)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from tests.vision.sampling_numpy import bilinear_numpy
from vision.errors import ParameterError
from vision.sampling import (
    BilinearPlan,
    along_across,
    bilinear,
    median,
    median_bounded,
    median_in_place,
    median_nonnegative,
    numpy_sum,
    order_stats_bounded,
)


def test_bilinear_is_the_numpy_form_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    for h, w in ((2, 2), (7, 13), (1536, 2048)):
        img = rng.integers(0, 256, size=(h, w), dtype=np.uint8)
        xy = np.column_stack([rng.uniform(-2, w + 1, 4000), rng.uniform(-2, h + 1, 4000)])
        # the last row and column, the corners, NaN and infinities
        xy[:6] = [[w - 1, h - 1], [0, 0], [w - 1, 0.5], [0.5, h - 1], [np.nan, 1], [1, -np.inf]]
        want = bilinear_numpy(img, xy)
        got = bilinear(img, xy)
        np.testing.assert_array_equal(got, want)
        assert np.isnan(got[4:6]).all() and np.isfinite(got[:4]).all()
        # a grid of points (..., 2) keeps its shape; a view of the image samples the same
        np.testing.assert_array_equal(bilinear(img, xy.reshape(2, -1, 2)), want.reshape(2, -1))
        np.testing.assert_array_equal(bilinear(np.asfortranarray(img), xy), want)
        plan = BilinearPlan.at(img.shape, xy)
        np.testing.assert_array_equal(plan.sample(img), want)
    assert bilinear(img, np.zeros((0, 2))).shape == (0,)
    with pytest.raises(ParameterError):
        plan.sample(img[:-1])


def test_median_selects_numpys_value_on_ties_and_every_size() -> None:
    rng = np.random.default_rng(12)
    for n in [*range(1, 40), 101, 1000, 4001]:
        for x in (rng.normal(size=n), rng.integers(0, 4, size=n).astype(float), np.ones(n)):
            assert median(x) == float(np.median(x))
            work = x.copy()
            assert median(work, overwrite_input=True) == float(np.median(x))
            np.testing.assert_array_equal(np.sort(work), np.sort(x))  # a permutation
    # sorted and reversed input (a quickselect's worst orders), a NaN anywhere
    x = np.arange(1000.0)
    assert median(x) == median(x[::-1]) == 499.5
    for i in (0, 5, 999):
        y = x.copy()
        y[i] = np.nan
        assert np.isnan(median(y))
    # integers and 2-D input are taken as float64, flattened
    assert median(np.array([[3, 1], [2, 4]])) == 2.5


def test_the_kernels_sum_is_numpys_bit_for_bit() -> None:
    rng = np.random.default_rng(13)
    for n in [*range(0, 300), 513, 1000, 2049, 10_000]:
        x = rng.normal(size=n) * 10 ** rng.uniform(-3, 3)
        lo = int(rng.integers(0, 5))
        y = np.concatenate([rng.normal(size=lo), x])
        assert numpy_sum(y[lo:], n) == x.sum(), n


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5, 10, 11, 64, 1001, 1650])
def test_median_in_place_is_numpys_median_on_sorted_reversed_and_equal_values(n: int) -> None:
    rng = np.random.default_rng(n)
    for x in (
        rng.standard_normal(n),
        np.round(rng.standard_normal(n), 1),  # ties
        np.sort(rng.standard_normal(n)),  # sorted
        np.sort(rng.standard_normal(n))[::-1].copy(),  # reversed
        np.full(n, 0.25),  # all equal
    ):
        got = median_in_place(x.copy())
        want = float(np.median(x)) if n else math.nan
        assert got == want or (math.isnan(got) and math.isnan(want)), (n, got, want)
    if n:
        x = rng.standard_normal(n)
        x[n // 3] = math.nan
        assert math.isnan(median_in_place(x))


def test_along_across_is_numpys_broadcast_expression_exactly() -> None:
    rng = np.random.default_rng(3)
    for n in (0, 1, 5, 1001):
        o, u, v = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        a, b = rng.normal(size=n) * 0.7, rng.normal(size=n) * 1e-3
        want = o[None, :] + a[:, None] * u[None, :] + b[:, None] * v[None, :]
        got = along_across(o, u, v, a, b)
        assert got.shape == (n, 2)
        np.testing.assert_array_equal(got, want)


def test_bounded_order_statistics_are_the_sorted_values_and_refuse_what_is_out_of_range() -> None:
    rng = np.random.default_rng(14)
    for k in range(2000):
        n = int(rng.integers(1, 700))
        x: NDArray[np.float64] = (
            rng.uniform(0, 256, n),  # every bucket
            np.round(rng.normal(80, 4, n)).clip(0, 255),  # many ties in few buckets
            rng.integers(0, 3, n) * 0.25,  # bucket edges only
            np.abs(rng.normal(0, 2, n)),  # crowded low buckets (image differences)
            np.full(n, 255.99),  # the range's last bucket
        )[k % 5].astype(np.float64)
        k1 = int(rng.integers(0, n))
        k2 = int(rng.integers(k1, n))
        before = x.copy()
        ok, a, b = order_stats_bounded(x, k1, k2, 4.0, 1024)
        s = np.sort(x)
        assert ok and (a, b) == (s[k1], s[k2]), (k, n, k1, k2)
        np.testing.assert_array_equal(x, before)  # left as it was
        assert median_bounded(x, 8.0, 2048) == float(np.median(x)), k
        np.testing.assert_array_equal(x, before)
    # out of the range (above, at its end, negative, NaN, infinite): refused, and the
    # median then taken by selection (NaN for a NaN)
    for bad in (256.0, 300.0, -1e-9, math.nan, math.inf):
        x = np.array([1.0, 2.0, bad, 3.0])
        ok, a, b = order_stats_bounded(x, 0, 3, 4.0, 1024)
        assert not ok and math.isnan(a) and math.isnan(b)
        want = float(np.median(x))
        got = median_bounded(x.copy(), 4.0, 1024)
        assert got == want or (math.isnan(got) and math.isnan(want)), bad
    # ranks outside the array: refused, not read past it
    assert not order_stats_bounded(np.zeros(0), 0, 0, 4.0, 1024)[0]
    assert not order_stats_bounded(np.ones(3), 1, 3, 4.0, 1024)[0]
    assert not order_stats_bounded(np.ones(3), 2, 1, 4.0, 1024)[0]
    assert math.isnan(median_bounded(np.zeros(0), 4.0, 1024))


def test_median_of_nonnegative_values_by_their_bits_is_numpys_and_leaves_them() -> None:
    rng = np.random.default_rng(19)
    for n in (1, 2, 3, 4, 7, 8, 250, 251, 1800, 1801):
        # residuals' magnitudes; many ties (whole buckets of one value, the two middle
        # ones in different buckets); a spread over 600 binades, beyond the buckets
        for x in (
            np.abs(rng.normal(size=n)) * 1e-5,
            rng.integers(1, 4, size=n).astype(np.float64),
            np.where(np.arange(n) < n // 2, 1.0, 2.0) + 0.0,
            10.0 ** rng.uniform(-300, 300, size=n),
        ):
            before = x.copy()
            got = median_nonnegative(x)
            assert np.float64(got).tobytes() == np.median(before).tobytes(), n
            if np.ptp(np.log2(before)) < 100:
                np.testing.assert_array_equal(x, before)  # counted, not partitioned
    # zero, negative, subnormal, infinite and NaN values: the quickselect's median
    for bad in (0.0, -1e-9, 5e-324, math.inf, math.nan):
        x = np.array([1.0, 2.0, bad, 3.0, 0.5])
        want = float(np.median(x))
        got = median_nonnegative(x)
        assert got == want or (math.isnan(got) and math.isnan(want)), bad
    assert math.isnan(median_nonnegative(np.zeros(0)))
