"""Rough location of the beam and hub on rendered frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vision import Measurer
from vision.errors import FrameFailure
from vision.locate import crossings, find_strip, locate, profile_levels, search_circles
from vision.synthetic.render import render_frame


def test_premapped_search_circles_change_nothing_and_hub_centres_lie_on_its_axis(
    nominal_spec, vt
) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.05)])
    m = Measurer(vt.truth_calibration(frame.truth))
    args = (frame.image, m.calibration.to_px, vt.L_M, vt.W_M, m.px_m)
    a = locate(*args)
    b = locate(*args, circles=search_circles(m.calibration.to_px, vt.L_M, vt.W_M, m.px_m))
    for name in ("beam", "clamp", "hub_back", "hub_width", "tip", "hub"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # The hub's profile centres (the first axis estimate) lie on its axis, which passes
    # through the pivot (the plane origin).
    th = frame.truth.hub_angle_rad
    assert len(a.hub) >= 2
    across = a.hub[:, 0] * math.sin(th) - a.hub[:, 1] * math.cos(th)
    assert np.max(np.abs(across)) < 0.5e-3


def test_crossings_found_by_the_caller_are_used_as_found(nominal_spec, vt) -> None:
    """A caller that has found the circles' crossings (the region reader) hands them
    on: the same rough location and measurement as finding them again, and a different
    pair is taken as given, not searched for again."""
    frame = render_frame(nominal_spec, [vt.bent(math.radians(290), -0.03)])
    m = Measurer(vt.truth_calibration(frame.truth))
    circles = search_circles(m.calibration.to_px, vt.L_M, vt.W_M, m.px_m)
    found = crossings(frame.image, circles, vt.W_M)
    assert found is not None
    args = (frame.image, m.calibration.to_px, vt.L_M, vt.W_M, m.px_m, circles)
    a, b = locate(*args), locate(*args, found=found)
    for name in ("beam", "clamp", "hub_back", "hub_width", "tip", "hub"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    r0, r1 = m.measure(frame.image), m.measure(frame.image, crossings_m=found)
    assert r0.ok and r1.ok
    assert (r0.hub_angle_rad, r0.tip_lateral_m) == (r1.hub_angle_rad, r1.tip_lateral_m)
    # 90 deg off the beam: nothing to follow there, and the frame is not measured
    turned = (
        np.array([[0.0, -1.0], [1.0, 0.0]]) @ found[0],
        np.array([[0.0, -1.0], [1.0, 0.0]]) @ found[1],
        found[2],
    )
    with pytest.raises(FrameFailure):
        locate(*args, found=turned)
    assert not m.measure(frame.image, crossings_m=turned).ok


def test_find_strip_with_precomputed_levels_is_the_same() -> None:
    rng = np.random.default_rng(2)
    offs = np.arange(-100.0, 100.5, 0.75)
    for k in range(20):
        centre, width = rng.uniform(-40, 40), rng.uniform(15, 25)
        v = 40 + 150 * (np.abs(offs - centre) < width / 2) + rng.normal(0, 3, len(offs))
        v += 120 * (np.abs(offs - centre - 50) < 4)  # a brighter bar beside it
        expect = centre + rng.uniform(-3, 3)
        lo, hi = profile_levels(v[None, :])[0]
        a = find_strip(v, offs, expect, near=12.0)
        b = find_strip(v, offs, expect, near=12.0, levels=(float(lo), float(hi)))
        assert a is not None and b is not None, k
        assert (a.centre, a.width, a.contrast) == (b.centre, b.width, b.contrast), k
        assert abs(a.centre - centre) < 0.5 and abs(a.width - width) < 1.0, k


def test_search_circles_sample_each_image_shape_with_its_own_plan() -> None:
    """The circles' sampling plan is kept per image shape: frames of another size are
    sampled at the same points with their own plan (NaN off the image), not with the
    first shape's gather indices."""
    from vision.sampling import bilinear

    centre = np.array([150.0, 110.0])
    scale = 1.0 / 1.5e-3  # px per m

    def to_px(p: np.ndarray) -> np.ndarray:
        return centre + np.asarray(p) * np.array([scale, -scale])

    circles = search_circles(to_px, 0.6, 0.012, 1.5e-3)
    rng = np.random.default_rng(7)
    small = rng.integers(0, 256, (240, 300), dtype=np.uint8)
    large = rng.integers(0, 256, (400, 520), dtype=np.uint8)
    for image in (small, large, small):
        v1, v2 = circles.sample(image)
        np.testing.assert_array_equal(v1, bilinear(image, circles.px[0]))
        np.testing.assert_array_equal(v2, bilinear(image, circles.px[1]))
    assert set(circles.plans) == {small.shape, large.shape}
    # the small frame cuts the outer circle (NaN there), not the inner one
    assert np.isnan(v2).any() and np.isfinite(v2).any() and np.isfinite(v1).all()


def test_the_follows_batches_change_nothing(nominal_spec, vt, monkeypatch) -> None:
    """The follow samples its cross-profiles a batch at a time only to save work: one
    profile at a time finds the same rough geometry, bit for bit."""
    import vision.locate as vloc

    frame = render_frame(nominal_spec, [vt.bent(math.radians(280), 0.04)])
    m = Measurer(vt.truth_calibration(frame.truth))
    args = (frame.image, m.calibration.to_px, vt.L_M, vt.W_M, m.px_m)
    a = locate(*args)
    monkeypatch.setattr(vloc, "_FOLLOW_BATCH", 1)
    monkeypatch.setattr(vloc, "_FOLLOW_MORE", (1,))
    b = locate(*args)
    for name in ("beam", "clamp", "hub_back", "hub_width", "tip", "hub", "beam_width"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
