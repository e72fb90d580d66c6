"""A JPEG with one bit flipped can decode into a plausible frame whose lower part is
shifted by a block (libjpeg resynchronises after the damage): such frames once measured
``ok`` with 11-14 mm of tip error. The beam is a smooth curve, so edges that leave any
smooth shape over many points, or whose residuals run together, flag the frame."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from vision import Calibration, Measurer
from vision.codec import decode, encode
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamPose, SceneSpec

L_M = 0.835
#: The fuzz suite's tolerance for a damaged frame that still measures ok (tests/fuzz).
TIP_TOLERANCE_M = 0.5e-3


@pytest.fixture(scope="module")
def jpeg_frame() -> tuple[bytes, Calibration, float]:
    """The fuzz suite's frame (a small camera, rolled and tilted, 3 DN), JPEG 92 without
    restart markers (a foreign camera's: a flipped bit shifts every block after it; with
    beambench's markers the damage ends at the next marker, tests/vision/test_regions.py)."""
    spec = SceneSpec.from_rig(
        CameraConfig(width_px=1280, height_px=960, focal_length_px=1300.0),
        CameraPoseConfig(tilt_rad=math.radians(20.0), roll_rad=math.radians(3.0)),
        RegistrationConfig(),
        beam_length_m=L_M,
        beam_width_m=0.01905,
        hub_offset_m=0.008,
        noise_dn=3.0,
    )
    pose = BeamPose.from_slope(math.radians(285), L_M, lambda s: 0.04 * (2 * s / L_M))
    frame = render_frame(spec, [pose])
    tr = frame.truth
    cal = Calibration(tr.corners_px, tr.plane_points_m, tr.camera_matrix, tr.distortion)
    return encode(frame.image, "jpeg", 92, restart_interval_mcu=0), cal, tr.tip_lateral_m


def _flipped(data: bytes, seed: int) -> bytes:
    """One bit flipped past the headers, where the seed says."""
    r = random.Random(seed)
    out = bytearray(data)
    i = r.randrange(600, len(out))
    out[i] ^= 1 << r.randrange(8)
    return bytes(out)


@pytest.mark.slow
def test_a_jpeg_shifted_by_a_flipped_bit_is_not_ok(jpeg_frame) -> None:
    """Seeds whose flipped bit (found by search) shifts the beam's image by a block: the
    image decodes, differs from the clean one over thousands of pixels, and is refused."""
    data, cal, truth = jpeg_frame
    clean = decode(data).astype(np.int16)
    m = Measurer(cal)
    assert m.measure(decode(data)).ok
    for seed in (359, 378, 387, 399):
        image = decode(_flipped(data, seed))
        assert image.shape == clean.shape
        assert int((np.abs(image - clean) > 30).sum()) > 1000, seed
        got = m.measure(image)
        assert not got.ok, (seed, got.tip_lateral_m - truth)
        assert "damaged" in got.reason, got.reason


@pytest.mark.slow
def test_flipped_bits_never_give_a_wrong_ok(jpeg_frame) -> None:
    """300 single-bit flips: a frame still measured ok has its tip within the fuzz
    suite's tolerance (a JPEG block's worth of damage the measurement must flag)."""
    data, cal, truth = jpeg_frame
    m = Measurer(cal)
    measured = 0
    for seed in range(300):
        try:
            image = decode(_flipped(data, seed))
        except ValueError:
            continue
        got = m.measure(image)
        if got.ok:
            measured += 1
            assert abs(got.tip_lateral_m - truth) <= TIP_TOLERANCE_M, (seed, got.tip_lateral_m)
    assert measured > 100
