from __future__ import annotations

import math

import numpy as np
import pytest

from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamPose


def test_straight_beam_centre_line_matches_the_geometry(clean_spec, vt) -> None:
    """Across the strip, the brightness-weighted centre of each image column lies on the
    projection of the beam axis (no distortion, so the axis is a straight image line)."""
    th = math.radians(330.0)
    frame = render_frame(clean_spec, [BeamPose.straight(th, vt.L_M)])
    img = frame.image.astype(float)
    e = np.array([math.cos(th), math.sin(th)])
    a = np.array([0.3, 0.7])
    ends = clean_spec.to_px(a[:, None] * e)
    bg = clean_spec.background_dn
    errs = []
    for x in range(int(ends[0, 0]) + 5, int(ends[1, 0]) - 5, 7):
        y_axis = np.interp(x, ends[:, 0], ends[:, 1])
        rows = np.arange(int(y_axis) - 25, int(y_axis) + 26)
        v = img[rows, x] - bg
        errs.append(np.sum(v * rows) / np.sum(v) - y_axis)
    # 4x4 supersampling and 8-bit rounding leave a few hundredths of a pixel per column;
    # the strip narrowing with depth moves the brightness centre by ~0.005 px.
    assert abs(np.mean(errs)) < 0.02, np.mean(errs)  # perspective shifts it ~0.005 px
    assert np.max(np.abs(errs)) < 0.08, np.max(np.abs(errs))
    # Its brightness-area across a column is the beam width in pixels (sec of the angle).
    assert frame.truth.tip_lateral_m == 0.0 and frame.truth.hub_angle_rad == th


def test_registration_corners_in_truth_are_dark_light_corners(clean_spec, vt) -> None:
    frame = render_frame(clean_spec, [BeamPose.straight(math.radians(280), vt.L_M)])
    c = frame.truth.corners_px
    centre = c.mean(axis=0)
    img = frame.image.astype(float)
    for p in c:
        out = p + 3 * (p - centre) / np.linalg.norm(p - centre)
        inn = p - 3 * (p - centre) / np.linalg.norm(p - centre)
        # Inside the crossing square: groove (dark); diagonally outside: plate (light).
        assert img[round(inn[1]), round(inn[0])] < 80
        assert img[round(out[1]), round(out[0])] > 150


def test_noise_level(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [BeamPose.straight(4.5, vt.L_M)])
    patch = frame.image[1400:1500, 100:300].astype(float)
    assert patch.std() == pytest.approx(2.0, rel=0.15)


def test_motion_blur_spreads_the_beam(clean_spec, vt) -> None:
    poses = [vt.bent(math.radians(300) + d, 0.0) for d in np.linspace(-0.004, 0.004, 5)]
    sharp = render_frame(clean_spec, poses[2:3]).image
    blurred = render_frame(clean_spec, poses).image
    assert np.count_nonzero(blurred > 100) > np.count_nonzero(sharp > 100)
    assert np.abs(blurred.astype(int) - sharp).max() > 50


def test_no_poses_are_refused(clean_spec, vt) -> None:
    with pytest.raises(ValueError, match="poses"):
        render_frame(clean_spec, [])
