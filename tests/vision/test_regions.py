"""Measuring from the decoded parts of a frame: the same result as from the whole frame;
a lost track (no beam, a jump) found again; frames that cannot be split decoded whole."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from daq.drivers.opencv_camera import JPEG_RST_INTERVAL_MCU as RST_CAMERA
from vision.codec import decode, encode
from vision.config import CameraConfig, CameraPoseConfig
from vision.frame_measurement import FrameMeasurement
from vision.jpeg_regions import jpeg_layout
from vision.measure import Measurer
from vision.regions import RegionReader
from vision.synthetic.render import render_frame

# Not beambench's defaults: a smaller camera, rolled and tilted the other way, a longer
# and wider hub (its back end 0.59 m behind the pivot, past the band first decoded
# without a track), a darker background.
CAMERA = CameraConfig(width_px=1280, height_px=1024, focal_length_px=900.0)
POSE = CameraPoseConfig(
    tilt_rad=math.radians(14.0), tilt_azimuth_rad=math.radians(200.0), roll_rad=math.radians(-4.0)
)


def _scene_spec(vt):
    """The scenes' renderer setting: the test camera, a 0.6 m hub, 3 DN of noise."""
    return vt.make_spec(
        camera=CAMERA,
        pose=POSE,
        noise_dn=3.0,
        seed=9,
        hub_length_m=0.6,
        hub_width_m=0.05,
        background_dn=30.0,
    )


@pytest.fixture(scope="module")
def scene(vt):
    spec = _scene_spec(vt)
    rng = np.random.default_rng(4)
    frames = []
    for hub_deg, slope in ((250.0, 0.03), (262.0, -0.05), (318.0, 0.06), (300.0, 0.0)):
        fr = render_frame(spec, [vt.bent(math.radians(hub_deg), slope)], rng=rng)
        frames.append(fr.image)
    cal = vt.truth_calibration(fr.truth)
    return frames, cal


def _same(a: FrameMeasurement, b: FrameMeasurement) -> None:
    """Every field equal (arrays exactly)."""
    assert a.ok == b.ok and a.reason == b.reason
    for f in dataclasses.fields(FrameMeasurement):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        elif isinstance(x, float) and math.isnan(x):
            assert math.isnan(y), f.name
        else:
            assert x == y, f.name


def test_parts_measure_as_the_whole_frame(scene) -> None:
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    for image in frames:
        data = encode(image, "jpeg", 88)
        got = reader.measure(data)
        assert got.ok, got.reason
        _same(got, measurer.measure(decode(data)))
    assert reader.stats.parts == len(frames) and reader.stats.whole == 0
    assert reader.hub_back_m == pytest.approx(0.6 - 0.008, abs=0.02)  # the track
    assert max(reader.stats.decoded_fraction) < 0.6


def test_a_canvas_used_again_measures_as_the_whole_frame(scene) -> None:
    """The reader blanks the last frame's canvas where it was decoded (the same
    background level) or all of it (another level): every frame as from the whole one,
    nothing of the frame before left in what this one did not decode."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    brighter = np.clip(frames[1].astype(np.int16) + 40, 0, 255).astype(np.uint8)
    levels = []
    for image in (frames[0], frames[3], brighter, frames[2], frames[2]):
        data = encode(image, "jpeg", 90)
        got = reader.measure(data)
        assert got.ok, got.reason
        _same(got, measurer.measure(decode(data)))
        levels.append(reader._canvas_level)
        canvas = reader._canvas
        assert canvas is not None
        left = canvas[~np.repeat(np.repeat(_done_blocks(reader), 8, 0), 8, 1)]
        assert np.all(left == reader._canvas_level)  # only this frame's decode
    assert reader.stats.parts == 5
    assert levels[2] != levels[1] and levels[3] != levels[2]  # both ways blanked


def test_damaged_frames_between_good_ones_leave_nothing_in_the_canvas(scene) -> None:
    """A frame given up half way (a segment that does not decode, a file cut short) leaves
    the canvas partly written: the next good frame still measures as its whole frame."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    rng = np.random.default_rng(11)
    goods = [encode(frames[k], "jpeg", 90) for k in (0, 3)]
    wants = [measurer.measure(decode(g)) for g in goods]
    for i in range(12):
        bad = bytearray(goods[i % 2])
        if i % 3 == 0:
            bad = bad[: int(len(bad) * rng.uniform(0.3, 0.9))]  # cut short
        else:  # bytes of the scan overwritten: markers, 0xFF, flipped bits
            at = rng.integers(len(bad) // 10, len(bad), size=8)
            bad_bytes = rng.integers(0, 256, size=8).astype(np.uint8)
            bad_bytes[: i % 4] = 0xFF
            for a, b in zip(at.tolist(), bad_bytes.tolist(), strict=True):
                bad[a] = b
        reader.measure(bytes(bad))  # ok or not: never an exception
        got = reader.measure(goods[(i + 1) % 2])
        assert got.ok, got.reason
        _same(got, wants[(i + 1) % 2])


@pytest.mark.parametrize("failing_call", [1, 2])
def test_a_band_that_fails_half_decoded_leaves_nothing_in_the_canvas(
    scene, monkeypatch, failing_call
) -> None:
    """libjpeg reads most damage as some pixels; a splice it refuses after writing part of
    the canvas (here: the circles' segments, or the band, written, then the error) must not
    leave that frame's pixels for the next one to read as decoded."""
    import vision.regions as regions

    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    goods = [encode(frames[k], "jpeg", 90) for k in (0, 3)]
    wants = [measurer.measure(decode(g)) for g in goods]
    real = regions.decode_into
    failing = {"on": False, "calls": 0, "raised": 0}

    def decode_into(layout, canvas, segments):  # type: ignore[no-untyped-def]
        real(layout, canvas, segments)
        if failing["on"]:
            failing["calls"] += 1
            if failing["calls"] == failing_call:  # 1: the circles', 2: the band's
                failing["raised"] += 1
                raise ValueError("a segment that does not decode")

    monkeypatch.setattr(regions, "decode_into", decode_into)
    for i in range(4):
        failing["on"], failing["calls"] = True, 0
        reader.measure(goods[i % 2])  # given up half way: decoded whole instead
        failing["on"] = False
        got = reader.measure(goods[(i + 1) % 2])
        assert got.ok, got.reason
        _same(got, wants[(i + 1) % 2])
        # and nothing of the frame given up where this one did not decode
        canvas = reader._canvas
        assert canvas is not None
        left = canvas[~np.repeat(np.repeat(_done_blocks(reader), 8, 0), 8, 1)]
        assert np.all(left == reader._canvas_level)
    assert failing["raised"] == 4 and reader.stats.whole == 4 and reader.stats.parts == 4


def _done_blocks(reader: RegionReader) -> np.ndarray:
    """The reader's decoded segments as a [block row, block col] mask."""
    canvas = reader._canvas
    assert canvas is not None
    rows = canvas.shape[0] // 8
    per_row = reader._canvas_done.size // rows
    return np.repeat(reader._canvas_done.reshape(rows, per_row), canvas.shape[1] // 8 // per_row, 1)


@pytest.mark.parametrize("interval", [4, 5, 8, 40])
def test_other_restart_intervals_measure_as_the_whole_frame(scene, interval: int) -> None:
    """A camera writing another restart interval (segments of 4, 5, 8 or 40 MCUs of the
    160 in a row): measured from its parts, as from the whole frame."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    data = encode(frames[3], "jpeg", 85, restart_interval_mcu=interval)
    got = reader.measure(data)
    assert got.ok, got.reason
    _same(got, measurer.measure(decode(data)))
    assert reader.stats.parts == 1


def test_a_region_read_beyond_what_was_decoded_is_decoded_and_measured_again(scene) -> None:
    """A track that says the hub ends at the pivot (it reaches 0.59 m behind it): the
    first decode cuts the hub short, the check finds the measurement read past it, the
    rest is decoded and the frame measured again, as from the whole frame."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    data = encode(frames[2], "jpeg", 90)
    reader.hub_back_m, reader.hub_w_m = 0.0, 0.02
    _same(reader.measure(data), measurer.measure(decode(data)))
    assert (reader.stats.parts, reader.stats.regrown) == (1, 1)


def test_a_lost_track_is_found_again(scene) -> None:
    """A frame without a beam (refused as the whole frame refuses it) loses the track;
    the next frames, the beam far from where it was, are measured from their parts."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    rng = np.random.default_rng(1)
    empty = np.clip(30 + rng.normal(0, 3, frames[0].shape), 0, 255).astype(np.uint8)
    sequence = [frames[0], empty, frames[2], frames[1]]  # 250 deg, nothing, 318, 262
    kinds = []
    for image in sequence:
        data = encode(image, "jpeg", 90)
        before = reader.stats.parts
        got = reader.measure(data)
        _same(got, measurer.measure(decode(data)))
        kinds.append(("parts" if reader.stats.parts > before else "whole", got.ok))
        if not got.ok:
            assert reader.hub_back_m is None  # lost
    assert kinds == [("parts", True), ("whole", False), ("parts", True), ("parts", True)]


@pytest.mark.slow
def test_a_smeared_frame_tracked_is_decoded_wide_enough_at_once(vt) -> None:
    """A smeared frame (the tip crossing 20 mm in the exposure: the beam's light read up
    to 1.5 smears either side of its centre line) without a track: the first decode
    misses that reach, the rest is decoded and the frame measured again. Next, the
    track saying the last frame was smeared, it is measured at once; a frame without a
    beam loses that track, and the smeared frame regrows again. Every result as from
    the whole frame."""
    from vision.synthetic.scene import BeamMotion, BeamPose

    pose = CameraPoseConfig(tilt_rad=math.radians(14.0), tilt_azimuth_rad=math.radians(160.0))
    spec = vt.make_spec(pose=pose, noise_dn=2.0, seed=33, background_dn=35.0)
    beam = BeamPose.from_load(math.radians(283), vt.L_M, lambda s: 1.0 + 0.3 * s / vt.L_M, 0.025)
    x = beam.stations_m / vt.L_M
    motion = BeamMotion(beam, 1.8, x**2 * (6 - 4 * x + x**2) / 3)
    exposure = 0.020 / motion.tip_speed_m_s(0.008)
    frame = render_frame(spec, motion.exposure_poses(exposure, 0.008))
    measurer = Measurer(vt.truth_calibration(frame.truth))
    reader = RegionReader(measurer)
    smeared = encode(frame.image, "jpeg", 90)
    rng = np.random.default_rng(3)
    empty = np.clip(35 + rng.normal(0, 2, frame.image.shape), 0, 255).astype(np.uint8)
    regrown, tracked = [], []
    for data in (smeared, smeared, encode(empty, "jpeg", 90), smeared):
        got = reader.measure(data)
        _same(got, measurer.measure(decode(data)))
        assert got.ok == (data is smeared), got.reason
        assert not got.ok or got.blur_px > measurer.max_blur_px  # smeared
        regrown.append(reader.stats.regrown)
        tracked.append(reader.smear_m > 0)
    assert regrown == [1, 1, 1, 2]
    assert tracked == [True, True, False, True]
    assert (reader.stats.parts, reader.stats.whole) == (3, 1)
    # told the next frame is not the next of the view (bench vision's independent poses),
    # the reader forgets the track: the smeared frame regrows as a run's first does
    reader.lose_track()
    assert reader.smear_m == 0 and reader.hub_back_m is None
    _same(reader.measure(smeared), measurer.measure(decode(smeared)))
    assert reader.stats.regrown == 3


def test_frames_that_cannot_be_split_are_decoded_whole(scene) -> None:
    frames, cal = scene
    image = frames[1]
    for data in (
        encode(image, "jpeg", 90, restart_interval_mcu=0),  # a foreign camera's JPEG
        encode(image, "png"),
        encode(image, "jpeg", 90, restart_interval_mcu=7),  # segments wrap the rows
    ):
        measurer = Measurer(cal)
        reader = RegionReader(measurer)
        _same(reader.measure(data), measurer.measure(decode(data)))
        assert (reader.stats.parts, reader.stats.whole) == (0, 1)
    paper = Measurer(cal, method="paper")
    reader = RegionReader(paper)
    data = encode(image, "jpeg", 90)
    _same(reader.measure(data), paper.measure(decode(data)))
    assert reader.stats.whole == 1
    bad = RegionReader(Measurer(cal)).measure(b"\xff\xd8 not a jpeg")
    assert not bad.ok and bad.reason.startswith("cannot decode frame")
    with pytest.raises(TypeError, match="measurer"):
        RegionReader(cal)  # type: ignore[arg-type]


@pytest.mark.slow
def test_flipped_bits_in_parts_never_give_a_wrong_ok(scene) -> None:
    """Single-bit flips in a JPEG with restart markers: measured from its parts, a frame
    still ``ok`` is within 0.5 mm of the clean frame's tip (the fuzz suite's tolerance),
    and agrees with the damaged frame decoded whole when that is ok too."""
    frames, cal = scene
    assert _flipped_and_measured_close(encode(frames[0], "jpeg", 92), Measurer(cal), 7, 60) > 20


def _flipped_and_measured_close(data: bytes, measurer: Measurer, seed: int, n: int) -> int:
    """``n`` copies of ``data`` with one bit flipped past the headers, each measured from
    its parts by a fresh reader: those still ``ok`` within 0.5 mm of the clean frame's tip
    (the fuzz suite's tolerance); how many were."""
    clean = measurer.measure(decode(data))
    assert clean.ok
    r = np.random.default_rng(seed)
    measured = 0
    for _ in range(n):
        out = bytearray(data)
        i = int(r.integers(600, len(out) - 2))
        out[i] ^= 1 << int(r.integers(8))
        got = RegionReader(measurer).measure(bytes(out))
        if got.ok:
            measured += 1
            assert abs(got.tip_lateral_m - clean.tip_lateral_m) <= 0.5e-3
    return measured


# -- colour frames: what the camera driver writes for a colour camera ---------------------

_SAMPLING = {
    "4:2:0": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420,
    "4:2:2": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422,
    "4:4:0": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_440,
    "4:4:4": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444,
}


def _colour(image: np.ndarray) -> np.ndarray:
    """A BGR frame of a gray one with a colour cast that varies across the frame (blue
    lifted to the right, red with a ripple, green darkened downward), so that its Y is
    not the gray image (about 0.97 of it and 4 to 14 levels more)."""
    h, w = image.shape
    yy, xx = np.mgrid[0:h, 0:w]
    g = image.astype(np.float64)
    b = 0.5 * g + 60.0 + 60.0 * xx / w
    gr = 0.95 * g - 12.0 * yy / h
    r = 1.2 * g - 6.0 + 8.0 * np.sin(xx / 97.0)
    return np.clip(np.dstack([b, gr, r]).round(), 0, 255).astype(np.uint8)


def _driver_jpeg(bgr: np.ndarray, quality: int = 90, sampling: str | None = None) -> bytes:
    """As ``daq/drivers/opencv_camera.py`` encodes a colour frame (OpenCV's default
    4:2:0 unless ``sampling``, a restart marker every ``JPEG_RST_INTERVAL_MCU``)."""
    params = [cv2.IMWRITE_JPEG_QUALITY, quality, cv2.IMWRITE_JPEG_RST_INTERVAL, RST_CAMERA]
    if sampling is not None:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, _SAMPLING[sampling]]
    ok, buf = cv2.imencode(".jpg", bgr, params)
    assert ok
    return bytes(buf)


def _done_pixels(reader: RegionReader, layout) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The reader's decoded segments as a [row, col] mask of its canvas."""
    seg_w, seg_h = layout.segment_px
    done = reader._canvas_done.reshape(layout.mcu_rows, layout.per_row)
    return np.repeat(np.repeat(done, seg_h, 0), seg_w, 1)


@pytest.mark.parametrize(
    ("sampling", "segment_px"),
    [(None, (64, 16)), ("4:2:2", (64, 8)), ("4:4:0", (32, 16)), ("4:4:4", (32, 8))],
)
def test_colour_frames_measure_from_their_parts_as_the_whole_frame(
    scene, sampling: str | None, segment_px: tuple[int, int]
) -> None:
    """Colour frames of a beam, a run in order (the track kept), as the camera driver
    writes them: each measured from its parts, field for field as the whole gray decode
    measures it; what was not decoded is the background level alone."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    for image in frames:
        data = _driver_jpeg(_colour(image), sampling=sampling)
        layout = jpeg_layout(data)
        assert layout is not None and layout.segment_px == segment_px
        whole = decode(data)
        assert (whole.astype(np.int16) - image).mean() > 4  # Y is not the gray image
        before = reader.stats.parts
        got = reader.measure(data)
        assert got.ok, got.reason
        _same(got, measurer.measure(whole))
        assert reader.stats.parts == before + 1  # in parts
        canvas = reader._canvas
        assert canvas is not None and canvas.shape == (
            layout.mcu_rows * segment_px[1],
            layout.per_row * segment_px[0],
        )
        assert np.all(canvas[~_done_pixels(reader, layout)] == reader._canvas_level)
        shown = canvas[: whole.shape[0], : whole.shape[1]]
        done = _done_pixels(reader, layout)[: whole.shape[0], : whole.shape[1]]
        np.testing.assert_array_equal(shown[done], whole[done])
    assert reader.stats.whole == 0
    assert max(reader.stats.decoded_fraction) < 0.6
    assert reader.hub_back_m == pytest.approx(0.6 - 0.008, abs=0.02)  # the track


def test_colour_and_gray_frames_in_one_run(scene) -> None:
    """A run switching between a gray frame and colour ones of two samplings (another
    segment size, the same image size): the canvas is made anew for each, every frame
    measured from its parts as from the whole frame."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    for k, make in enumerate(
        (
            lambda im: encode(im, "jpeg", 90),
            lambda im: _driver_jpeg(_colour(im)),
            lambda im: _driver_jpeg(_colour(im), sampling="4:2:2"),
            lambda im: encode(im, "jpeg", 90),
        )
    ):
        data = make(frames[k])
        got = reader.measure(data)
        assert got.ok, got.reason
        _same(got, measurer.measure(decode(data)))
    assert reader.stats.parts == 4


def test_damaged_colour_frames_never_show_another_frames_pixels(scene) -> None:
    """Damaged colour frames (cut short, scan bytes overwritten, restart markers among
    them) between good ones: each measured without an exception, the damaged one either
    refused with one reason or measured; the next good frame as its whole frame, nothing
    of the damaged one left in what it did not decode."""
    frames, cal = scene
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    rng = np.random.default_rng(21)
    goods = [_driver_jpeg(_colour(frames[k]), quality=85) for k in (1, 2)]
    wants = [measurer.measure(decode(g)) for g in goods]
    layout = jpeg_layout(goods[0])
    assert layout is not None
    refused = 0
    for i in range(10):
        bad = bytearray(goods[i % 2])
        if i % 3 == 0:
            bad = bad[: int(len(bad) * rng.uniform(0.3, 0.9))]  # cut short
        else:
            at = rng.integers(len(bad) // 10, len(bad), size=8)
            bad_bytes = rng.integers(0, 256, size=8).astype(np.uint8)
            bad_bytes[: i % 4] = 0xFF
            for a, b in zip(at.tolist(), bad_bytes.tolist(), strict=True):
                bad[a] = b
        m = reader.measure(bytes(bad))
        if not m.ok:
            refused += 1
            assert m.reason and "\n" not in m.reason
        got = reader.measure(goods[(i + 1) % 2])
        assert got.ok, got.reason
        _same(got, wants[(i + 1) % 2])
        canvas = reader._canvas
        assert canvas is not None
        assert np.all(canvas[~_done_pixels(reader, layout)] == reader._canvas_level)
    assert refused > 0


def test_a_colour_frame_damaged_in_a_segment_is_refused_or_measured_close(scene) -> None:
    """Single-bit flips in a colour frame's scan: measured from its parts, a frame still
    ``ok`` is within 0.5 mm of the clean frame's tip (the fuzz suite's tolerance)."""
    frames, cal = scene
    data = _driver_jpeg(_colour(frames[0]), quality=92)
    assert _flipped_and_measured_close(data, Measurer(cal), 8, 25) > 5


@pytest.fixture(scope="module")
def swing(vt):
    """A run's frames (the scene's camera): the beam straight at 300 deg, turned 2 deg
    on, then the same hub angle with the beam bent (its tip ~50 mm off the turned
    straight beam, its crossings of the search circles a few mm), and one bent hard."""
    spec = _scene_spec(vt)
    rng = np.random.default_rng(5)
    frames = []
    for hub_deg, slope in ((300.0, 0.0), (302.0, 0.0), (302.0, 0.09), (300.0, 0.2)):
        fr = render_frame(spec, [vt.bent(math.radians(hub_deg), slope)], rng=rng)
        frames.append(encode(fr.image, "jpeg", 90))
    return frames, vt.truth_calibration(fr.truth)


def test_the_track_turned_with_the_chord_decodes_less_and_measures_the_same(swing) -> None:
    """The next frame of a run, the beam turned: its band is the last frame's read region
    turned with the chord (the track), smaller than the band from the crossings alone;
    measured at once, as from the whole frame."""
    frames, cal = swing
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    alone = RegionReader(measurer)
    regrown = []
    for data in frames[:2]:
        _same(reader.measure(data), measurer.measure(decode(data)))
        regrown.append(reader.stats.regrown)
        alone.lose_track()
        alone.measure(data)
    # the first frame's hub reaches past the band decoded without a track: regrown
    assert regrown == [1, 1]
    assert (reader.stats.parts, reader.stats.tracked) == (2, 1)
    assert alone.stats.tracked == 0
    assert reader.stats.decoded_fraction[1] < 0.9 * alone.stats.decoded_fraction[1]


def test_a_beam_bent_beyond_the_tracks_margin_is_regrown(swing) -> None:
    """The beam bends between two frames more than the track's margin (its tip moves
    ~50 mm, its crossings little): the band turned from the last frame misses the tip,
    the check finds it, the rest is decoded and the frame measured again, as from the
    whole frame."""
    frames, cal = swing
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    regrown = []
    for data in (frames[1], frames[2]):
        _same(reader.measure(data), measurer.measure(decode(data)))
        regrown.append(reader.stats.regrown)
    assert regrown == [1, 2]  # the first: its long hub, untracked (as above)
    assert (reader.stats.parts, reader.stats.tracked) == (2, 1)


def test_a_beam_whose_shape_changed_is_not_tracked(swing) -> None:
    """A straight beam, then one bent hard (tip slope 0.2 rad): its crossings lie 12 mm
    off the last frame's centre line turned with the chord, so the band is predicted from
    the crossings alone (not the track), and measured as from the whole frame;
    lose_track forgets the shape."""
    frames, cal = swing
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    for data in (frames[0], frames[3]):
        got = reader.measure(data)
        assert got.ok, got.reason
        _same(got, measurer.measure(decode(data)))
    assert (reader.stats.parts, reader.stats.tracked) == (2, 0)
    assert reader._shape is not None
    reader.lose_track()
    assert reader._shape is None


def test_the_check_holds_every_outward_profile_searched(vt, nominal_spec, monkeypatch) -> None:
    """The check marks the outward follow's cross-profiles sample by sample: every pixel
    of every profile the follow searched (its batches' rows up to the one that lost the
    strip), read on the whole frame, lies in a block the check asks for (beambench's
    camera: the profiles reach past the tubes about the beam)."""
    import vision.locate as locate_mod
    from vision.locate import crossings, outward_width

    rng = np.random.default_rng(8)
    frames = []
    for hub_deg, slope in ((300.0, 0.05), (35.0, -0.08), (170.0, 0.0)):
        fr = render_frame(nominal_spec, [vt.bent(math.radians(hub_deg), slope)], rng=rng)
        frames.append(fr.image)
    cal = vt.truth_calibration(fr.truth)
    measurer = Measurer(cal)
    reader = RegionReader(measurer)
    real_points, real_batch = locate_mod.bilinear_points, locate_mod._follow_batch
    # each follow batch's sample points, and how many of its profiles were searched
    batches: list[tuple[np.ndarray, int]] = []
    grids: list[np.ndarray] = []

    def points(img, px):
        grids.append(np.array(px))
        return real_points(img, px)

    def batch(vals, *args):
        got = real_batch(vals, *args)
        batches.append((grids[-1].reshape(vals.shape[0], vals.shape[1], 2), got[0] + got[4]))
        return got

    for image in frames:
        batches.clear()
        grids.clear()
        monkeypatch.setattr(locate_mod, "bilinear_points", points)
        monkeypatch.setattr(locate_mod, "_follow_batch", batch)
        m = measurer.measure(image)
        monkeypatch.undo()
        assert m.ok, m.reason
        found = crossings(image, reader._circles)
        assert found is not None
        p1, p2, shown = found
        w0 = outward_width(shown, cal.beam_width_m)
        shape = ((image.shape[0] + 7) // 8, (image.shape[1] + 7) // 8)
        mask = reader._read(m, p1, p2, w0, shape, profiles=True)
        # the outward follow's batches: the first, until one that lost the strip
        searched = []
        for grid, rows in batches:
            searched.append(grid[:rows].reshape(-1, 2))
            if rows < len(grid):
                break
        px = np.concatenate(searched)
        h, w = image.shape  # samples off the image read nothing (NaN)
        px = px[(px[:, 0] >= 0) & (px[:, 1] >= 0) & (px[:, 0] <= w - 1) & (px[:, 1] <= h - 1)]
        assert len(px) > 1000
        x0 = np.minimum(np.floor(px[:, 0]).astype(int), image.shape[1] - 2)
        y0 = np.minimum(np.floor(px[:, 1]).astype(int), image.shape[0] - 2)
        for dx in (0, 1):
            for dy in (0, 1):
                assert np.all(mask[(y0 + dy) // 8, (x0 + dx) // 8])
        # and the band they lie in (the check without a track) holds all of that, and
        # more: what a tracked frame does not decode
        band = reader._read(m, p1, p2, w0, shape, profiles=False)
        assert np.all(band >= mask) and band.sum() > 1.05 * mask.sum()


def test_mark_points_marks_the_blocks_of_each_samples_pixels_and_one_more() -> None:
    """_mark_points against numpy: the blocks of columns floor(x) - 1 .. floor(x) + 2 and
    rows likewise, clipped to the mask; NaN and points off the image mark nothing."""
    from vision.regions import _mark_points

    rng = np.random.default_rng(2)
    rows, cols = 13, 21
    px = np.column_stack(
        [rng.uniform(-20, cols * 8 + 20, 400), rng.uniform(-20, rows * 8 + 20, 400)]
    )
    px[::37] = np.nan
    px[5] = (1e300, 3.0)
    px[6] = (-1.5, -1.99)  # reads nothing, marks the corner block (a pixel more)
    px[7:11] = [(0.0, 0.0), (cols * 8 - 1.0, rows * 8 - 1.0), (cols * 8 + 0.9, 4.0), (3.0, -2.0)]
    px[11:60] = px[11] + np.arange(49)[:, None] * 0.3  # close points, as a profile's
    got = np.zeros((rows, cols), np.uint8)
    _mark_points(got, px, 3)
    want = np.zeros((rows, cols), bool)
    for x, y in px:
        if not (np.isfinite(x) and np.isfinite(y) and x > -2 and y > -2):
            continue
        if not (x < cols * 8 + 1 and y < rows * 8 + 1):
            continue
        fx, fy = int(np.floor(x)), int(np.floor(y))
        c = np.clip(np.arange(fx - 1, fx + 3), 0, cols * 8 - 1) // 8
        r = np.clip(np.arange(fy - 1, fy + 3), 0, rows * 8 - 1) // 8
        want[np.ix_(r, c)] = True
    np.testing.assert_array_equal(got.view(bool), want)
    assert want[0, 0] and want.sum() > 100
