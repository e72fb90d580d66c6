"""vision.locate's search kernels against the numpy forms they replace
(tests/vision/locate_numpy.py): the same decisions (which run, which profile, which
peak) and the same numbers to the last bit (the same arithmetic in the same order;
levels and medians are order statistics)."""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d

from tests.vision.locate_numpy import (
    circle_candidates_numpy,
    find_strip_numpy,
    follow_numpy,
    strip_end_numpy,
)
from vision.locate import (
    _HUB_WIDENING,
    _circle_candidates,
    _extreme_wrap,
    _follow_batch,
    _grid,
    _hub_run,
    _offset_grid,
    _strip_end_at,
    _uniform_wrap,
    find_strip,
    profile_levels,
)


def _profile(rng: np.random.Generator, offs: np.ndarray, centre: float, width: float) -> np.ndarray:
    v = 30 + rng.uniform(0, 200) * (np.abs(offs - centre) < width / 2) + rng.normal(0, 4, offs.size)
    if rng.uniform() < 0.5:  # a second bar, maybe brighter
        v += rng.uniform(0, 250) * (np.abs(offs - centre - rng.uniform(-60, 60)) < 3)
    if rng.uniform() < 0.2:  # integer levels: ties at the threshold
        v = np.round(v)
    return v


def test_find_strip_decides_and_measures_as_the_numpy_form() -> None:
    rng = np.random.default_rng(21)
    offs = np.arange(-100.0, 100.5, 0.75)
    seen = {"none": 0, "found": 0}
    for k in range(3000):
        v = _profile(rng, offs, rng.uniform(-110, 110), rng.uniform(2, 40))
        if k % 5 == 0:  # off the image at one end: kept (>= 70 % on it) or not
            v[: int(rng.integers(1, 80))] = np.nan
        if k % 11 == 0:
            v[:] = 90.0 + rng.normal(0, 3, v.size)  # no contrast
        expect = rng.uniform(-100, 100)
        near = None if k % 3 == 0 else float(rng.uniform(0.2, 40))
        want = find_strip_numpy(v, offs, expect, near=near)
        got = find_strip(v, offs, expect, near=near)
        if want is None:
            assert got is None, k
            seen["none"] += 1
            continue
        assert got is not None, k
        assert (got.centre, got.width, got.contrast) == (want.centre, want.width, want.contrast), k
        seen["found"] += 1
        if np.isfinite(v).all():
            lo, hi = profile_levels(v[None, :])[0]
            again = find_strip(v, offs, expect, near=near, levels=(float(lo), float(hi)))
            assert again == got
    assert min(seen.values()) > 300  # both outcomes tested many times


def test_the_follows_search_is_the_numpy_forms_batch_by_batch() -> None:
    rng = np.random.default_rng(22)
    offs = np.arange(-50.0, 50.4, 0.75)
    lost = {True: 0, False: 0}
    for k in range(400):
        width = float(rng.uniform(4, 12))
        rows, centre, w = [], 0.0, width
        for _ in range(int(rng.integers(1, 40))):
            centre += rng.normal(0, 1.5)
            if rng.uniform() < 0.05:
                w = width * rng.uniform(1.2, 2.5)  # the hub, or a strip widening
            rows.append(_profile(rng, offs, centre, w))
            if rng.uniform() < 0.08:
                rows[-1][: int(rng.integers(1, 60))] = np.nan
            if rng.uniform() < 0.05:
                rows[-1][:] = 40.0  # a profile missed
        vals = np.array(rows)
        to_hub = bool(k % 2)
        want = follow_numpy(vals, offs, width, to_hub, _HUB_WIDENING)
        # in batches of random sizes, the state carried from one to the next
        state = (0.0, width, False)
        found, centres, widths, gone = [], [], [], False
        b0 = 0
        while b0 < len(vals) and not gone:
            size = int(rng.integers(1, 20))
            batch = vals[b0 : b0 + size]
            cb, wb = np.empty(len(batch)), np.empty(len(batch))
            kb = np.empty(len(batch), np.int64)
            count, *rest = _follow_batch(batch, offs, 0.75, width, to_hub, *state, cb, wb, kb)
            state, gone = (rest[0], rest[1], rest[2]), rest[3]
            found += (kb[:count] + b0).tolist()
            centres += cb[:count].tolist()
            widths += wb[:count].tolist()
            b0 += len(batch)
        assert (found, centres, widths, gone) == want, k
        lost[gone] += 1
    assert min(lost.values()) > 50


def test_the_circles_strips_are_the_numpy_forms() -> None:
    rng = np.random.default_rng(23)
    counts = []
    for k in range(300):
        n = int(rng.integers(40, 1500))
        phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
        step = float(rng.uniform(0.5e-3, 2e-3))
        width = float(rng.uniform(2, 30)) * step
        v = 40 + rng.normal(0, rng.uniform(0.5, 6), n)
        for _ in range(int(rng.integers(0, 6))):  # strips, some across the wrap
            c, w = int(rng.integers(0, n)), rng.uniform(0.3, 3) * width / step
            idx = np.arange(int(c - w / 2), int(c + w / 2) + 1) % n
            v[idx] += rng.uniform(5, 200)
        if k % 4 == 0:
            v = np.round(v)  # plateaus: ties between neighbours
        if k % 5 == 0:  # a stretch off the image (NaN), sometimes nearly all of it
            a = int(rng.integers(0, n))
            v[a : a + int(rng.integers(1, n))] = np.nan
        accept = (
            None if k % 2 else (float(rng.uniform(1, 5)) * step, float(rng.uniform(5, 60)) * step)
        )
        want = circle_candidates_numpy(v, phi, width, step, accept)
        got = _circle_candidates(v, phi, width, step, accept)
        assert got == want, k
        counts.append(len(got))
    assert counts.count(0) > 20 and max(counts) >= 3


def test_the_top_hats_filters_are_scipys_bit_for_bit() -> None:
    rng = np.random.default_rng(24)
    for t in range(2000):
        n = int(rng.integers(1, 300))
        x = rng.normal(size=n) * 50
        if t % 3 == 0:
            x = np.round(x)  # ties
        size = int(rng.integers(1, 2 * n + 5))  # windows wider than the circle too
        origin = int(rng.integers(-(size // 2), (size - 1) // 2 + 1))
        np.testing.assert_array_equal(
            _uniform_wrap(x, size), uniform_filter1d(x, size, mode="wrap")
        )
        for is_max, f in ((True, maximum_filter1d), (False, minimum_filter1d)):
            want = f(x, size, mode="wrap", origin=origin)
            start, sign = -(size // 2) - origin, 1.0 if is_max else -1.0
            np.testing.assert_array_equal(_extreme_wrap(x, size, start, sign), want)
    assert math.isnan(_uniform_wrap(np.array([1.0, np.nan]), 1)[1])


def test_the_strip_ends_where_the_numpy_form_ends_it() -> None:
    rng = np.random.default_rng(25)
    ends = set()
    for k in range(500):
        n = int(rng.integers(10, 400))
        end = int(rng.integers(1, n + 20))  # some strips run past the samples
        v = 30 + rng.normal(0, 3, n)
        v[:end] += rng.uniform(0, 200)
        if k % 4 == 0:
            v = np.round(v)  # ties at the threshold
        if k % 5 == 0:
            v[int(rng.integers(0, n)) :] = np.nan  # off the image, maybe from the start
        inside = int(rng.integers(1, n // 2 + 2))
        got = _strip_end_at(v, inside)
        assert got == strip_end_numpy(v, inside), k
        ends.add(min(got, 1))
    assert ends == {-1, 1}


def _hub_run_numpy(widths, wider):
    """locate's hub run in its former numpy form (None: fewer than two wide)."""
    wide = np.flatnonzero(widths > wider)
    if wide.size < 2:
        return None
    k0 = int(wide[0])
    hub_w = widths[k0:]
    med = float(np.median(hub_w))
    keep = np.abs(hub_w - med) < 0.25 * med
    bad2 = ~keep[:-1] & ~keep[1:]
    last = int(np.argmax(bad2)) if bad2.any() else len(keep)
    while last > 0 and not keep[last - 1]:
        last -= 1
    return k0, med, keep, last


def test_the_hub_run_is_the_numpy_forms() -> None:
    """The hub's start, median width, kept widths and end as the numpy form found them,
    on widths that widen, wander, step off and back, tie at the limit, or hold NaN."""
    rng = np.random.default_rng(8)
    for trial in range(400):
        n = int(rng.integers(0, 40))
        w = rng.choice([0.02, 0.05], size=n) * (1.0 + 0.2 * rng.standard_normal(n))
        if trial % 5 == 0 and n:
            w[rng.integers(0, n)] = 0.03  # at the limit: not wider
        if trial % 7 == 0 and n:
            w[rng.integers(0, n)] = math.nan
        if trial % 3 == 0:
            w = np.sort(w)  # a clean run of hub widths after the beam's
        want = _hub_run_numpy(w, 0.03)
        n_wide, k0, med, keep, last = _hub_run(w, 0.03)
        if want is None:
            assert n_wide < 2
            continue
        assert (k0, last) == (want[0], want[3])
        np.testing.assert_array_equal(med, want[1])
        np.testing.assert_array_equal(keep, want[2])


def test_the_grids_are_the_numpy_forms() -> None:
    """The follow's and the end faces' sample grids against ``_grid`` of the numpy
    arrays they replace, bit for bit."""
    from vision.hub import _face_grid

    rng = np.random.default_rng(9)
    for k, m in ((1, 1), (3, 17), (16, 40)):
        t, off = rng.normal(size=k) * 0.3, rng.normal(size=m) * 0.01
        p, d, n = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        want = _grid(p[0] + t * d[0], p[1] + t * d[1], off * n[0], off * n[1])
        np.testing.assert_array_equal(_offset_grid(t, p, d, off * n[0], off * n[1]), want)
        want = _grid(off * n[0], off * n[1], p[0] + t * d[0], p[1] + t * d[1])
        np.testing.assert_array_equal(_face_grid(off, n, p, t, d), want)
