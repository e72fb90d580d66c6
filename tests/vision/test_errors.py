"""vision's exception tree: one root, messages built from the facts, and every error a
caller can trigger with bad input still a ValueError (the boundary's contract)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vision import load_calibration
from vision.codec import decode
from vision.config import CameraConfig, RegistrationConfig
from vision.errors import (
    CalibrationError,
    DecodeError,
    DegeneratePointsError,
    FrameFailure,
    ParameterError,
    RegistrationError,
    VisionError,
)
from vision.homography import collineation_4pt
from vision.registration import calibration_from_registration


def test_constructors_build_the_sentence_from_the_facts() -> None:
    assert str(ParameterError("jpeg_quality", "must be between 1 and 100, got 0")) == (
        "jpeg_quality must be between 1 and 100, got 0"
    )
    assert str(CalibrationError("no such file")) == "no such file"
    err = CalibrationError("the homography is badly conditioned", section="registration")
    assert str(err) == "registration: the homography is badly conditioned"
    assert str(DegeneratePointsError("src", "all points coincide")) == "src: all points coincide"
    assert str(RegistrationError("blank image", found=False)) == (
        "registration object not found: blank image"
    )
    assert str(RegistrationError("a corner lies off the image", found=True)) == (
        "registration object: a corner lies off the image"
    )
    assert str(DecodeError(0)) == "empty image data"
    assert DecodeError(12).n_bytes == 12
    assert FrameFailure("blank frame").reason == "blank frame"


def test_frame_failure_is_not_an_input_error() -> None:
    """Measurer.measure turns it into ok=False; it must not be caught as bad input."""
    assert issubclass(FrameFailure, VisionError)
    assert not issubclass(FrameFailure, ValueError)


def test_bad_input_at_the_boundary_is_a_vision_error_and_a_value_error(tmp_path: Path) -> None:
    path = tmp_path / "cal.json"
    path.write_text(json.dumps({"camera": {}}))
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    cases = [
        (lambda: CameraConfig(jpeg_quality=0), ParameterError),
        (lambda: RegistrationConfig(plate_side_m=0.1), ParameterError),
        (lambda: load_calibration(path), CalibrationError),
        (lambda: load_calibration(tmp_path / "missing.json"), CalibrationError),
        (lambda: decode(b""), DecodeError),
        (lambda: decode(b"not an image"), DecodeError),
        (lambda: collineation_4pt(square[[0, 1, 1, 3]], square), DegeneratePointsError),
        (
            lambda: calibration_from_registration(
                np.zeros((64, 64), np.uint8), RegistrationConfig()
            ),
            RegistrationError,
        ),
    ]
    for call, kind in cases:
        with pytest.raises(kind) as info:
            call()
        assert isinstance(info.value, VisionError) and isinstance(info.value, ValueError)
