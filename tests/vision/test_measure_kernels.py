"""vision.measure's kernels against the numpy forms they replace: the same formula per
point (a, b each two products and a sum), which numpy's matrix-vector product may
evaluate with a fused multiply-add: equal to a few ulps (1e-15 m on coordinates under a
metre), and the same points kept."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from vision.measure import _beam_frame_points


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


def test_the_frame_kernel_is_the_numpy_forms() -> None:
    """``_frame_points``: the beam's pairs as ``_beam_frame_points`` keeps them, each
    side's largest a, and the hub's points by the numpy form it replaced
    (``column_stack([d @ e, d @ n])``)."""
    from vision.measure import _frame_points

    rng = np.random.default_rng(42)
    for _ in range(60):
        theta = rng.uniform(-np.pi, np.pi)
        e = np.array([math.cos(theta), math.sin(theta)])
        n = np.array([-e[1], e[0]])
        origin = rng.normal(0, 0.1, 2)
        m = int(rng.integers(1, 200))
        a = rng.uniform(-0.05, 0.8, m)
        pa = origin + a[:, None] * e + 0.0095 * n
        pb = origin + (a + rng.normal(0, 1e-3, m))[:, None] * e - 0.0095 * n
        hub = [rng.normal(0, 0.05, (int(rng.integers(0, 40)), 2)) for _ in range(2)]
        got = _frame_points(pa, pb, hub[0], hub[1], *origin, *e, 0.02)
        ha, hb, amax_a, swap = _beam_frame_points(pa, pb, *origin, *e, *n, 0.02)
        np.testing.assert_array_equal(got[0], ha)
        np.testing.assert_array_equal(got[1], hb)
        assert got[2][0] == amax_a and got[3] == swap
        assert got[2][1] == (hb[:, 0].max() if len(hb) else -math.inf)
        for pts, q in zip(hub, got[4:], strict=True):
            d = pts - origin
            want = np.column_stack([d @ e, d @ n]) if len(pts) else np.zeros((0, 2))
            np.testing.assert_allclose(q, want, rtol=0, atol=1e-15)


def test_the_rough_slope_kernels_are_the_numpy_forms() -> None:
    """``_rough_slope``: the derivative of the least-squares polynomial through the
    rough centre line's points (numpy's Vandermonde, normal equations and ``solve``,
    then ``polyval``): equal to rounding (a quartic on [0, 1]: cond ~1e5)."""
    from numpy.polynomial import polynomial as pw

    from vision.measure import _rough_slope_k, _scaled_polyval_k

    rng = np.random.default_rng(43)
    for deg in (1, 2, 4):
        a = np.sort(rng.uniform(0.0, 0.7, 37))
        b = 0.02 * a**2 - 0.03 * a**3 + 1e-4 * rng.standard_normal(37)
        scale = float(np.max(np.abs(a)))
        vand = np.vander(a / scale, deg + 1, increasing=True)
        coef = np.linalg.solve(vand.T @ vand, vand.T @ b)
        der = coef[1:] * np.arange(1, deg + 1)
        got = _rough_slope_k(a, b, scale, deg)
        np.testing.assert_allclose(got, der, rtol=1e-9, atol=1e-12 * np.abs(der).max())
        q = rng.uniform(-0.1, 0.9, 50)
        np.testing.assert_array_equal(
            _scaled_polyval_k(q, der, scale), pw.polyval(q / scale, der) / scale
        )


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
    """``_offsets_k`` and ``_across_k`` (the strips' half widths in pixels) against the
    numpy form they replaced (``unit_step_gradient``, normalised by ``np.hypot``, the
    normal ``(-t_y, t_x)`` times the half width): equal exactly."""
    from vision.measure import _across_k, _offsets_k
    from vision.sampling import unit_step_gradient

    rng = np.random.default_rng(45)
    strips = []
    for k in (2, 3, 57, 211):
        t = np.sort(rng.uniform(0.0, 0.5, k))
        strips.append((np.column_stack([t, 0.1 * t**2 + 0.01 * rng.random()]), 0.01 * k))
    lines, offsets = [], []
    for line_m, half_m in strips:
        t = unit_step_gradient(line_m)
        t /= np.hypot(t[:, 0], t[:, 1])[:, None]
        lines.append(line_m)
        offsets.append(line_m + half_m * np.column_stack([-t[:, 1], t[:, 0]]))
    want = np.vstack(lines + offsets)
    sizes = np.cumsum([0] + [len(x) for x, _ in strips]).astype(np.intp)
    halves = np.array([h for _, h in strips])
    got = _offsets_k(np.vstack(lines), sizes, halves)
    np.testing.assert_array_equal(got, want)
    n = sizes[-1]
    px, off = want[:n], want[n:]
    np.testing.assert_array_equal(
        _across_k(got), np.hypot(off[:, 0] - px[:, 0], off[:, 1] - px[:, 1])
    )
