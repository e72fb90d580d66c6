from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vision import Calibration, load_calibration
from vision.camera import camera_matrix
from vision.homography import apply_homography

IMG = [[100.0, 120.0], [410.0, 90.0], [450.0, 400.0], [80.0, 380.0]]
# seen by a camera: image y grows downwards as the plane's Y falls (not a mirror image)
PLANE = [[0.0, 0.0], [0.1, 0.0], [0.1, -0.1], [0.0, -0.1]]


def _write(tmp_path: Path, data: object) -> Path:
    p = tmp_path / "cal.json"
    p.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return p


def test_round_trip_through_json(tmp_path: Path) -> None:
    cal = Calibration(
        np.array(IMG),
        np.array(PLANE),
        camera_matrix(2100, 2048, 1536),
        np.array([-0.1, 0, 0, 0, 0]),
    )
    again = load_calibration(_write(tmp_path, cal.to_json()))
    np.testing.assert_allclose(again.fit.matrix, cal.fit.matrix)
    np.testing.assert_allclose(again.to_plane(np.array(IMG)), PLANE, atol=1e-12)
    assert again.beam_length_m == 0.835


def test_four_points_give_the_exact_collineation() -> None:
    cal = Calibration(np.array(IMG), np.array(PLANE))
    np.testing.assert_allclose(apply_homography(cal.fit.matrix, np.array(IMG)), PLANE, atol=1e-14)


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ("{not json", "not valid JSON"),
        ([1, 2], "top level must be an object"),
        ({"camera": {}}, "'registration' object is missing"),
        ({"registration": {"image_points_px": IMG}}, "plane_points_m is missing"),
        ({"registration": {"image_points_px": IMG[:3], "plane_points_m": PLANE[:3]}}, "4 or more"),
        (
            {
                "registration": {
                    "image_points_px": [[0, 0], [1, 0], [2, 0], [0, 1]],
                    "plane_points_m": PLANE,
                }
            },
            "nearly collinear",
        ),
        (
            {
                "registration": {
                    "image_points_px": [IMG[0], IMG[2], IMG[1], IMG[3]],
                    "plane_points_m": PLANE,
                }
            },
            "consistent order",
        ),
        (
            {
                "registration": {"image_points_px": IMG, "plane_points_m": PLANE},
                "beam": {"length": 1},
            },
            "beam.length",
        ),
        (
            {
                "registration": {"image_points_px": IMG, "plane_points_m": PLANE},
                "camera": {"matrix": [[1]]},
            },
            "3x3",
        ),
        (
            {"registration": {"image_points_px": IMG, "plane_points_m": PLANE}, "extra": 1},
            "unknown key",
        ),
        ({"registration": {"image_points_px": "abc", "plane_points_m": PLANE}}, "numeric|shape"),
    ],
)
def test_bad_files_say_why(tmp_path: Path, data: object, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        load_calibration(_write(tmp_path, data))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no such file"):
        load_calibration(tmp_path / "nope.json")
