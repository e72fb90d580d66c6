"""Image sampling: bilinear interpolation at sub-pixel points (with a reusable plan) and a fast
median, shared by the measurement steps. The edge estimators are in :mod:`vision.edges`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vision.errors import ParameterError
from vision.jit import kernel


def median(x: NDArray[np.float64], overwrite_input: bool = False) -> float:
    """``np.median`` of a 1-D array (NaN if it holds one) by selection, without the
    generic machinery that makes ``np.median`` several times slower on the small arrays
    a frame's measurement takes many medians of. ``overwrite_input``: partition ``x``
    itself (a float64 array the caller no longer needs) instead of a copy."""
    a = np.asarray(x, dtype=np.float64).ravel()
    return float(_median(a, overwrite_input))


@kernel
def _median(a: NDArray[np.float64], overwrite: bool) -> float:
    """:func:`median` of the contiguous ``a`` (selected in place with ``overwrite``)."""
    return median_in_place(a if overwrite else a.copy())


@kernel
def median_in_place(w: NDArray[np.float64]) -> float:
    """:func:`median` of ``w``, selected in place: the middle order statistic, or the
    mean of the two (``0.5 * (lo + hi)``, numpy's). Kernels call this one: a literal
    argument (``_median(a, True)``) would compile another specialisation."""
    n = w.size
    if n == 0:
        return math.nan
    for i in range(n):
        if w[i] != w[i]:
            return math.nan
    k = n // 2
    select_kth(w, k, n)
    if n % 2:
        return w[k]
    lo = w[0]
    for i in range(1, k):
        if w[i] > lo:
            lo = w[i]
    return 0.5 * (lo + w[k])


@kernel
def select_kth(w: NDArray[np.float64], k: int, n: int) -> None:
    """Partition ``w[:n]`` (no NaN) about its ``k``-th smallest value, in place: ``w[k]``
    is that value, none before it is larger, none after it (to ``n``) smaller (Hoare's
    quickselect, median-of-three pivot)."""
    lo, hi = 0, n - 1
    while hi > lo:
        a, b, c = w[lo], w[(lo + hi) >> 1], w[hi]
        if a > b:
            a, b = b, a
        if b > c:
            b = c
        pivot = a if a > b else b
        i, j = lo, hi
        while i <= j:
            while w[i] < pivot:
                i += 1
            while w[j] > pivot:
                j -= 1
            if i <= j:
                w[i], w[j] = w[j], w[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@kernel
def order_stats_bounded(
    w: NDArray[np.float64], k1: int, k2: int, scale: float, buckets: int
) -> tuple[bool, float, float]:
    """The ``k1``-th and ``k2``-th smallest values of ``w`` (``k1 <= k2 < w.size``),
    exactly, when every value lies in ``0 .. buckets / scale`` (``scale`` a power of
    two); (False, NaN, NaN) otherwise (a NaN among them included). ``w`` is left as it
    is.

    Counting sort's first half instead of a quickselect, whose compares on image
    samples are coin flips (a mispredicted branch each: ~3 us for a 251-sample
    profile): the values counted into buckets ``1 / scale`` wide (``v * scale``, exact,
    then truncated: a monotonic map, so the ranks below each bucket are known), then
    each rank selected among its bucket's few values alone."""
    n = w.size
    if not 0 <= k1 <= k2 < n:
        return False, math.nan, math.nan
    counts = np.zeros(buckets, dtype=np.int32)
    first, last = buckets, -1  # the buckets used
    for i in range(n):
        v = w[i] * scale
        if not (v >= 0.0 and v < buckets):  # NaN fails too
            return False, math.nan, math.nan
        b = int(v)
        counts[b] += 1
        first, last = min(first, b), max(last, b)
    # Low ranks walked to from the lowest bucket, high ones from the highest (a
    # profile's levels lie near its ends).
    b, below = first, 0
    while below + counts[b] <= k1:
        below += counts[b]
        b += 1
    low = _bucket_kth(w, scale, b, counts[b], k1 - below)
    if k2 == k1:
        return True, low, low
    b, above = last, 0  # above: the values in buckets over b
    while n - above - counts[b] > k2:
        above += counts[b]
        b -= 1
    return True, low, _bucket_kth(w, scale, b, counts[b], k2 - (n - above - counts[b]))


@kernel
def _bucket_kth(w: NDArray[np.float64], scale: float, b: int, count: int, k: int) -> float:
    """The ``k``-th smallest of the ``count`` values of ``w`` in bucket ``b``
    (:func:`order_stats_bounded`)."""
    tmp = np.empty(count)
    j = 0
    for i in range(w.size):
        if int(w[i] * scale) == b:
            tmp[j] = w[i]
            j += 1
    select_kth(tmp, k, count)
    return tmp[k]


@kernel
def median_bounded(w: NDArray[np.float64], scale: float, buckets: int) -> float:
    """:func:`median_in_place` of ``w`` by :func:`order_stats_bounded` when its values
    lie in its range (``w`` then left as it is), else by :func:`median_in_place` (which
    partitions ``w``)."""
    n = w.size
    if n == 0:
        return math.nan
    k = n // 2
    ok, lo, hi = order_stats_bounded(w, k - 1 if n % 2 == 0 else k, k, scale, buckets)
    if not ok:
        return median_in_place(w)
    return hi if n % 2 else 0.5 * (lo + hi)


#: :func:`median_nonnegative`'s buckets: a float's bits shifted right by this many (its
#: exponent and the top 4 bits of its mantissa: 16 buckets a binade), and at most this many
#: buckets between a set's smallest value and its largest (128 binades).
_BITS_SHIFT = 48
_BITS_BUCKETS = 2048


@kernel
def median_nonnegative(w: NDArray[np.float64]) -> float:
    """:func:`median_in_place` of ``w`` (its value, bit for bit: the same order
    statistics, the same mean of two), ``w`` left as it is, when its values are finite
    and positive and span at most 128 binades (absolute residuals); else by
    :func:`median_in_place`, which partitions ``w``.

    The order statistics by counting sort's first half on the values' bits, as
    :func:`order_stats_bounded` on a fixed scale: a positive float's bits, read as an
    integer, rise with it, so the top 16 bits count the values into buckets of known
    rank; the middle ones are then selected among their bucket's few values alone (a
    residual's median bucket holds ~2 % of them). A quickselect's compares on noise
    are coin flips, a mispredicted branch each: a joint fit's scales of its ~1800
    residuals took 20 us a solve by it, 5 us by this."""
    n = w.size
    if n == 0:
        return math.nan
    bits = w.view(np.int64)
    low, high = bits[0] >> _BITS_SHIFT, bits[0] >> _BITS_SHIFT
    for i in range(n):
        key = bits[i] >> _BITS_SHIFT
        low, high = min(low, key), max(high, key)
    # zero and negative values (sign bit: a negative key), infinities and NaNs (the
    # largest exponent) or too wide a span: the quickselect
    if low <= 0 or high >= 0x7FF0 or high - low >= _BITS_BUCKETS:
        return median_in_place(w)
    counts = np.zeros(high - low + 1, dtype=np.int64)
    for i in range(n):
        counts[(bits[i] >> _BITS_SHIFT) - low] += 1
    k = n // 2
    b, below = 0, 0
    while below + counts[b] <= k:
        below += counts[b]
        b += 1
    target = b + low
    tmp = np.empty(counts[b])
    j = 0
    for i in range(n):
        tmp[j] = w[i]  # (overwritten by the next value when not in the bucket)
        j += int((bits[i] >> _BITS_SHIFT) == target)
        if j == counts[b]:
            break
    kk = k - below
    select_kth(tmp, kk, j)
    hi = tmp[kk]
    if n % 2:
        return hi
    # the (k - 1)-th: the largest before the k-th in its bucket, or of the buckets below
    lo = -1.0
    if kk > 0:
        lo = tmp[0]
        for i in range(1, kk):
            lo = max(lo, tmp[i])
    else:
        for i in range(n):
            v = w[i]
            lo = max(lo, v if (bits[i] >> _BITS_SHIFT) < target else -1.0)
    return 0.5 * (lo + hi)


@kernel
def numpy_sum(a: NDArray[np.float64], n: int) -> float:
    """``a[:n].sum()`` as numpy sums a contiguous float64 array, bit for bit: halves
    (each a multiple of 8 where it can be) down to blocks of at most 128, each summed
    eight ways, the halves' sums added up the tree. Walked with a stack, not recursion:
    a cached kernel calling a recursive one crashes when loaded (numba 0.68)."""
    depth = 64  # the tree is log2(n / 128) + 1 deep
    node_lo, node_n = np.zeros(depth, np.int64), np.empty(depth, np.int64)
    state = np.zeros(depth, np.int64)  # 0: left half next, 1: right half next, 2: add
    sums = np.empty(depth)
    top, done = 0, 0
    node_n[0] = n
    while top >= 0:
        m = node_n[top]
        if m <= 128:
            sums[done] = _block_sum(a, node_lo[top], m)
            done += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if state[top] == 2:
            sums[done - 2] = sums[done - 2] + sums[done - 1]
            done -= 1
            top -= 1
            continue
        first = node_lo[top] if state[top] == 0 else node_lo[top] + half
        size = half if state[top] == 0 else m - half
        state[top] += 1
        top += 1
        node_lo[top], node_n[top], state[top] = first, size, 0
    return sums[0]


@kernel
def _block_sum(a: NDArray[np.float64], lo: int, n: int) -> float:
    """numpy's sum of a block of at most 128: eight running sums added pairwise, then
    the rest in order (under 8: in order from -0.0)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


def along_across(
    origin: NDArray[np.float64],
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Points (N, 2) ``origin + a u + b v`` for the coordinates ``a``, ``b`` (N) along the
    2-vectors ``u`` and ``v``: numpy's ``origin[None, :] + a[:, None] * u[None, :] +
    b[:, None] * v[None, :]`` in one call, its operations in its order (:func:`_along_k`)."""
    return _along_k(
        np.ascontiguousarray(origin, dtype=np.float64),
        np.ascontiguousarray(u, dtype=np.float64),
        np.ascontiguousarray(v, dtype=np.float64),
        np.ascontiguousarray(a, dtype=np.float64),
        np.ascontiguousarray(b, dtype=np.float64),
    )


@kernel
def _along_k(
    origin: NDArray[np.float64],
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`along_across`: ``(origin + a u) + b v``, each product and sum rounded."""
    out = np.empty((a.shape[0], 2))
    for i in range(a.shape[0]):
        for j in range(2):
            out[i, j] = (origin[j] + a[i] * u[j]) + b[i] * v[j]
    return out


def bilinear(image: NDArray[np.uint8], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bilinear samples of a [row, col] image at points (N, 2) (x, y); NaN off the image."""
    xy = np.asarray(xy, dtype=np.float64)
    out = bilinear_points(np.ascontiguousarray(image), np.ascontiguousarray(xy).reshape(-1, 2))
    return out.reshape(xy.shape[:-1])


@kernel
def bilinear_points(image: NDArray[np.uint8], xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`bilinear` of points (N, 2): the cell's corner at the truncated point (one
    cell in from the last row and column), interpolated along x on its top and bottom
    rows, then along y between them."""
    h, w = image.shape
    out = np.empty(xy.shape[0])
    for i in range(xy.shape[0]):
        x, y = xy[i, 0], xy[i, 1]
        if not (x >= 0 and y >= 0 and x <= w - 1 and y <= h - 1):  # NaN fails too
            out[i] = math.nan
            continue
        # Non-negative here, so truncation is the floor.
        x0, y0 = min(int(x), w - 2), min(int(y), h - 2)
        fx, fy = x - x0, y - y0
        v00, v10 = float(image[y0, x0]), float(image[y0 + 1, x0])
        top = v00 + fx * (image[y0, x0 + 1] - v00)
        bottom = v10 + fx * (image[y0 + 1, x0 + 1] - v10)
        out[i] = top + fy * (bottom - top)
    return out


@dataclass(frozen=True, eq=False)
class BilinearPlan:
    """:func:`bilinear` at fixed points for images of one shape (points searched in
    every frame of a camera placement): the points, made contiguous once."""

    shape: tuple[int, ...]
    xy: NDArray[np.float64]  # (N, 2) contiguous

    @classmethod
    def at(cls, shape: tuple[int, ...], xy: NDArray[np.float64]) -> BilinearPlan:
        return cls(tuple(shape), np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2))

    def sample(self, image: NDArray[np.uint8]) -> NDArray[np.float64]:
        if image.shape != self.shape:
            raise ParameterError(
                "image", f"must have the plan's shape {self.shape}, got {image.shape}"
            )
        return bilinear_points(np.ascontiguousarray(image), self.xy)
