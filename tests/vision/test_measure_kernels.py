"""vision.measure's kernels against the numpy forms they replace: the same formula per
point (a, b each two products and a sum), which numpy's matrix-vector product may
evaluate with a fused multiply-add: equal to a few ulps (1e-15 m on coordinates under a
metre), and the same points kept."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from vision.measure import (
    _beam_frame_points,
    _columns,
    _kth,
    _scaled_polyval_k,
    _strong_k,
    _vander_k,
)


def _beam_frame_numpy(pa, pb, clamp, e, n, a0):  # type: ignore[no-untyped-def]
    """The form before the kernel (Measurer._beam_frame without its failure)."""
    da, db = pa - clamp, pb - clamp
    aa, ab = da @ e, db @ e
    k = (aa > a0) & (ab > a0)
    aa, ab = aa[k], ab[k]
    ba, bb = (da @ n)[k], (db @ n)[k]
    ha, hb = np.column_stack([aa, ba]), np.column_stack([ab, bb])
    amax = aa.max() if aa.size else -math.inf
    return ha, hb, amax, bool(np.median(ba - bb) < 0) if aa.size else False


def test_the_beam_frame_is_the_numpy_forms() -> None:
    rng = np.random.default_rng(41)
    for k in range(300):
        m = int(rng.integers(0, 300))
        theta = rng.uniform(-np.pi, np.pi)
        e = np.array([math.cos(theta), math.sin(theta)])
        n = np.array([-e[1], e[0]])
        clamp = rng.normal(0, 0.1, 2)
        a = rng.uniform(-0.05, 0.8, m)
        side = 0.0095 * (1 if k % 2 else -1)
        pa: NDArray[np.float64] = (
            clamp + a[:, None] * e + (side + rng.normal(0, 1e-4, m))[:, None] * n
        )
        pb = clamp + (a + rng.normal(0, 1e-3, m))[:, None] * e - side * n
        a0 = float(rng.uniform(0, 0.05))
        ha, hb, amax, swap = _beam_frame_points(pa, pb, *clamp, *e, *n, a0)
        want = _beam_frame_numpy(pa, pb, clamp, e, n, a0)
        assert ha.shape == want[0].shape and hb.shape == want[1].shape, k
        np.testing.assert_allclose(ha, want[0], rtol=0, atol=1e-15)
        np.testing.assert_allclose(hb, want[1], rtol=0, atol=1e-15)
        assert abs(amax - want[2]) <= 1e-15 or amax == want[2] == -math.inf
        if len(ha):
            assert swap == want[3] == (k % 2 == 0), k


def test_linspace_is_numpys_exactly() -> None:
    """``vision.centreline.linspace``, the kernel the measurement's sample lines use,
    element for element numpy's (ends, one and no samples, a step that underflows)."""
    from vision.centreline import linspace

    rng = np.random.default_rng(44)
    cases = [(0.0, 1.0, 0), (0.3, 0.7, 1), (-0.2, 0.2, 2), (1e-310, 2e-310, 7), (5.0, -3.0, 801)]
    cases += [
        (float(x), float(y), int(k))
        for x, y, k in zip(
            rng.uniform(-1, 1, 30), rng.uniform(-1, 1, 30), rng.integers(0, 900, 30), strict=True
        )
    ]
    for start, stop, num in cases:
        np.testing.assert_array_equal(linspace(start, stop, num), np.linspace(start, stop, num))


def test_the_strip_offsets_are_the_numpy_forms() -> None:
    """``_offsets_k`` (the strips' lines and their points a half width across) against
    the numpy form it replaced (``np.gradient`` along the line, normalised by ``np.hypot``, the
    normal ``(-t_y, t_x)`` times the half width): equal exactly."""
    from vision.measure import _offsets_k

    rng = np.random.default_rng(45)
    strips = []
    for k in (2, 3, 57, 211):
        t = np.sort(rng.uniform(0.0, 0.5, k))
        strips.append((np.column_stack([t, 0.1 * t**2 + 0.01 * rng.random()]), 0.01 * k))
    lines, offsets = [], []
    for line_m, half_m in strips:
        t = np.gradient(line_m, axis=0)
        t /= np.hypot(t[:, 0], t[:, 1])[:, None]
        lines.append(line_m)
        offsets.append(line_m + half_m * np.column_stack([-t[:, 1], t[:, 0]]))
    want = np.vstack(lines + offsets)
    sizes = np.cumsum([0] + [len(x) for x, _ in strips]).astype(np.intp)
    halves = np.array([h for _, h in strips])
    got = _offsets_k(np.vstack(lines), sizes, halves)
    np.testing.assert_array_equal(got, want)


def test_the_small_forms_are_numpys_exactly() -> None:
    """The 90th percentile's selection (NaN sorted last, as np.partition), the rough
    slope's Vandermonde matrix and scaled polynomial, and the hub points' columns, bit
    for bit against the numpy calls they replace."""
    rng = np.random.default_rng(17)
    for n in (1, 2, 9, 300):
        x = rng.gamma(2.0, 2.0, n)
        x[rng.random(n) < 0.2] = rng.choice(x)  # ties
        if n > 2:
            x[rng.integers(0, n)] = math.nan
        for k in {0, n // 2, int(0.9 * (n - 1)), n - 1}:
            np.testing.assert_array_equal(_kth(x, k), np.partition(x, k)[k])
        a = rng.uniform(-0.2, 1.1, n)
        for m in (1, 2, 5):
            np.testing.assert_array_equal(_vander_k(a, m), np.vander(a, m, increasing=True))
        for deg in (1, 4):
            c = rng.normal(size=deg)
            want = np.polynomial.polynomial.polyval(a / 0.83, c) / 0.83
            np.testing.assert_array_equal(_scaled_polyval_k(a, c, 0.83), want)
        d, e, nn = rng.normal(size=(n, 2)), rng.normal(size=2), rng.normal(size=2)
        np.testing.assert_array_equal(_columns(d, e, nn), np.column_stack([d @ e, d @ nn]))


def test_the_strong_lines_are_the_numpy_forms() -> None:
    """The strip's lines of more than 0.35 of its median contrast, their points and
    ramp widths, as the numpy form chose them."""
    rng = np.random.default_rng(19)
    for n in (1, 2, 8, 501):
        a, b = rng.normal(size=(n, 2)), rng.normal(size=(n, 2))
        contrast, spread = rng.gamma(1.5, 30.0, n), rng.gamma(2.0, 1.0, n)
        contrast[rng.random(n) < 0.1] = float(np.median(contrast)) * 0.35  # at the limit
        keep = contrast > 0.35 * np.median(contrast)
        pts, sp = _strong_k(a, b, contrast, spread)
        np.testing.assert_array_equal(pts, np.vstack([a[keep], b[keep]]))
        np.testing.assert_array_equal(sp, spread[keep])
