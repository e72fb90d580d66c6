"""vision.hub's kernels against the numpy forms they replace (tests/vision/hub_numpy.py):
the same decisions (points kept, failures) and the same numbers to rounding. Sums now
run in order where numpy summed pairwise (or BLAS dotted): over at most a few hundred
terms of one sign that moves a result by a few hundred ulps at most, so 1e-12 relative
(1e-13 m absolute on offsets of centimetres) is rounding, and a changed decision
(another point dropped, another step taken as the edge) would be orders larger."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.vision.hub_numpy import end_edge_numpy, hub_axis_numpy, rough_axis_numpy
from vision.errors import FrameFailure
from vision.hub import end_edge, hub_axis, rough_axis
from vision.locate import Rough


def _outcome(fn, *args, **kw):  # type: ignore[no-untyped-def]
    try:
        return fn(*args, **kw)
    except FrameFailure as exc:
        return str(exc)


def _edges(rng: np.random.Generator, n: int, theta: float, width: float, noise: float):  # type: ignore[no-untyped-def]
    e = np.array([math.cos(theta), math.sin(theta)])
    nn = np.array([-e[1], e[0]])
    back = rng.normal(0, 0.05, 2)
    length = rng.uniform(0.02, 0.1)
    pts = []
    for side in (0.5, -0.5):
        a = np.sort(rng.uniform(-0.005, length + 0.005, n))
        b = side * width + rng.normal(0, noise, n)
        if rng.uniform() < 0.7:  # outliers
            k = rng.integers(0, n, max(1, n // 10))
            b[k] += rng.normal(0, 30 * noise, k.size)
        pts.append(back + a[:, None] * e + b[:, None] * nn)
    rough = np.array([math.cos(theta + 0.03), math.sin(theta + 0.03)])
    return pts[0], pts[1], back, back + length * e, rough


def test_hub_axis_is_the_numpy_forms() -> None:
    rng = np.random.default_rng(31)
    failed = 0
    for k in range(400):
        n = int(rng.integers(3, 200))
        noise = float(rng.uniform(1e-6, 2e-4)) if k % 7 else 0.0  # exact lines: r all 0
        pa, pb, back, front, e = _edges(rng, n, rng.uniform(-np.pi, np.pi), 0.03, noise)
        margin = float(rng.uniform(0.0, 0.01))
        want = _outcome(hub_axis_numpy, pa, pb, back, front, e, margin)
        got = _outcome(hub_axis, pa, pb, back, front, e, margin)
        if isinstance(want, str):
            assert got == want, k
            failed += 1
            continue
        assert not isinstance(got, str), k
        for g, w in zip(got, want, strict=True):
            np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-13, err_msg=str(k))
    assert 10 <= failed < 300  # both outcomes


def test_end_edge_is_the_numpy_forms() -> None:
    rng = np.random.default_rng(32)
    h, w = 300, 330
    yy, xx = np.mgrid[0:h, 0:w]
    outcomes = {"edge": 0, "failure": 0}
    for k in range(60):
        # a bright bar ending at x0 (blurred), light falling across the image
        x0 = rng.uniform(120, 250)
        blur = rng.uniform(0.5, 4)
        level = rng.uniform(5, 120) if k % 6 else 3.0  # some too faint: no clear edge
        img = 40 + level / (1 + np.exp((xx - x0) / blur)) * (np.abs(yy - 150) < 30)
        img = np.clip(img + 0.1 * xx + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
        scale = rng.uniform(800, 1200)  # px per m
        origin_px = np.array([rng.uniform(20, 60), 150.0])

        def to_px(p: np.ndarray, s: float = scale, o: np.ndarray = origin_px) -> np.ndarray:
            return o + np.asarray(p) * np.array([s, -s])

        theta = rng.normal(0, 0.05)
        e = np.array([math.cos(theta), math.sin(theta)])
        n = np.array([-e[1], e[0]])
        lateral = np.linspace(-0.01, 0.01, int(rng.integers(1, 7)))
        guess = (x0 - origin_px[0]) / scale + rng.normal(0, 0.005)
        reach = rng.uniform(0.01, 0.05) if k % 10 else 0.5  # some reach off the image
        args = (img, np.zeros(2), e, n, lateral, guess, reach)
        kw = {"to_px": to_px, "px_m": 1.0 / scale}
        want = _outcome(end_edge_numpy, *args, **kw)
        got = _outcome(end_edge, *args, **kw)
        if isinstance(want, str):
            assert got == want, k
            outcomes["failure"] += 1
        else:
            assert not isinstance(got, str), k
            assert got == pytest.approx(want, rel=1e-12, abs=1e-13), k
            outcomes["edge"] += 1
    assert min(outcomes.values()) >= 10


def test_the_rough_axis_is_the_svds() -> None:
    # the major axis in closed form against the SVD's first right singular vector: the
    # same line to rounding (both exact for the scatter's 2 x 2 eigenproblem)
    rng = np.random.default_rng(33)
    for k in range(300):
        theta = rng.uniform(-np.pi, np.pi)
        e = np.array([math.cos(theta), math.sin(theta)])
        back = rng.normal(0, 0.1, 2)
        length = rng.uniform(0.01, 0.1)
        a = np.sort(rng.uniform(0, length, int(rng.integers(0, 30))))
        hub = back + a[:, None] * e + rng.normal(0, 1e-4, (a.size, 2))
        clamp = back + (length + rng.uniform(0.001, 0.01)) * e
        rough = Rough(np.zeros((2, 2)), clamp, back, 0.03, clamp, hub)
        want, got = rough_axis_numpy(rough), rough_axis(rough)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-14, err_msg=str(k))


def test_the_hub_axis_sd_covers_the_tilt_of_an_edge_that_steps() -> None:
    """Two parallel edges, one with a bar lying against part of it (its points step out
    3-13 mm over 10-45 % of the edge): the fits before the last robust pass tilt toward
    the step, and the step's points are then dropped or kept in one run. The sd from
    the residuals' scatter put the tilt beyond 3 of it on 1 in 5 such edges, up to 10;
    with the kept points' own turn and the two edges' disagreement (Birge's ratio),
    every tilt is within 3 (0 of 592 beyond 3, the largest 2.98, the median 0.85; on
    frames of both renderers with such bars, 8 of 29 were beyond 3 and 0 of 30 are, the
    largest 1.04; the plain bench sets' unchanged)."""
    rng = np.random.default_rng(12)
    z = []
    for _ in range(60):
        th = rng.uniform(-np.pi, np.pi)
        e = np.array([math.cos(th), math.sin(th)])
        nn = np.array([-e[1], e[0]])
        px = 4.5e-4
        length, width = rng.uniform(0.1, 0.25), rng.uniform(0.03, 0.06)
        a = np.arange(0.0, length, 1.3 * px)
        noise = rng.uniform(0.03, 0.3) * px
        frac = rng.uniform(0.1, 0.45)
        start = rng.uniform(0.0, 1.0 - frac) * length
        step = np.where((a > start) & (a < start + frac * length), rng.uniform(0.003, 0.013), 0.0)
        side = 1.0 if rng.uniform() < 0.5 else -1.0
        back = rng.normal(0, 0.05, 2)
        edges = []
        for s in (1.0, -1.0):
            b = s * (0.5 * width + (step if s == side else 0.0)) + rng.normal(0, noise, a.size)
            edges.append(back + a[:, None] * e + b[:, None] * nn)
        got, _, _, _, sd = hub_axis(*edges, back, back + length * e, e + 0.02 * nn, 10 * px)
        tilt = math.asin(float(got[0] * e[1] - got[1] * e[0]))
        z.append(abs(tilt) / sd)
    assert max(z) <= 3.0, np.sort(z)[-5:]
