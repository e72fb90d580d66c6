"""The compiled tube rasterisation of vision.regions against the numpy form it replaced
(kept here as the reference): the same points along the same lines, the same blocks."""

from __future__ import annotations

import math
from unittest import mock

import cv2
import numpy as np
import pytest

from vision.config import CameraConfig, CameraPoseConfig
from vision.measure import Measurer
from vision.regions import (
    RegionReader,
    _median_of_segments,
    _missing,
    _missing_segments,
    _tube_pixels,
    _tube_points,
)
from vision.synthetic.render import render_frame


def _dense_line_numpy(line: np.ndarray, half_m: float) -> tuple[np.ndarray, np.ndarray] | None:
    """regions._dense_line before the kernel."""
    if not np.isfinite(line).all():
        line = line[np.all(np.isfinite(line), axis=1)]
    if len(line) < 2:
        return None
    if len(line) == 2:
        (x0, y0), (x1, y1) = line.tolist()
        length = math.hypot(x1 - x0, y1 - y0)
        if not length > 0:
            return None
        n = max(2, int(length / (0.5 * half_m)) + 2)
        u = np.arange(n, dtype=np.float64) / (n - 1)
        pts = np.empty((n, 2))
        pts[:, 0] = x0 + u * (x1 - x0)
        pts[:, 1] = y0 + u * (y1 - y0)
        pts[-1] = x1, y1
        t = np.empty((n, 2))
        t[:] = (x1 - x0) / length, (y1 - y0) / length
        return pts, t
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))))
    if not s[-1] > 0:
        return None
    sq = np.linspace(0.0, s[-1], max(2, int(s[-1] / (0.5 * half_m)) + 2))
    pts = np.column_stack([np.interp(sq, s, line[:, 0]), np.interp(sq, s, line[:, 1])])
    t = np.gradient(pts, axis=0)
    t /= np.maximum(np.hypot(t[:, 0], t[:, 1]), 1e-12)[:, None]
    return pts, t


def _points_numpy(tubes: list[tuple[np.ndarray, float]]) -> tuple[np.ndarray, np.ndarray] | None:
    """RegionReader._tubes' points before the kernel: (centres, sides +, sides -) and the
    first point of each tube kept; None when no tube is kept."""
    centres, tangents, halves, counts = [], [], [], []
    for line_m, half_m in tubes:
        got = _dense_line_numpy(np.asarray(line_m, dtype=np.float64), half_m)
        if got is not None:
            centres.append(got[0])
            tangents.append(got[1])
            halves.append(half_m)
            counts.append(len(got[0]))
    if not centres:
        return None
    pts = np.concatenate(centres)
    t = np.concatenate(tangents)
    n = np.array(counts)
    first = np.cumsum(n) - n
    last = first + n - 1
    h = np.repeat(np.array(halves, dtype=np.float64), n)[:, None]
    pts[first] -= h[first] * t[first]
    pts[last] += h[last] * t[last]
    off = h * t[:, ::-1]
    off[:, 0] = -off[:, 0]
    return np.concatenate((pts, pts + off, pts - off)), first


def _tubes_numpy(
    to_px: object, shape: tuple[int, int], tubes: list[tuple[np.ndarray, float]]
) -> np.ndarray:
    """RegionReader._tubes before the kernels."""
    mask = np.zeros(shape, dtype=np.uint8)
    got = _points_numpy(tubes)
    if got is None:
        return mask.view(bool)
    pts3, first = got
    k = len(pts3) // 3
    px_all = to_px(pts3)  # type: ignore[operator]
    if not np.all(np.isfinite(px_all)):
        return np.ones(shape, dtype=bool)
    centre = px_all[:k]
    side = np.maximum(
        np.hypot(*(px_all[k : 2 * k] - centre).T), np.hypot(*(px_all[2 * k :] - centre).T)
    )
    half_px = np.maximum.reduceat(side, first).tolist()
    blk = np.clip(centre / 8 * 16.0, -(2**27), 2**27).round().astype(np.int32)
    ends = [*first.tolist()[1:], k]
    for i0, i1, hp in zip(first.tolist(), ends, half_px, strict=True):
        thick = min(2 * math.ceil(hp / 8) + 3, 32767)
        cv2.polylines(mask, [blk[i0:i1].reshape(-1, 1, 2)], False, 1, thick, shift=4)
    return mask.view(bool)


@pytest.fixture(scope="module")
def reader(vt) -> RegionReader:
    """A reader on a camera that is not beambench's (smaller, tilted and rolled)."""
    spec = vt.make_spec(
        camera=CameraConfig(width_px=960, height_px=720, focal_length_px=760.0),
        pose=CameraPoseConfig(tilt_rad=math.radians(9.0), roll_rad=math.radians(3.0)),
        seed=5,
    )
    fr = render_frame(spec, [vt.bent(math.radians(280.0), 0.04)])
    return RegionReader(Measurer(vt.truth_calibration(fr.truth)))


def _random_tubes(rng: np.random.Generator) -> list[tuple[np.ndarray, float]]:
    """Straight lines and polylines about the pivot (m), some with NaN points, repeated
    points, no length or a single point."""
    tubes = []
    for _ in range(int(rng.integers(1, 8))):
        k = int(rng.choice([1, 2, 2, 3, 5, 30]))
        start = rng.normal(0, 0.3, 2)
        line = start + np.cumsum(rng.normal(0, 0.1, (k, 2)), axis=0)
        roll = rng.random()
        if roll < 0.15:
            line[int(rng.integers(k))] = np.nan
        elif roll < 0.25 and k > 2:
            line[1] = line[0]  # a repeated point: a step of no length
        elif roll < 0.3:
            line[:] = line[0]  # no length at all
        tubes.append((line, float(rng.uniform(0.003, 0.08))))
    return tubes


def test_tube_points_are_the_numpy_forms(reader) -> None:
    """The same points (equal to an ulp: the arc lengths' hypot, libm's against
    CPython's for straight lines) and the same tubes kept."""
    rng = np.random.default_rng(8)
    for _ in range(300):
        tubes = _random_tubes(rng)
        want = _points_numpy(tubes)
        lines = np.concatenate([line for line, _ in tubes])
        counts = np.array([len(line) for line, _ in tubes], dtype=np.intp)
        halves = np.array([h for _, h in tubes])
        pts, first, bounded = _tube_points(lines, counts, halves)
        assert bounded
        if want is None:
            assert first.size == 0 and pts.size == 0
            continue
        np.testing.assert_array_equal(first, want[1])
        np.testing.assert_allclose(pts, want[0], rtol=1e-14, atol=1e-15)


def test_tube_blocks_are_the_numpy_forms(reader) -> None:
    """The same blocks, random tubes and the reader's own (a frame's bands and scans)."""
    shape = (90, 120)
    to_px = reader.measurer.calibration.to_px
    rng = np.random.default_rng(9)
    for _ in range(300):
        tubes = _random_tubes(rng)
        np.testing.assert_array_equal(
            reader._tubes(shape, tubes), _tubes_numpy(to_px, shape, tubes)
        )
    p1, p2 = np.array([0.02, 0.18]), np.array([0.03, 0.31])
    for behind in (None, 0.9):
        got = reader._predicted(p1, p2, 0.02, shape, behind)
        with mock.patch.object(reader, "_tubes", wraps=reader._tubes) as spy:
            reader._predicted(p1, p2, 0.02, shape, behind)
        reader_tubes = spy.call_args.args[1]
        np.testing.assert_array_equal(got, _tubes_numpy(to_px, shape, reader_tubes))
        assert 0 < got.sum() < got.size


def test_tube_pixels_rounding_and_limits() -> None:
    """Half-way points round to even as np.round does; far points clip to +-2**27; the
    thickness from the widest side; a point not finite: nothing (everything, to the
    caller)."""
    centre = np.array([[0.25, 0.75], [1.25, -0.25], [1e12, -1e12]])  # 1/16 block: 0.5 px
    px = np.concatenate((centre, centre + np.array([0.0, 20.0]), centre - np.array([3.0, 0.0])))
    blk, thick = _tube_pixels(px, np.array([0, 2]), 8)
    np.testing.assert_array_equal(blk, [[0, 2], [2, 0], [2**27, -(2**27)]])
    np.testing.assert_array_equal(thick, [2 * 3 + 3, 2 * 3 + 3])
    px[4, 1] = np.nan
    blk, thick = _tube_pixels(px, np.array([0, 2]), 8)
    assert blk.size == 0 and thick.size == 0


def test_unbounded_tubes_cover_everything(reader) -> None:
    """A width of zero or a line a million km long: every block (the numpy form raised
    ZeroDivisionError on the first and ran out of memory on the second); a non-finite
    point is dropped, a single point is no tube."""
    shape = (90, 120)
    line = np.array([[0.0, 0.1], [0.0, 0.5]])
    assert reader._tubes(shape, [(line, 0.0)]).all()
    assert reader._tubes(shape, [(np.array([[0.0, 0.0], [1e9, 1e9]]), 0.01)]).all()
    with_inf = np.array([[0.0, 0.1], [0.0, np.inf], [0.05, 0.3]])
    got = reader._tubes(shape, [(with_inf, 0.01)])
    np.testing.assert_array_equal(got, reader._tubes(shape, [(with_inf[[0, 2]], 0.01)]))
    assert 0 < got.sum() < got.size
    assert not reader._tubes(shape, [(np.array([[0.0, 0.1]]), 0.01)]).any()


def test_median_of_samples_is_numpys() -> None:
    """Every 2nd row and 4th column of the segments' strip, read in place in the canvas,
    as np.median of the strip's slice: odd and even counts (the mean of the two middle
    values), ties, one segment, the extremes, none."""
    rng = np.random.default_rng(10)
    for seg_h, seg_w, per_row, rows in (
        (8, 32, 5, 4),
        (16, 64, 3, 3),
        (8, 8, 1, 6),
        (8, 32, 64, 2),
    ):
        for kind in ("uniform", "narrow", "two"):
            shape = (rows * seg_h, per_row * seg_w)
            if kind == "uniform":
                canvas = rng.integers(0, 256, shape, dtype=np.uint8)
            elif kind == "narrow":
                canvas = rng.integers(100, 104, shape, dtype=np.uint8)
            else:
                canvas = np.where(rng.random(shape) < 0.5, 0, 255).astype(np.uint8)
            for n in (1, 2, 3, rows * per_row):
                segs = np.sort(rng.choice(rows * per_row, n, replace=False)).astype(np.intp)
                strip = np.concatenate(
                    [
                        canvas[
                            s // per_row * seg_h : (s // per_row + 1) * seg_h,
                            s % per_row * seg_w : (s % per_row + 1) * seg_w,
                        ]
                        for s in segs
                    ]
                )
                got = _median_of_segments(canvas, per_row, segs, seg_h, seg_w, 2, 4)
                assert got == np.median(strip[::2, ::4])
                got = _median_of_segments(canvas, per_row, segs, seg_h, seg_w, 1, 1)
                assert got == np.median(strip)
    none = np.zeros(0, dtype=np.intp)
    canvas = np.zeros((8, 32), np.uint8)
    assert _median_of_segments(canvas, 1, none, 8, 32, 2, 4) == 128.0  # the numpy form's


def test_missing_segments_are_the_numpy_forms() -> None:
    """Segments hit by a block and not done: segment_hits(...) & ~done, its indices."""
    rng = np.random.default_rng(11)
    for interval, per_row, rows in (
        (1, 7, 5),
        (2, 5, 4),
        (3, 4, 6),
        (4, 9, 3),
        (8, 3, 5),
        (16, 16, 3),
        (24, 2, 3),
        (5, 1, 9),
    ):
        for density in (0.0, 0.01, 0.2, 1.0):
            blocks = rng.random((rows, per_row * interval)) < density
            done = rng.random(rows * per_row) < 0.3
            hits = blocks.reshape(rows * per_row, interval).any(axis=1)
            want = np.flatnonzero(hits & ~done)
            got = _missing(blocks, done, interval)
            np.testing.assert_array_equal(got, want)
            assert got.dtype == np.intp


def test_missing_segments_of_colour_jpegs_are_the_numpy_forms() -> None:
    """A colour JPEG's segment is ``interval * H`` blocks across and ``V`` down (here
    every H, V in {1, 2}; two block rows folded to one, then the word path for 4:4:4 and
    4:4:0 at beambench's interval of 4, the byte path otherwise): hit when one of its
    blocks is, missing when also not done."""
    rng = np.random.default_rng(12)
    for across, down, per_row, rows in (
        (8, 2, 5, 4),  # 4:2:0, interval 4
        (8, 2, 1, 3),
        (4, 2, 7, 3),  # 4:4:0, interval 4 (or 4:2:0 at 2)
        (8, 1, 6, 5),  # 4:2:2, interval 4
        (4, 1, 9, 3),  # 4:4:4, interval 4
        (2, 2, 3, 6),  # 4:2:0, interval 1
        (6, 2, 4, 2),  # 4:2:0, interval 3
        (32, 2, 2, 3),
    ):
        for density in (0.0, 0.005, 0.05, 1.0):
            blocks = rng.random((rows * down, per_row * across)) < density
            done = rng.random(rows * per_row) < 0.3
            hits = np.array(
                [
                    blocks[r * down : (r + 1) * down, c * across : (c + 1) * across].any()
                    for r in range(rows)
                    for c in range(per_row)
                ]
            )
            want = np.flatnonzero(hits & ~done)
            got = _missing_segments(blocks, done, across, down)
            np.testing.assert_array_equal(got, want)
            assert got.dtype == np.intp
        # one block set at a time: each block belongs to exactly its own segment
        for r in range(rows * down):
            for c in range(per_row * across):
                one = np.zeros((rows * down, per_row * across), dtype=bool)
                one[r, c] = True
                own = r // down * per_row + c // across
                np.testing.assert_array_equal(
                    _missing_segments(one, np.zeros(rows * per_row, dtype=bool), across, down),
                    [own],
                )
    assert _missing_segments(np.zeros((0, 8), bool), np.zeros(0, bool), 8, 2).size == 0
