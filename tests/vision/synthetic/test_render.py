from __future__ import annotations

import math

import numpy as np
import pytest

from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamMotion, BeamPose


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


@pytest.mark.slow
def test_a_blurred_frame_is_the_time_average_of_sharp_ones(vt) -> None:
    """Coverage and lighting are linear: the frame of a motion is the mean of the frames
    of its poses (to the 8-bit rounding of each), whatever the hub's size."""
    spec = vt.make_spec(noise_dn=0.0, seed=4, hub_length_m=0.068, hub_width_m=0.051)
    motion = BeamMotion(vt.bent(math.radians(280), 0.03), 12.0)
    poses = motion.exposure_poses(0.0005, 0.008, max_step_m=1e-3)
    assert len(poses) == 6  # 12 rad/s x 0.843 m x 0.5 ms = 5.1 mm of tip smear
    blurred = render_frame(spec, poses).image.astype(float)
    mean = np.mean([render_frame(spec, [p]).image.astype(float) for p in poses], axis=0)
    assert np.abs(blurred - mean).max() <= 1.0
    assert np.abs(blurred - render_frame(spec, poses[2:3]).image).max() > 50


def test_the_hub_is_drawn_to_its_size(vt) -> None:
    """A 68 x 51 mm clamp block ending 8 mm past the pivot: bright inside, background
    just beyond its back face and beside it."""
    spec = vt.make_spec(noise_dn=0.0, seed=4, hub_length_m=0.068, hub_width_m=0.051)
    th = math.radians(290)
    image = render_frame(spec, [BeamPose.straight(th, vt.L_M)]).image
    e = np.array([math.cos(th), math.sin(th)])
    n = np.array([-e[1], e[0]])
    inside = [(-0.05, 0.02), (-0.01, -0.02), (0.004, 0.0)]
    outside = [(-0.066, 0.0), (-0.03, 0.031), (0.012, 0.02)]
    for pts, lo, hi in ((inside, 150, 256), (outside, 0, 60)):
        px = spec.to_px(np.array([a * e + b * n for a, b in pts]))
        v = image[np.rint(px[:, 1]).astype(int), np.rint(px[:, 0]).astype(int)]
        assert np.all((v >= lo) & (v < hi)), (pts, v)
