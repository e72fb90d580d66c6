"""`beambench bench vision`'s timing: both methods on the same frames, taking turns."""

from __future__ import annotations

import math

import pytest

from daq.drivers.opencv_camera import JPEG_RST_INTERVAL_MCU
from pipelines.bench import vision as bv
from vision import Measurer
from vision.jpeg_regions import jpeg_layout


def test_both_methods_time_the_same_frames_and_measure_them() -> None:
    frames, _ = bv._frames("nominal", 2, 11)
    seconds, results = bv._time_methods(frames, ("default", "paper"), repeats=2)
    assert set(seconds) == {"default", "paper"}
    assert all(math.isfinite(s) and s > 0 for s in seconds.values())
    for method in ("default", "paper"):
        assert [m.method for m in results[method]] == [method, method]
        assert all(m.ok for m in results[method])
    # the default method within the nominal targets (issue #5) on these seeded frames
    err = bv._errors(frames, results["default"], seconds["default"])
    assert err["failed"] == 0
    assert err["lat_rms"] <= 0.06 and err["hub_rms"] <= 0.004 and err["lon_rms"] <= 0.08


def test_decode_included_timing_measures_the_parts_as_the_whole() -> None:
    """The decode-included table: both methods on the capture's JPEGs, the default
    method's parts giving exactly what the whole JPEG gives."""
    frames, _ = bv._frames("nominal", 2, 12)
    seconds, results, (d_hub, d_tip), fraction = bv._time_decoded(frames, repeats=1)
    assert all(math.isfinite(s) and s > 0 for s in seconds.values())
    assert all(m.ok for m in results["default"]) and all(m.ok for m in results["paper"])
    assert (d_hub, d_tip) == (0.0, 0.0)
    assert 0.0 < fraction < 1.0
    err = bv._errors(frames, results["default"], seconds["default"])
    assert err["lat_rms"] <= 0.06 and err["hub_rms"] <= 0.004


def test_colour_frames_are_measured_in_parts_as_the_whole() -> None:
    """The "nominal colour" row: the frames as the colour camera's driver writes them
    (4:2:0, its restart interval) are decoded in parts (a colour JPEG was decoded whole
    before), giving exactly what their whole gray decode gives, within the nominal
    targets."""
    frames, _ = bv._frames("nominal", 2, 12)
    jpeg = bv.colour_jpeg(frames[0].image)
    layout = jpeg_layout(jpeg)
    assert layout is not None and layout.segment_px == (16 * JPEG_RST_INTERVAL_MCU, 16)
    seconds, results, (d_hub, d_tip), fraction = bv._time_decoded(frames, 1, colour=True)
    assert all(m.ok for m in results["default"]) and all(m.ok for m in results["paper"])
    assert (d_hub, d_tip) == (0.0, 0.0)
    assert 0.0 < fraction < 0.5
    err = bv._errors(frames, results["default"], seconds["default"])
    assert err["lat_rms"] <= 0.06 and err["hub_rms"] <= 0.004


@pytest.mark.slow
def test_the_fast_sets_large_swinging_beams_are_measured_within_their_uncertainty() -> None:
    """The built-in synthetic bench at 2.35 Hz (tips up to 155 mm aside at up to 3.4 m/s,
    as its camera takes them): issue #20's damaged-frame check refused about half such
    frames ("damaged or occluded frame?") because the fit took the edges' distance apart
    across the axis as constant. Every frame is measured now, within 3 stated standard
    uncertainties."""
    frames, _ = bv._frames("fast", 4, bv.SEEDS["fast"])
    assert max(abs(f.truth.tip_lateral_m) for f in frames) > 0.12  # swung far aside
    results = [Measurer(f.calibration).measure(f.image) for f in frames]
    err = bv._errors(frames, results, 1.0)
    assert err["failed"] == 0, [m.reason for m in results if not m.ok]
    assert err["hub_cover"] == 1.0 and err["lat_cover"] == 1.0, err
    assert err["lat_rms"] < 0.1, err


def test_the_smear_sets_hub_and_mode_move_either_way_under_uneven_light() -> None:
    """The smear sets' exposures: the hub's and the first mode's shares with their own
    signs (the beam lagging the hub near a stroke end counter-moves), the set's smear the
    tip's where they add and a bound on every point's where they do not, each slice of the
    exposure moving no point more than its step; the light 10-20 % uneven."""
    import numpy as np

    rng = np.random.default_rng(3)
    counter = 0
    for _ in range(60):
        poses = bv._smeared(rng, 0.020)
        a, b = poses[0], poses[-1]
        k = len(poses)
        radius = bv.HUB_OFFSET_M + a.stations_m + a.longitudinal_m
        # first to last slice midpoint: (k - 1) of the k slices
        move = ((b.hub_angle_rad - a.hub_angle_rad) * radius + b.lateral_m - a.lateral_m) * k
        move /= max(k - 1, 1)
        hub_tip = (b.hub_angle_rad - a.hub_angle_rad) * radius[-1]
        mode_tip = b.lateral_m[-1] - a.lateral_m[-1]
        assert np.max(np.abs(move)) <= 0.020 * (1 + 1e-9)
        assert np.max(np.abs(move)) / k <= bv.SMEAR_STEP_M * (1 + 1e-9)
        if hub_tip * mode_tip < 0:
            counter += 1
            assert abs(move[-1]) < 0.020
        else:
            assert abs(move[-1]) == pytest.approx(0.020, rel=1e-9)
    assert 20 <= counter <= 40  # about half of 60 (binomial sd 3.9)
    for kind in ("smear-20", "smear-40"):
        spec = bv._variety_spec(kind, np.random.default_rng(1), 1)
        assert 0.10 <= spec.lighting_gradient <= 0.20
    assert bv._variety_spec("low-30", np.random.default_rng(1), 1).lighting_gradient == 0.0
