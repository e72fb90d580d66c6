from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from vision import (
    Measurer,
    calibration_from_registration,
    detect_registration_corners,
)
from vision.centreline import cantilever_eigenvalues, cantilever_modes_t
from vision.codec import decode, encode
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.render import render_frame, static_layers
from vision.synthetic.scene import BeamPose, Clutter


def _errors(m, tr) -> tuple[float, float, float]:
    d_hub = (m.hub_angle_rad - tr.hub_angle_rad + math.pi) % (2 * math.pi) - math.pi
    return (
        math.degrees(d_hub),
        (m.tip_lateral_m - tr.tip_lateral_m) * 1e3,
        (m.tip_longitudinal_m - tr.tip_longitudinal_m) * 1e3,
    )


def _swinging_cantilever(vt, hub_deg: float, amp, accel: float, peak_m: float) -> BeamPose:
    """A cantilever's shape on a swinging hub: the first three modes' static responses
    (amplitudes ``amp``) and a uniform inertial load (``accel``), scaled to ``peak_m`` at
    the tip (zero moment and shear at the free end)."""
    beta4 = np.array(cantilever_eigenvalues(3)) ** 4

    def load(s):  # type: ignore[no-untyped-def]
        x = s / vt.L_M
        return 8 * accel * (0.01 + x) + (np.array(amp) * beta4) @ cantilever_modes_t(x, 3)

    return BeamPose.from_load(math.radians(hub_deg), vt.L_M, load, peak_m)


def test_nominal_frames_are_measured_within_bounds(nominal_spec, vt) -> None:
    errs = []
    for hub_deg, slope in ((245.0, 0.05), (287.0, -0.06), (328.0, 0.03)):
        frame = render_frame(nominal_spec, [vt.bent(math.radians(hub_deg), slope)])
        cal = vt.truth_calibration(frame.truth)
        m = Measurer(cal).measure(frame.image)
        assert m.ok, m.reason
        errs.append(_errors(m, frame.truth))
        np.testing.assert_allclose(
            m.lateral_at_stations_m, frame.truth.lateral_at_stations_m, atol=1.5e-4
        )
        np.testing.assert_allclose(m.clamp_plane_m, frame.truth.clamp_plane_m, atol=1e-4)
        assert m.beam_width_m == pytest.approx(vt.W_M, rel=0.02)
    e = np.abs(np.array(errs))
    # Per-frame bounds loose enough for 3 frames; the benchmark measures the RMS.
    assert e[:, 0].max() < 0.012, e
    assert e[:, 1].max() < 0.2, e
    assert e[:, 2].max() < 0.2, e


def test_centreline_overlay_lies_on_the_beam(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.08)])
    cal = vt.truth_calibration(frame.truth)
    m = Measurer(cal).measure(frame.image)
    assert m.ok, m.reason
    px = m.centreline_px[5:-5]
    v = frame.image[np.round(px[:, 1]).astype(int), np.round(px[:, 0]).astype(int)]
    assert np.median(v) > 180
    # The calibration's mapping agrees with the renderer's exact projection.
    np.testing.assert_allclose(
        cal.to_px(m.centreline_plane_m),
        nominal_spec.to_px(m.centreline_plane_m),
        atol=1e-6,
    )


def test_bad_frames_give_ok_false_with_a_reason(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(280), 0.0)])
    m = Measurer(vt.truth_calibration(frame.truth))
    black = m.measure(np.zeros_like(frame.image))
    assert not black.ok and "blank" in black.reason and math.isnan(black.tip_lateral_m)
    empty = np.clip(static_layers(nominal_spec)["lit"], 0, 255).astype(np.uint8)
    no_beam = m.measure(empty)
    assert not no_beam.ok and "no beam" in no_beam.reason
    assert np.all(np.isnan(no_beam.lateral_at_stations_m))
    small = m.measure(np.full((10, 10), 100, np.uint8))
    assert not small.ok
    with pytest.raises(TypeError):
        m.measure([[0]])  # type: ignore[arg-type]


def test_a_foreign_bright_bar_is_not_taken_for_the_beam(vt) -> None:
    spec = vt.make_spec(noise_dn=2.0, seed=5, clutter=(Clutter((0.3, -0.6), (0.3, 0.019), 1.0),))
    frame = render_frame(spec, [vt.bent(math.radians(250), 0.04)])
    m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
    assert m.ok, m.reason
    assert abs(_errors(m, frame.truth)[1]) < 0.3


@pytest.mark.parametrize(
    ("hub_deg", "side", "from_m", "seed"),
    [(250.0, -1, -0.10, 103), (310.0, 1, -0.19, 114)],
)
def test_a_bar_along_half_a_hub_edge_leaves_the_beams_root_alone(
    vt, caplog, hub_deg: float, side: int, from_m: float, seed: int
) -> None:
    """A bar as bright as the hub, 8 mm wide, lying against one long edge of the hub
    over half its length: that edge's points step 8 mm out halfway along. In the joint
    fit the straight edge sets the hub's scale and the stepped edge's points all fall
    beyond the cut; its offset then had no point and the frame was refused, "measurement
    failed (Singular matrix)" with a warning (12 of 20 such frames). The axis now comes
    from the beam's root alone, within 3 of its stated uncertainties."""
    th = math.radians(hub_deg)
    e, n = np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])
    centre = e * (from_m + 0.05) + n * side * (0.04 / 2 + 0.004)
    bar = Clutter((float(centre[0]), float(centre[1])), (0.10, 0.008), th, 190.0)
    spec = vt.make_spec(noise_dn=2.0, seed=seed, clutter=(bar,))
    frame = render_frame(spec, [vt.bent(th, 0.03 if side > 0 else -0.04)])
    with caplog.at_level("WARNING", logger="vision"):
        m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
    assert m.ok, m.reason
    assert not caplog.records
    e_hub, e_tip, _ = _errors(m, frame.truth)
    assert abs(e_hub) <= 3 * math.degrees(m.hub_angle_std_rad), (e_hub, m.hub_angle_std_rad)
    assert abs(e_tip) <= 3 * m.tip_lateral_std_m * 1e3, (e_tip, m.tip_lateral_std_m)


def test_measurer_pickles_and_the_paper_method_runs(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.05)])
    m = Measurer(vt.truth_calibration(frame.truth))
    again = pickle.loads(pickle.dumps(m))
    a, b = m.measure(frame.image), again.measure(frame.image)
    assert a.tip_lateral_m == b.tip_lateral_m
    paper = Measurer(vt.truth_calibration(frame.truth), method="paper").measure(frame.image)
    assert paper.ok, paper.reason
    e = _errors(paper, frame.truth)
    assert abs(e[0]) < 0.5 and abs(e[1]) < 8.0  # the baseline is far coarser
    with pytest.raises(ValueError, match="method"):
        Measurer(m.calibration, method="magic")
    with pytest.raises(ValueError, match="stations_m"):
        Measurer(m.calibration, stations_m=(2.0,))


def test_registration_is_detected_to_a_tenth_of_a_pixel(nominal_spec, vt) -> None:
    frame = render_frame(nominal_spec, [vt.bent(math.radians(300), 0.0)])
    corners = detect_registration_corners(frame.image, RegistrationConfig())
    np.testing.assert_allclose(corners, frame.truth.corners_px, atol=0.05)
    cal = calibration_from_registration(frame.image, RegistrationConfig())
    assert len(cal.image_points_px) == 16  # every quadrant corner of the plate
    # All 16 map onto their plane points as the renderer's exact projection says.
    np.testing.assert_allclose(
        cal.image_points_px, nominal_spec.to_px(cal.plane_points_m), atol=0.08
    )
    assert cal.fit.rms_residual < 2e-5  # m
    m = Measurer(cal).measure(frame.image)
    assert m.ok and abs(math.degrees(m.hub_angle_rad - frame.truth.hub_angle_rad)) < 0.03
    occluded = frame.image.copy()
    c = frame.truth.corners_px.mean(axis=0).astype(int)
    occluded[c[1] - 120 : c[1] + 120, c[0] - 120 : c[0] + 120] = 40
    with pytest.raises(ValueError, match="registration object not found"):
        calibration_from_registration(occluded, RegistrationConfig())


@pytest.mark.slow
def test_hard_view_with_distortion_jpeg_and_noise(vt) -> None:
    spec = vt.make_spec(
        camera=CameraConfig(distortion=(-0.1, 0.0, 0.0, 0.0, 0.0)),
        pose=CameraPoseConfig(distance_m=1.75, tilt_rad=math.radians(40), tilt_azimuth_rad=0.2),
        noise_dn=10.0,
        seed=7,
        lighting_gradient=0.4,
        vignetting=0.3,
    )
    from vision.codec import decode

    frame = render_frame(spec, [vt.bent(math.radians(330), 0.14)])
    assert frame.truth.tip_lateral_m > 0.075  # an 80 mm class deflection
    image = decode(encode(frame.image, "jpeg", 60))
    m = Measurer(vt.truth_calibration(frame.truth)).measure(image)
    assert m.ok, m.reason
    e = _errors(m, frame.truth)
    assert abs(e[0]) < 0.05 and abs(e[1]) < 0.8 and abs(e[2]) < 0.6, e
    # The errors agree with the uncertainty the measurement reports for itself.
    assert abs(e[0]) < 4 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
    assert abs(e[1]) < 4 * m.tip_lateral_std_m * 1e3 + 0.05, (e, m.tip_lateral_std_m)


def test_motion_blur_is_measured_or_flagged(nominal_spec, vt) -> None:
    base = vt.bent(math.radians(290), 0.04)
    poses = [
        BeamPose(base.hub_angle_rad + d, base.stations_m, base.lateral_m, base.longitudinal_m)
        for d in np.linspace(-0.004, 0.004, 7)
    ]
    frame = render_frame(nominal_spec, poses)
    m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
    if m.ok:
        assert abs(_errors(m, frame.truth)[1]) < 1.0
    else:
        assert "blur" in m.reason


def test_reported_uncertainty_follows_the_noise(nominal_spec, vt) -> None:
    pose = vt.bent(math.radians(300), 0.05)
    quiet = render_frame(nominal_spec, [pose])  # 2 DN
    noisy_spec = vt.make_spec(noise_dn=8.0, seed=9)
    noisy = render_frame(noisy_spec, [pose])
    mq = Measurer(vt.truth_calibration(quiet.truth)).measure(quiet.image)
    mn = Measurer(vt.truth_calibration(noisy.truth)).measure(noisy.image)
    assert mq.ok and mn.ok, (mq.reason, mn.reason)
    assert 2.0 < mn.tip_lateral_std_m / mq.tip_lateral_std_m < 8.0  # ~4x the noise
    assert abs(_errors(mn, noisy.truth)[1]) < 4 * mn.tip_lateral_std_m * 1e3 + 0.02
    strict = Measurer(vt.truth_calibration(noisy.truth), max_tip_std_m=0.5 * mn.tip_lateral_std_m)
    flagged = strict.measure(noisy.image)
    assert not flagged.ok and "too noisy" in flagged.reason


def test_a_short_clamp_block_is_measured_from_the_beams_root(vt) -> None:
    """The paper's hub: a 68 x 51 mm block with the clamp 8 mm past the pivot (the
    measurement used to refuse any hub shorter than twice its width). The axis comes from
    the beam's root and the block's short edges together; every frame is measured with
    its errors inside 3 stated standard uncertainties."""
    spec = vt.make_spec(
        noise_dn=2.0,
        seed=21,
        hub_length_m=0.068,
        hub_width_m=0.051,
        pose=CameraPoseConfig(tilt_rad=math.radians(10.0)),
    )
    for hub_deg, tip_slope in ((250.0, 0.03), (290.0, -0.05), (325.0, 0.02)):
        frame = render_frame(spec, [vt.bent(math.radians(hub_deg), tip_slope)])
        m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
        assert m.ok, m.reason
        e = _errors(m, frame.truth)
        assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
        assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3, (e, m.tip_lateral_std_m)
        # The axis to ~0.01 deg from 2 DN edges: the tip within a few tenths of a mm.
        assert m.tip_lateral_std_m < 0.3e-3 and abs(e[2]) < 0.2, (e, m.tip_lateral_std_m)
        assert m.hub_width_m == pytest.approx(0.051, abs=0.5e-3)


def test_low_contrast_is_measured_with_an_honest_uncertainty(vt) -> None:
    """The beam 30 DN above the background at 5 DN of noise (SNR 6): measured, not
    refused as "too noisy", each error within 3 stated standard uncertainties and the
    stated tip uncertainty under the 0.5 mm limit."""
    spec = vt.make_spec(noise_dn=5.0, seed=31, background_dn=40.0, beam_dn=70.0, hub_dn=65.5)
    measured = 0
    for hub_deg, tip_slope in ((255.0, 0.04), (280.0, -0.03), (300.0, 0.05), (320.0, -0.02)):
        frame = render_frame(spec, [vt.bent(math.radians(hub_deg), tip_slope)])
        m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
        if not m.ok:
            assert "too noisy" not in m.reason, m.reason
            continue
        measured += 1
        e = _errors(m, frame.truth)
        assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
        assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3, (e, m.tip_lateral_std_m)
        assert m.tip_lateral_std_m <= 0.5e-3
    assert measured >= 3


def test_a_smear_beyond_what_is_measured_is_refused_with_its_size(vt) -> None:
    """A tip moving 20 mm across the beam during the exposure: the edges' fits are
    biased (errors of 1-2.5 mm once came out 'ok' with a stated 0.1-0.25 mm), so the
    frame is refused, and the reason gives the smear."""
    from vision.synthetic.scene import BeamMotion

    spec = vt.make_spec(noise_dn=2.0, seed=32)
    pose = vt.bent(math.radians(285), 0.04)
    poses = BeamMotion(pose, 40.0).exposure_poses(0.0006, 0.008, max_step_m=5e-4)
    frame = render_frame(spec, poses)
    m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
    if m.ok:
        assert abs(_errors(m, frame.truth)[1]) <= 3 * m.tip_lateral_std_m * 1e3
    else:
        assert "motion blur" in m.reason and "mm of smear" in m.reason, m.reason


def test_a_cantilevers_shape_on_a_short_hub_is_measured_through_its_modes(vt) -> None:
    """The short clamp block again, the beam now bent as a cantilever is (the response to
    its inertial load: zero moment and shear at the free end). The modes hold the shape,
    so the axis comes from the root with about a third of the generic polynomial's
    noise: the hub angle within 0.01 deg (3 sigma of the ~0.003 deg the bench sets
    show) and inside 3 stated standard uncertainties, every frame."""
    spec = vt.make_spec(
        noise_dn=2.0,
        seed=23,
        hub_length_m=0.068,
        hub_width_m=0.051,
        pose=CameraPoseConfig(tilt_rad=math.radians(11.0)),
    )
    for hub_deg, amp, accel, peak in (
        (252.0, (1.0, 0.1, -0.03), 0.5, 0.03),
        (288.0, (-0.6, 0.15, 0.02), -1.0, -0.025),
        (322.0, (0.3, -0.12, 0.04), 0.8, 0.02),
    ):
        frame = render_frame(spec, [_swinging_cantilever(vt, hub_deg, amp, accel, peak)])
        m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
        assert m.ok, m.reason
        e = _errors(m, frame.truth)
        assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
        assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3, (e, m.tip_lateral_std_m)
        assert abs(e[0]) < 0.01 and abs(e[1]) < 0.15, e


def test_the_modes_state_their_own_error_not_the_polynomials_noise(vt) -> None:
    """On the short clamp block the generic polynomial's axis is three times noisier
    than the modes' (its shapes bend freely at the root). Widened by their whole
    difference from it, the modes stated about the polynomial's uncertainty, and refused
    frames whose modal fit was within 0.2 mm ("too noisy", 0.53-0.57 mm). Widened by
    what two more modes change (their truncation) and by the polynomial's extra shapes
    only as far as they rise above their noise, they state less than the polynomial
    alone, and every error stays inside 3 stated standard uncertainties."""
    spec = vt.make_spec(
        noise_dn=2.5,
        seed=29,
        hub_length_m=0.068,
        hub_width_m=0.051,
        pose=CameraPoseConfig(tilt_rad=math.radians(9.0)),
    )
    modal_sd, poly_sd = [], []
    for hub_deg, amp, accel, peak in (
        (246.0, (0.8, -0.1, 0.02), 0.7, 0.033),
        (268.0, (-1.0, 0.12, 0.03), -0.4, -0.028),
        (297.0, (0.5, 0.1, -0.04), 1.0, 0.035),
        (316.0, (-0.7, -0.08, 0.02), -0.9, -0.022),
    ):
        frame = render_frame(spec, [_swinging_cantilever(vt, hub_deg, amp, accel, peak)])
        cal = vt.truth_calibration(frame.truth)
        m = Measurer(cal).measure(frame.image)
        poly = Measurer(cal, shape_modes=0).measure(frame.image)
        assert m.ok and poly.ok, (m.reason, poly.reason)
        e = _errors(m, frame.truth)
        assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
        assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3, (e, m.tip_lateral_std_m)
        modal_sd.append(m.tip_lateral_std_m)
        poly_sd.append(poly.tip_lateral_std_m)
    assert np.sqrt(np.mean(np.square(modal_sd))) < 0.8 * np.sqrt(np.mean(np.square(poly_sd)))


@pytest.mark.slow
def test_a_20_mm_smear_is_measured_at_mid_exposure_and_a_wider_one_refused(vt) -> None:
    """The tip crossing 20 mm during the exposure (hub turning, beam vibrating): the beam's
    light, not its edges, gives the centre line, whose time-average is the mid-exposure
    one; measured within 3 stated standard uncertainties and 0.15 mm (the issue's
    target). With the measurable smear set below what the frame shows, it is refused and
    the reason gives the smear."""
    from vision.synthetic.scene import BeamMotion

    spec = vt.make_spec(noise_dn=2.0, seed=33, pose=CameraPoseConfig(tilt_rad=math.radians(14)))
    pose = BeamPose.from_load(math.radians(283), vt.L_M, lambda s: 1.0 + 0.3 * s / vt.L_M, 0.025)
    x = pose.stations_m / vt.L_M
    rate = 1.0 * x**2 * (6 - 4 * x + x**2) / 3  # the beam's own vibration, m/s
    motion = BeamMotion(pose, 1.8, rate)
    exposure = 0.020 / motion.tip_speed_m_s(0.008)
    frame = render_frame(spec, motion.exposure_poses(exposure, 0.008))
    m = Measurer(vt.truth_calibration(frame.truth)).measure(frame.image)
    assert m.ok, m.reason
    e = _errors(m, frame.truth)
    assert m.blur_px > 6.0  # measured from the light, not the edges
    assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3 and abs(e[1]) < 0.15, (e, m.tip_lateral_std_m)
    assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
    strict = Measurer(vt.truth_calibration(frame.truth), max_smear_px=8.0).measure(frame.image)
    assert not strict.ok and "motion blur" in strict.reason and "mm of smear" in strict.reason


def test_a_beam_swung_far_aside_is_measured_not_refused_as_damaged(vt) -> None:
    """Tips 150 mm aside (the synthetic bench at 2.35 Hz: slope 0.27 at the tip), a
    cantilever's shape, JPEG 85 on a camera tilted 16 deg: the edges lie half the
    width from the centre line along its normal, 1 / cos(theta) across the axis, 0.4 mm
    wider apart at the tip than at the root. Fitted with a constant width they left
    runs in the residuals (correlated 0.85-0.96) and the frame was refused as
    "damaged or occluded"; now measured within 3 stated standard uncertainties."""
    spec = vt.make_spec(noise_dn=3.0, seed=71, pose=CameraPoseConfig(tilt_rad=math.radians(16.0)))
    for hub_deg, amp, accel, peak in (
        (262.0, (1.0, 0.08, -0.02), 0.6, 0.150),
        (306.0, (-1.0, 0.1, 0.03), -0.8, -0.152),
    ):
        frame = render_frame(spec, [_swinging_cantilever(vt, hub_deg, amp, accel, peak)])
        image = decode(encode(frame.image, "jpeg", 85))
        m = Measurer(vt.truth_calibration(frame.truth)).measure(image)
        assert m.ok, m.reason
        e = _errors(m, frame.truth)
        assert abs(e[0]) <= 3 * math.degrees(m.hub_angle_std_rad), (e, m.hub_angle_std_rad)
        assert abs(e[1]) <= 3 * m.tip_lateral_std_m * 1e3, (e, m.tip_lateral_std_m)
        assert abs(e[1]) < 0.15, e
