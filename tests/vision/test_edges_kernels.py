"""The edge scan's kernels (vision/edges.py) against the numpy form they replace
(tests/vision/edges_reference.py), on seeded synthetic strips unlike beambench's frames:
the same points kept and dropped, and the same positions.

Two comparisons. With the reference's single-precision exp set to the kernels' own
(:func:`vision.edges._exp32`), every number is equal but for the pooled light tilt's
sums, which the kernels add in another order (1e-12 px covers that: a tilt of ~1e-4 per
sample summed over a few hundred lines, rounded at 1e-16 relative, moves an edge by
~1e-15 px; the edges are within 1e3 px). With numpy's own exp, which differs from the
kernels' by up to 2 ulp (1.2e-7 relative; it is within 2.4 ulp of the exact value, the
kernels' within 0.5) on ~1/3 of the fit's arguments, the erf fit's positions may move by
about that much of a step's size times the residual it weights (~1e-7 px), and a line
near the fit's convergence test (1e-3 px) may take its third step or not (~1e-4 px):
1e-3 px bounds both, a tenth of the fit's own noise on a sharp edge."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from decimal import Decimal, localcontext
from typing import Any

import numpy as np
import pytest
from numba import njit
from scipy.special import ndtr

from tests.vision import edges_reference as ref
from vision.edges import (
    _EXP2_TABLE,
    _column_medians_even,
    _erf_steps,
    _exp32_of,
    _interp,
    _median9,
    _ndtr_from_weight,
    _scan_lines,
    _smoothed,
    erf_edge,
    strip_edges_many,
)

ESTIMATORS = ("moment", "area", "erf", "gauss3")


def _kernel_exp(x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:  # the kernels' exp
    y = _exp32_of(np.ascontiguousarray(x, dtype=np.float32))
    if out is None:
        return y
    out[...] = y
    return out


@pytest.fixture
def same_exp() -> Iterator[None]:
    ref.EXP32 = _kernel_exp
    yield
    ref.EXP32 = np.exp


def _bar(shape: tuple[int, int], y0: float, slope: float, half: float, sigma: float, dn: float):  # type: ignore[no-untyped-def]
    """A bright bar (``dn`` above the background) about y = y0 + slope x, blurred."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    d = (y - y0 - slope * x) / np.hypot(1.0, slope)
    return dn * (ndtr((d + half) / sigma) - ndtr((d - half) / sigma))


def _scene(seed: int) -> tuple[np.ndarray, list[tuple[np.ndarray, Any]]]:
    """Strips of random widths, blurs and contrasts on uneven light, some scanned along
    rows, one running off the image's edge, one only a few lines long; noise and
    clutter (a bright blob across one strip)."""
    rng = np.random.default_rng(seed)
    h, w = 260, 420
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    light = 1.0 + rng.uniform(-1e-3, 1e-3) * x + rng.uniform(-1e-3, 1e-3) * y
    img = np.full((h, w), rng.uniform(20.0, 60.0))
    strips: list[tuple[np.ndarray, Any]] = []
    # along columns (x): a wide bar and a narrow one, one of them off the bottom edge
    for y0, half in ((rng.uniform(50, 70), rng.uniform(12, 22)), (h - 6.0, rng.uniform(5, 9))):
        slope = rng.uniform(-0.06, 0.06)
        img += _bar((h, w), y0, slope, half, rng.uniform(0.5, 2.5), rng.uniform(60, 180))
        xs = np.linspace(rng.uniform(10, 40), rng.uniform(360, 410), int(rng.integers(20, 60)))
        hw: Any = half if rng.random() < 0.5 else np.full(len(xs), half)
        strips.append((np.column_stack([xs, y0 + slope * xs]), hw))
    # along rows (y): a long one and a short one (a few lines)
    for x0, y1 in (
        (rng.uniform(250, 300), 200.0),
        (rng.uniform(330, 380), 150.0 + rng.uniform(2, 9)),
    ):
        slope = rng.uniform(-0.05, 0.05)
        half = rng.uniform(6, 12)
        img += _bar((w, h), x0, slope, half, rng.uniform(0.6, 1.8), rng.uniform(80, 160)).T
        ys = np.linspace(150.0 if y1 < 170 else 110.0, y1, 12)
        strips.append((np.column_stack([x0 + slope * ys, ys]), half))
    img[100:115, 200:212] += 90.0  # clutter across the first strip's background
    img = img * light + rng.normal(0.0, rng.uniform(1.0, 4.0), img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), strips


def _assert_same(got: list[Any], want: list[Any], atol: float) -> None:
    for a, b in zip(got, want, strict=True):
        assert len(a.side_a) == len(b.side_a)  # the same lines kept
        for f in ("side_a", "side_b", "contrast", "spread"):
            np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=atol)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_scan_is_the_numpy_scan(seed: int, estimator: str, same_exp: None) -> None:
    img, strips = _scene(seed)
    got = strip_edges_many(img, strips, estimator=estimator)
    want = ref.strip_edges_many(img, strips, estimator=estimator)
    assert sum(len(e.side_a) for e in want) > 100
    _assert_same(got, want, 1e-12)
    # strip by strip, with other margins and windows
    for line, hw in strips:
        kw = {"margin_px": 4, "window": 3, "max_window": 6, "estimator": estimator}
        _assert_same(
            strip_edges_many(img, [(line, hw)], **kw),
            ref.strip_edges_many(img, [(line, hw)], **kw),
            1e-12,
        )


@pytest.mark.parametrize("seed", range(3))
def test_scan_with_numpys_exp_moves_an_edge_by_rounding(seed: int) -> None:
    img, strips = _scene(100 + seed)
    got = strip_edges_many(img, strips, estimator="erf")
    want = ref.strip_edges_many(img, strips, estimator="erf")
    _assert_same(got, want, 1e-3)


def test_scan_of_nothing_and_of_lines_off_the_image() -> None:
    img = np.full((50, 60), 30, dtype=np.uint8)
    flat = np.column_stack([np.linspace(5, 55, 10), np.full(10, 25.0)])
    off = np.column_stack([np.linspace(5, 55, 10), np.full(10, -40.0)])
    for est in ESTIMATORS:
        for strips in ([], [(flat, 4.0)], [(off, 4.0)], [(flat[:1], 4.0)]):
            got = strip_edges_many(img, strips, estimator=est)
            want = ref.strip_edges_many(img, strips, estimator=est)
            assert len(got) == len(want)
            _assert_same(got, want, 0.0)


@pytest.mark.parametrize("blocks", [1, 3])
def test_erf_edge_is_the_numpy_fit(blocks: int, same_exp: None) -> None:
    """Float profiles (a registration edge's), starts NaN or off the window, flat
    lines, blurred blocks (the wider window), a too-short profile."""
    rng = np.random.default_rng(21)
    n, m = 200, 17
    j = np.arange(m, dtype=np.float64)
    c = rng.uniform(5.0, 11.0, n)
    sig = np.repeat([0.7, 1.6, 0.9], [70, 70, 60])
    prof = 25.0 + 140.0 * ndtr((j[None, :] - c[:, None]) / sig[:, None])
    prof += rng.normal(0.0, 2.0, prof.shape)
    start = c + rng.normal(0.0, 0.3, n)
    start[::17] = np.nan
    start[5] = 1.0  # the window leaves the profile
    lo, hi = np.full(n, 25.0), np.full(n, 165.0)
    hi[7] = 25.5  # no contrast
    sigma0 = rng.uniform(0.3, 2.0, n)
    sigma0[3] = np.nan
    for p in (prof, np.round(prof), prof[:, :6]):
        got = erf_edge(p, start, lo, hi, sigma0, blocks=blocks)
        want = ref.erf_edge(p, start, lo, hi, sigma0, blocks=blocks)
        np.testing.assert_array_equal(got, want)
    falling = erf_edge(prof[:, ::-1], m - 1 - start, lo, hi, sigma0, rising=False, blocks=blocks)
    want = ref.erf_edge(prof[:, ::-1], m - 1 - start, lo, hi, sigma0, rising=False, blocks=blocks)
    np.testing.assert_array_equal(falling, want)


def test_erf_step_is_the_numpy_step(same_exp: None) -> None:
    rng = np.random.default_rng(8)
    half, n = 4, 50
    v = rng.uniform(-5.0, 160.0, (2 * half + 1, n))
    amp, c, s = rng.uniform(20, 200, n), rng.uniform(-0.6, 0.6, n), rng.uniform(0.3, 4.0, n)
    centre = np.round(rng.uniform(5, 30, n))
    for sign in (1.0, -1.0):
        fit = ref._ErfWindow(
            v.astype(np.float32), np.arange(-half, half + 1, dtype=np.float32)[:, None], amp, sign
        )
        dc0, _ = fit.step(c + centre, centre, s, joint=False)
        dc1, ds1 = fit.step(c + centre, centre, s, joint=True)
        offs = np.arange(-half, half + 1, dtype=np.float32)
        v32 = v.astype(np.float32)
        got0, got1, got_s = np.empty(n), np.empty(n), np.empty(n)
        _erf_steps(v32, offs, amp, sign, c + centre, centre, s, False, got0, got_s)
        _erf_steps(v32, offs, amp, sign, c + centre, centre, s, True, got1, got_s)
        np.testing.assert_array_equal(got0, dc0)
        np.testing.assert_array_equal(got1, dc1)
        np.testing.assert_array_equal(got_s, ds1)


@njit(cache=False)
def _libm_exp_into(x: np.ndarray, out: np.ndarray) -> None:  # the C library's expf
    for i in range(x.size):
        out.flat[i] = np.exp(x.flat[i])


def _ulps(got: np.ndarray, x: np.ndarray) -> np.ndarray:
    """|got - exp(x)| in units of the last place of exp(x) rounded to single precision
    (subnormal spacing below 2^-126); exp(x) in double (its error, ~1e-16, is 1e-9 of a
    single-precision ulp)."""
    exact = np.exp(x.astype(np.float64))
    return np.abs(got.astype(np.float64) - exact) / np.spacing(exact.astype(np.float32))


def test_exp32_is_the_exact_value_rounded_and_within_an_ulp_of_the_c_librarys() -> None:
    """The fit's arguments -u^2 / 2 are <= 0, down to ~-240 (|u| up to ~6.5 samples
    over the narrowest width, 0.3): seeded arguments from 0 to the last subnormal
    result (below: test_exp32_at_its_edges), and positive ones. Bound 0.50005 ulp: the
    exact value's rounding (0.5) plus the method's relative error (1.2e-12 from the
    Taylor polynomial, ~1e-15 from the rounding of the double arithmetic) over a
    single-precision ulp (>= 6e-8 of the value): 2e-5 ulp, doubled. The C library's
    expf (the fit's exp before; glibc's is within 0.502 ulp of the exact value, 0.5016
    measured here) and this one are then single-precision values within 1.002 ulp of
    each other: at most 1 ulp apart."""
    rng = np.random.default_rng(19)
    x = np.concatenate(
        [
            rng.uniform(-90.0, 0.0, 400_000),
            rng.uniform(-0.5, 0.0, 100_000),  # near 0: results near 1, the densest ulps
            rng.uniform(-103.97, -87.0, 100_000),  # subnormal results
            rng.uniform(0.0, 88.7, 50_000),
        ]
    ).astype(np.float32)
    got = _exp32_of(x)
    assert _ulps(got, x).max() <= 0.50005
    libm = np.empty_like(x)
    _libm_exp_into(x, libm)
    spacing = np.spacing(np.minimum(got, libm))
    assert np.all(np.abs(got.astype(np.float64) - libm) <= spacing)


def test_exp32_at_its_edges() -> None:
    """0 and the smallest arguments give 1 exactly; the subnormal results to the last one,
    then 0 (underflow: the exact value below half the smallest subnormal, 2^-150, at
    -103.972), and 0 for large negative arguments and -inf; inf past 88.7228 (ln of
    the largest float); NaN for NaN."""
    f = np.float32
    x = np.array(
        [0.0, -0.0, -1e-30, -1e-7, 1e-7, -87.33, -87.34, -100.0, -103.27, -103.28],
        dtype=f,
    )
    got = _exp32_of(x)
    assert np.all(got[:3] == 1.0)
    assert _ulps(got, x).max() <= 0.50005
    tiny = np.nextafter(f(0.0), f(1.0))
    boundary = f(math.log(2.0**-150))  # -103.972...
    assert _exp32_of(np.array([np.nextafter(boundary, f(0.0))], dtype=f))[0] == tiny
    under = np.array([np.nextafter(boundary, f(-200.0)), -104.0, -110.0, -1e30, -np.inf])
    assert np.all(_exp32_of(under.astype(f)) == 0.0)
    assert np.isfinite(_exp32_of(np.array([88.7228], dtype=f))[0])
    over = np.array([88.7229, 89.0, 1e30, np.inf], dtype=f)
    assert np.all(_exp32_of(over) == np.inf)
    assert np.isnan(_exp32_of(np.array([np.nan], dtype=f))[0])


def test_exp32s_table_is_two_to_the_k_over_32_rounded() -> None:
    with localcontext() as ctx:
        ctx.prec = 40
        want = [float(Decimal(2) ** (Decimal(k) / 32)) for k in range(32)]
    bits = _EXP2_TABLE + (np.arange(32, dtype=np.uint64) << np.uint64(47))
    np.testing.assert_array_equal(bits.view(np.float64), want)


def test_normal_cdf_is_the_numpy_polynomial() -> None:
    u = np.linspace(-12.0, 12.0, 200001).astype(np.float32)
    g = np.exp(np.float32(-0.5) * u * u)
    np.testing.assert_array_equal(_ndtr_from_weight(u, g), ref._ndtr_from_weight(u, g))


def test_smoothed_levels_are_the_numpy_smoothing() -> None:
    rng = np.random.default_rng(4)
    sizes = [0, 1, 2, 3, 5, 6, 8, 9, 12, 40]
    bounds = np.cumsum([0, *sizes])
    out_levels = rng.integers(60, 70, bounds[-1]) * 0.5
    in_levels = rng.normal(200.0, 3.0, bounds[-1])
    lo, hi = ref._smoothed_levels(out_levels, in_levels, bounds)
    np.testing.assert_array_equal(_smoothed(out_levels, bounds), lo)
    np.testing.assert_array_equal(_smoothed(in_levels, bounds), hi)


def test_median_of_nine_on_ties_and_random_values() -> None:
    rng = np.random.default_rng(2)
    for x in itertools.chain(rng.integers(0, 4, (300, 9)).astype(float), rng.normal(size=(300, 9))):
        assert _median9(x) == np.median(x)


def test_column_medians_on_ties_and_random_values() -> None:
    rng = np.random.default_rng(6)
    for rows in (2, 4, 8, 10, 12):
        for x in (rng.integers(0, 4, (rows, 300)), rng.integers(-255, 256, (rows, 301))):
            want = np.median(x, axis=0)
            got = _column_medians_even(x.astype(np.int32))  # (sorts its argument)
            np.testing.assert_array_equal(got, want)


def test_interp_is_numpys_to_the_bit() -> None:
    rng = np.random.default_rng(12)
    for n in (2, 3, 5, 40):
        for _ in range(50):
            xp = np.sort(rng.uniform(-5.0, 60.0, n))
            if n > 2 and rng.random() < 0.3:  # repeated abscissae and exact hits
                xp[1] = xp[2] = np.round(xp[2])
                xp = np.sort(xp)
            fp = rng.normal(0.0, 50.0, n)
            xq = np.arange(-8, 64)
            np.testing.assert_array_equal(_interp(xq, xp, fp), np.interp(xq, xp, fp))


def test_scan_lines_are_the_numpy_lines() -> None:
    """Strips of every direction and length, half widths scalar or per point, partly or
    wholly off the image, a polyline given backwards."""
    rng = np.random.default_rng(13)
    shape = (300, 400)
    for _ in range(300):
        a = rng.uniform(-60.0, 460.0, 2)
        b = a + rng.uniform(-200.0, 200.0, 2)
        k = int(rng.integers(2, 40))
        line = a + np.linspace(0.0, 1.0, k)[:, None] * (b - a) + rng.normal(0.0, 0.5, (k, 2))
        hw: Any = rng.uniform(1.0, 25.0) if rng.random() < 0.5 else rng.uniform(1.0, 25.0, k)
        margin, window = int(rng.integers(2, 7)), int(rng.integers(4, 9))
        got = _scan_lines(shape, line, hw, margin, window)
        want = ref._scan_lines(shape, line, hw, margin, window)
        assert (got is None) == (want is None)
        if got is not None and want is not None:
            assert (got.columns, got.reach) == (want.columns, want.reach)
            for f in ("lines", "yc", "half", "top"):
                np.testing.assert_array_equal(getattr(got, f), getattr(want, f))


def test_a_monotonic_lines_order_is_argsorts() -> None:
    """The scan lines' order without a sort, where the centre line's x is strictly
    monotonic, is argsort's; anything else (ties, turns, NaN) is left to argsort."""
    from vision.edges import _monotonic_k

    rng = np.random.default_rng(23)
    for n in (2, 3, 40, 600):
        x = np.cumsum(rng.uniform(0.1, 2.0, n))
        y, hw = rng.normal(size=n), rng.uniform(5, 20, n)
        for xx in (x, x[::-1].copy()):
            pts = np.column_stack([xx, y])  # strided columns, as the scan passes them
            ok, xs, ys, hs = _monotonic_k(pts[:, 0], pts[:, 1], hw)
            order = np.argsort(xx)
            assert ok
            np.testing.assert_array_equal(xs, xx[order])
            np.testing.assert_array_equal(ys, y[order])
            np.testing.assert_array_equal(hs, hw[order])
        for k in range(3):
            bad = x.copy()
            i = int(rng.integers(0, n - 1))
            bad[i + 1] = bad[i] if k == 0 else (bad[i] - 0.5 if k == 1 else math.nan)
            if n > 2 or k != 1:
                assert not _monotonic_k(bad, y, hw)[0]
