"""The overlays of a processed run made at once (issue #19): the same pixels, bit for bit,
as made frame by frame."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from pipelines.review.overlays import (
    frame_overlay,
    measured_parts,
    overlay_columns,
    spline_at,
)
from pipelines.review.viewer import OverlayColumns
from vision import Calibration, FrameMeasurement

IMG = [[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]]
PLANE = [[0.0, 0.0], [0.1, 0.0], [0.1, -0.1], [0.0, -0.1]]
PLAIN = Calibration(np.array(IMG), np.array(PLANE), beam_length_m=0.8)
# a skewed camera matrix: the lens goes through OpenCV, which maps the points of a call
# together (frame_overlay's calls are kept)
OPENCV = Calibration(
    np.array(IMG),
    np.array(PLANE),
    np.array([[900.0, 0.6, 260.0], [0.0, 905.0, 250.0], [0.0, 0.0, 1.0]]),
    np.array([-0.12, 0.05, 1e-3, -5e-4, 0.0]),
    beam_length_m=0.8,
)


def _measurements(cal: Calibration, n: int, rng: np.random.Generator) -> list[FrameMeasurement]:
    out = []
    for k in range(n):
        if k % 7 == 3:
            out.append(FrameMeasurement(ok=False, reason="beam not found" if k % 2 else ""))
            continue
        hub = rng.uniform(1.4, 1.8)
        axis = np.array([np.cos(hub), np.sin(hub)])
        normal = np.array([-axis[1], axis[0]])
        clamp = rng.uniform(-0.01, 0.01, 2)
        # the centre line: beyond the simulated beam at some frames, short at others
        points = (4, 1, 0, 2)[k % 4] if k % 5 == 0 else int(rng.integers(20, 60))
        s = np.sort(rng.uniform(-0.02, 0.85, points))
        lateral = 0.02 * (s / 0.8) ** 2 + rng.normal(scale=2e-4, size=points)
        line = clamp + np.outer(s, axis) + np.outer(lateral, normal)
        out.append(
            FrameMeasurement(
                ok=True,
                hub_angle_rad=hub,
                centreline_plane_m=line,
                centreline_px=cal.to_px(line) if points else np.zeros((0, 2)),
                hub_line_px=cal.to_px(np.vstack([clamp - 0.06 * axis, clamp])),
                clamp_plane_m=clamp,
                tip_plane_m=line[-1] if points else clamp + 0.8 * axis,
            )
        )
    return out


@pytest.mark.parametrize("cal", [PLAIN, OPENCV], ids=["formula", "opencv"])
@pytest.mark.parametrize("stations", [21, 3])
def test_the_overlays_made_at_once_are_frame_overlays_one_by_one(
    cal: Calibration, stations: int
) -> None:
    rng = np.random.default_rng(stations)
    n = 40
    ms = _measurements(cal, n, rng)
    st = np.linspace(0.0, 0.8, stations)
    w = 30
    lat = 0.02 * (st / 0.8) ** 2 * rng.uniform(-1.0, 1.0, (w, 1))
    lon = -rng.uniform(0.0, 1e-4, (w, 1)) * (st / 0.8) ** 2
    rows = rng.permutation(np.concatenate([np.arange(w), np.full(n - w, -1)]))
    scale = rng.choice([1.0, 0.5, 0.25], n)
    # the measured parts made ahead for some frames, here for the others
    parts = [measured_parts(m) if k % 3 else None for k, m in enumerate(ms)]
    one_by_one = [
        frame_overlay(
            m,
            cal.to_px,
            (st, lat[r], lon[r]) if r >= 0 else None,
            cal.beam_length_m,
            scale=float(scale[k]),
        )
        for k, (m, r) in enumerate(zip(ms, rows, strict=True))
    ]
    want = OverlayColumns.from_overlays(one_by_one)
    got = overlay_columns(ms, cal, (st, lat, lon), rows, scale, parts)
    assert cal.to_px_pointwise == (cal is PLAIN)
    assert want.counts["difference"].sum() > 0 and (want.counts["centreline"] == 0).sum() > 6
    for name in want.counts:
        np.testing.assert_array_equal(got.counts[name], want.counts[name], err_msg=name)
        assert got.points[name].shape == want.points[name].shape, name
        assert got.points[name].tobytes() == want.points[name].tobytes(), name
    np.testing.assert_array_equal(got.failed, want.failed)
    np.testing.assert_array_equal(got.given, want.given)
    assert [r for r, f in zip(got.reasons, got.failed, strict=True) if f] == [
        r for r, f in zip(want.reasons, want.failed, strict=True) if f
    ]
    # no simulated shape at all
    bare = overlay_columns(ms, cal, None, np.full(n, -1), scale)
    assert not bare.counts["sim_beam"].any() and not bare.counts["difference"].any()
    assert bare.points["centreline"].tobytes() == want.points["centreline"].tobytes()


def test_the_measured_parts_are_those_of_the_measurement() -> None:
    ms = _measurements(PLAIN, 8, np.random.default_rng(5))
    assert measured_parts(ms[3]) is None  # not measured
    p = measured_parts(ms[1])
    assert p is not None
    rel = ms[1].centreline_plane_m - ms[1].clamp_plane_m
    np.testing.assert_allclose(p.along, rel @ p.axis, rtol=0, atol=1e-15)
    np.testing.assert_allclose(p.across, rel @ p.normal, rtol=0, atol=1e-15)
    changed = dataclasses.replace(ms[1], hub_angle_rad=ms[1].hub_angle_rad + 0.1)
    q = measured_parts(changed)
    assert q is not None and not np.array_equal(q.axis, p.axis)


def test_spline_at_is_scipys_cubic_spline_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    for n in (4, 5, 9, 50, 400):
        for shape in ((), (1,), (3,), (2, 4)):
            x = np.cumsum(rng.uniform(0.001, 0.3, n)) + rng.uniform(-3.0, 3.0)
            y = rng.normal(size=(n, *shape)) * 10.0 ** rng.integers(-6, 2)
            inside = rng.uniform(x[0], x[-1], 40)
            at = np.concatenate([inside, x, [x[0], x[-1]], [x[0] - 0.5, x[-1] + 0.5]])
            want = CubicSpline(x, y, axis=0)(at)
            got = spline_at(x, y, at)
            assert got.shape == want.shape
            assert got.tobytes() == want.tobytes(), (n, shape)
            # at a scalar and at a 2-D array of times too
            assert spline_at(x, y, at[0]).tobytes() == CubicSpline(x, y, axis=0)(at[0]).tobytes()
            grid = inside.reshape(5, 8)
            assert spline_at(x, y, grid).tobytes() == CubicSpline(x, y, axis=0)(grid).tobytes()


def test_spline_at_leaves_scipy_the_cases_it_does_not_take() -> None:
    x = np.array([0.0, 0.5, 1.2])
    y = np.array([[0.0, 1.0], [0.3, 0.2], [0.1, -0.4]])
    at = np.array([0.1, 0.7, 1.2])
    for xs, ys in ((x, y), (x[:2], y[:2])):  # a parabola, a line: scipy's own
        assert spline_at(xs, ys, at).tobytes() == CubicSpline(xs, ys, axis=0)(at).tobytes()
    x4 = np.array([0.0, 0.5, 1.2, 2.0])
    for bad_x, bad_y in (
        (x4, np.array([0.0, np.nan, 1.0, 2.0])),  # not finite
        (np.array([0.0, 0.5, 0.5, 2.0]), np.ones(4)),  # not increasing
    ):
        with pytest.raises(ValueError) as scipy_says:
            CubicSpline(bad_x, bad_y, axis=0)
        with pytest.raises(ValueError, match=str(scipy_says.value)):
            spline_at(bad_x, bad_y, at)
