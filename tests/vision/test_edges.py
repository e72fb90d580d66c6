"""Sub-pixel strip edges and the sampling helpers, on synthetic profiles of known edges."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.ndimage import median_filter
from scipy.special import ndtr

from vision.edges import (
    _median9,
    _ndtr_from_weight,
    _smoothed,
    erf_edge,
    strip_edges,
    strip_edges_many,
)
from vision.sampling import bilinear, median


def _strip_image(
    shape: tuple[int, int], y0: float, slope: float, half: float, sigma: float
) -> np.ndarray:
    """A bright strip (40 -> 210 DN) about the line y = y0 + slope x, perpendicular half
    width ``half`` px, edges blurred by a Gaussian of ``sigma`` px, sampled at pixel
    centres (the erf model exactly)."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    d = (y - y0 - slope * x) / np.hypot(1.0, slope)
    v = 40.0 + 170.0 * (ndtr((d + half) / sigma) - ndtr((d - half) / sigma))
    return np.round(v).clip(0, 255).astype(np.uint8)


@pytest.mark.parametrize("transpose", [False, True])
def test_strip_edges_find_both_sides_of_a_blurred_strip(transpose: bool) -> None:
    y0, slope, half, sigma = 60.3, 0.12, 9.4, 0.9
    img = _strip_image((140, 400), y0, slope, half, sigma)
    xs = np.linspace(20.0, 380.0, 40)
    line = np.column_stack([xs, y0 + slope * xs])
    if transpose:  # the same strip along rows: scan lines are then image rows
        img, line = np.ascontiguousarray(img.T), line[:, ::-1]
    edges = strip_edges(img, line, half, estimator="erf")
    a, b = edges.side_a, edges.side_b
    if transpose:  # back to (x, y) of the untransposed strip
        a, b = a[:, ::-1], b[:, ::-1]
    assert len(a) > 300
    across = half * np.hypot(1.0, slope)  # the edges along a column
    # Quantization to 8 bits is the only error left (noise-free): a few thousandths.
    np.testing.assert_allclose(a[:, 1], y0 + slope * a[:, 0] - across, atol=0.02)
    np.testing.assert_allclose(b[:, 1], y0 + slope * b[:, 0] + across, atol=0.02)
    np.testing.assert_allclose(edges.contrast, 170.0, atol=4.0)


def test_strips_scanned_together_give_what_each_gives_alone() -> None:
    """A wide bar (a hub: 19 px half width, blurred 1.1 px, on a dimmer plateau) and a
    narrow strip (a beam) side by side along the image, plus a strip scanned the other
    way: one pass must give every strip exactly its own scan's edges (its reach,
    background samples, level smoothing and edge width stay its own)."""
    rng = np.random.default_rng(5)
    img = np.maximum(
        _strip_image((300, 600), 80.4, 0.05, 19.0, 1.1),
        _strip_image((300, 600), 210.7, -0.03, 9.2, 0.7),
    )
    img = np.maximum(img, _strip_image((600, 300), 150.2, 0.02, 8.0, 0.8).T)
    img = np.clip(img + rng.normal(0.0, 3.0, img.shape), 0, 255).astype(np.uint8)
    xs = np.linspace(20.0, 250.0, 30)
    hub = np.column_stack([xs, 80.4 + 0.05 * xs])
    xs2 = np.linspace(330.0, 580.0, 30)
    beam = np.column_stack([xs2, 210.7 - 0.03 * xs2])
    ys = np.linspace(10.0, 60.0, 20)
    cross = np.column_stack([150.2 + 0.02 * ys, ys])  # scanned along rows
    strips = [(hub, 19.0), (beam, np.full(30, 9.2)), (cross, 8.0)]
    together = strip_edges_many(img, strips, estimator="erf")
    for (line, half), got in zip(strips, together, strict=True):
        alone = strip_edges(img, line, half, estimator="erf")
        assert len(alone.side_a) > 15
        np.testing.assert_array_equal(got.side_a, alone.side_a)
        np.testing.assert_array_equal(got.side_b, alone.side_b)
        np.testing.assert_array_equal(got.contrast, alone.contrast)
        np.testing.assert_array_equal(got.spread, alone.spread)


def test_a_falling_edge_is_the_rising_edge_of_the_negated_profile() -> None:
    # strip_edges fits both sides as rising edges this way; erf_edge's own falling mode
    # must agree.
    rng = np.random.default_rng(3)
    j = np.arange(30.0)
    c = rng.uniform(12.0, 17.0, 50)
    prof = 30.0 + 150.0 * ndtr(-(j[None, :] - c[:, None]) / 0.8) + rng.normal(0, 2, (50, 30))
    lo, hi = np.full(50, 30.0), np.full(50, 180.0)
    start = np.round(c) + 0.2
    falling = erf_edge(prof, start, lo, hi, np.full(50, 0.8), rising=False)
    rising = erf_edge(-prof, start, -hi, -lo, np.full(50, 0.8), rising=True)
    np.testing.assert_allclose(falling, rising, atol=1e-9)
    assert np.sqrt(np.mean((falling - c) ** 2)) < 0.05


def test_normal_cdf_from_the_weight_is_accurate() -> None:
    u = np.linspace(-12.0, 12.0, 200001).astype(np.float32)
    g = np.exp(np.float32(-0.5) * u * u)
    err = np.abs(_ndtr_from_weight(u, g).astype(np.float64) - ndtr(u.astype(np.float64)))
    assert err.max() < 3.5e-7


def test_the_running_median_of_nine_is_exact() -> None:
    # A min/max network: right on every 0-1 input means right on every input.
    for bits in itertools.product((0.0, 1.0), repeat=9):
        x = np.array(bits)
        assert _median9(x) == np.median(x)


def test_smoothed_levels_are_each_strips_own_median_filter() -> None:
    # Strips of every length a scan gives (short ones smooth over fewer lines), with
    # ties (levels are half-integers): each strip's series as median_filter gives it.
    rng = np.random.default_rng(11)
    sizes = [1, 2, 3, 4, 7, 8, 9, 10, 31]
    bounds = np.cumsum([0, *sizes])
    out_levels = rng.integers(80, 90, bounds[-1]) * 0.5
    in_levels = rng.integers(400, 420, bounds[-1]) * 0.5
    lo, hi = _smoothed(out_levels, bounds), _smoothed(in_levels, bounds)
    for a, b in itertools.pairwise(bounds):
        k = min(9, 2 * ((b - a) // 2) + 1) if b - a > 2 else 1
        for got, x in ((lo, out_levels), (hi, in_levels)):
            want = median_filter(x[a:b], size=k, mode="nearest")
            np.testing.assert_array_equal(got[a:b], want)


def test_median_is_numpys() -> None:
    rng = np.random.default_rng(0)
    for n in (1, 2, 3, 10, 11, 500):
        x = rng.normal(size=n)
        assert median(x) == float(np.median(x))
    assert np.isnan(median(np.array([1.0, np.nan, 2.0])))
    assert np.isnan(median(np.zeros(0)))
    # Infinities are values like any other.
    for x in ([-np.inf, 0.0, np.inf], [-np.inf, 1.0, 2.0, np.inf], [3.0, np.inf]):
        assert median(np.array(x)) == float(np.median(x))
    # overwrite_input: the same value, the caller's array partitioned instead of a copy
    for n in (10, 11):
        x = rng.normal(size=n)
        kept, work = x.copy(), x.copy()
        assert median(work, overwrite_input=True) == median(kept) == float(np.median(x))
        np.testing.assert_array_equal(kept, x)
        np.testing.assert_array_equal(np.sort(work), np.sort(x))
        assert not np.array_equal(work, x)  # partitioned in place


def test_bilinear_interpolates_and_is_nan_off_the_image() -> None:
    img = np.arange(20, dtype=np.uint8).reshape(4, 5) * 10
    xy = np.array([[1.25, 2.5], [0.0, 0.0], [4.0, 3.0], [-0.1, 1.0], [1.0, np.nan], [np.inf, 1]])
    v = bilinear(img, xy)
    # value = 10 * (5 y + x) for this ramp
    np.testing.assert_allclose(v[:3], [10 * (5 * 2.5 + 1.25), 0.0, 190.0])
    assert np.all(np.isnan(v[3:]))


@pytest.mark.parametrize("transpose", [False, True])
def test_both_edges_of_a_strip_under_uneven_light_are_where_the_strip_is(
    transpose: bool,
) -> None:
    """Light that changes across the scan lines tilts both plateaus. Levels taken at the
    strip's middle put both its edges off the same way, toward the light (the strip's
    centre line off by about rho half mid / slope: 0.06 px here, with the light 60 %
    brighter from one side of the image to the other), which turns the hub's axis
    against the beam's. The image is the closed form of a Gaussian blur of a lit box
    strip: for light L linear across, G * (L R) = L (G * R) + sigma^2 L' d(G * R)/dy
    exactly, sampled at pixel centres, with 2 DN of noise (seeded)."""
    h, w = 200, 500
    y0, slope, half, sigma, lo, hi = 97.3, 0.08, 10.2, 0.85, 45.0, 215.0
    rho = 3e-3  # the light's relative change per pixel down the image
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    light = 1.0 + rho * (y - y0)
    root = np.hypot(1.0, slope)
    d = (y - y0 - slope * x) / root
    box = ndtr((d + half) / sigma) - ndtr((d - half) / sigma)
    dbox_dy = np.exp(-0.5 * ((d + half) / sigma) ** 2) - np.exp(-0.5 * ((d - half) / sigma) ** 2)
    dbox_dy /= sigma * np.sqrt(2 * np.pi) * root
    v = light * (lo + (hi - lo) * box) + sigma**2 * rho * (hi - lo) * dbox_dy
    v += np.random.default_rng(7).normal(0.0, 2.0, v.shape)
    img = np.round(v).clip(0, 255).astype(np.uint8)
    xs = np.linspace(20.0, w - 20.0, 40)
    line = np.column_stack([xs, y0 + slope * xs])
    if transpose:  # the same strip along rows, the light across them
        img, line = np.ascontiguousarray(img.T), line[:, ::-1]
    edges = strip_edges(img, line, half, estimator="erf")
    a, b = edges.side_a, edges.side_b
    if transpose:
        a, b = a[:, ::-1], b[:, ::-1]
    assert len(a) > 400
    across = half * root
    err_a = a[:, 1] - (y0 + slope * a[:, 0] - across)
    err_b = b[:, 1] - (y0 + slope * b[:, 0] + across)
    centre = 0.5 * (err_a + err_b)

    # The noise of the mean at 4 sd (from the means of blocks of 20 lines: the levels
    # are smoothed over 9 lines, so neighbouring lines' errors are not independent),
    # plus the estimator's own second-order error, 2 rho sigma^2 (the erf model's
    # levels are flat within its window: the light's tilt there, times the step, and
    # the blur's sigma^2 L' term are both even bumps at the edge, each moving it
    # rho sigma^2 toward the dark side).
    def sem(x: np.ndarray) -> float:
        blocks = x[: len(x) // 20 * 20].reshape(-1, 20).mean(axis=1)
        return float(blocks.std() / np.sqrt(len(blocks)))

    tol = 4.0 * sem(centre) + 2.0 * rho * sigma**2
    assert abs(centre.mean()) < tol, (centre.mean(), tol)
    # The width is untouched by the tilt (the two edges' shifts cancel in it).
    width = err_b - err_a
    assert abs(width.mean()) < 4.0 * sem(width)
