from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipelines.cli import main
from vision import Calibration
from vision.codec import encode
from vision.config import CameraConfig, CameraPoseConfig, RegistrationConfig
from vision.synthetic.render import render_frame
from vision.synthetic.scene import BeamMotion, BeamPose, SceneSpec


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("measure")
    spec = SceneSpec.from_rig(
        CameraConfig(),
        CameraPoseConfig(),
        RegistrationConfig(),
        beam_length_m=0.835,
        beam_width_m=0.01905,
        hub_offset_m=0.008,
        noise_dn=2.0,
    )
    pose = BeamPose.from_slope(math.radians(290), 0.835, lambda s: 0.03 * (2 * s / 0.835))
    frame = render_frame(spec, [pose])
    tr = frame.truth
    cal = Calibration(tr.corners_px, tr.plane_points_m, tr.camera_matrix, tr.distortion)
    (d / "cal.json").write_text(cal.to_json())
    (d / "frame.jpg").write_bytes(encode(frame.image, "jpeg", 95))
    (d / "black.png").write_bytes(encode(frame.image * 0, "png"))
    (d / "junk.jpg").write_bytes(b"junk")
    (d / "truth.json").write_text(json.dumps({"tip_lateral_m": tr.tip_lateral_m}))
    # the same beam turning at 2.4 rad/s (2 m/s at the tip) over a 6 ms exposure: the tip
    # moves 12 mm across the beam, about 12 px (1.0 mm/px at the tip)
    smeared = render_frame(spec, BeamMotion(pose, 2.0 / 0.843).exposure_poses(0.006, 0.008))
    (d / "smeared.png").write_bytes(encode(smeared.image, "png"))
    return {p.name: p for p in d.iterdir()}


def test_json_lines_per_image(files, capsys) -> None:
    rc = main(
        [
            "measure",
            str(files["frame.jpg"]),
            str(files["black.png"]),
            "--calibration",
            str(files["cal.json"]),
            "--json",
        ]
    )
    assert rc == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert len(lines) == 2
    good, black = lines
    truth = json.loads(files["truth.json"].read_text())["tip_lateral_m"]
    assert good["ok"] and abs(good["tip_lateral_m"] - truth) < 3e-4
    assert set(good) >= {
        "ok",
        "reason",
        "hub_angle_rad",
        "tip_lateral_m",
        "tip_longitudinal_m",
        "stations_m",
        "lateral_at_stations_m",
    }
    assert math.degrees(good["hub_angle_rad"]) == pytest.approx(290, abs=0.02)
    assert not black["ok"] and black["reason"] and black["tip_lateral_m"] is None


def test_json_carries_each_standard_uncertainty_beside_its_value(files, capsys) -> None:
    argv = ["measure", str(files["frame.jpg"]), str(files["black.png"])]
    assert main([*argv, "--calibration", str(files["cal.json"]), "--json"]) == 0
    good, black = (json.loads(x) for x in capsys.readouterr().out.splitlines())
    keys = list(good)
    for value, sd in (
        ("hub_angle_rad", "hub_angle_sd_rad"),
        ("tip_lateral_m", "tip_lateral_sd_m"),
        ("tip_longitudinal_m", "tip_longitudinal_sd_m"),
    ):
        assert keys.index(sd) == keys.index(value) + 1
        assert good[sd] > 0.0 and black[sd] is None
    # plausible for a 2 DN frame: micro- to a tenth of a millimetre, not zero or metres
    assert 1e-6 < good["tip_longitudinal_sd_m"] < 1e-4
    # a calibration file that states no covariance adds nothing for the calibration
    for name in ("hub_angle_sd_rad", "tip_lateral_sd_m", "tip_longitudinal_sd_m"):
        assert good[f"calibration_{name}"] == 0.0 and f"calibration_{name}" not in black


def test_json_carries_the_beam_width_and_the_blur_it_saw(files, capsys) -> None:
    """Beside the measurement, what the frame showed: the beam's width from its edges
    (the calibration's 19.05 mm is a hint, not copied) and the edges' ramp width, which
    motion blur widens (a still frame's ~2 px of optics against a smeared one's)."""
    argv = ["measure", *(str(files[k]) for k in ("frame.jpg", "smeared.png", "black.png"))]
    assert main([*argv, "--calibration", str(files["cal.json"]), "--json"]) == 0
    still, smeared, black = (json.loads(x) for x in capsys.readouterr().out.splitlines())
    assert still["ok"] and smeared["ok"], (still["reason"], smeared["reason"])
    for m in (still, smeared):
        # within 0.2 mm (a fifth of a pixel) of the drawn width, and not the hint itself
        assert m["beam_width_m"] == pytest.approx(0.01905, abs=2e-4)
        assert m["beam_width_m"] != 0.01905
    assert 1.0 < still["blur_px"] < 3.0  # the optics' blur (sigma 0.6 px) and the pixels
    assert smeared["blur_px"] > 2 * still["blur_px"]
    assert smeared["blur_px"] < 14.0  # no wider than the tip's 12 mm (12 px) and its optics
    assert black["beam_width_m"] is None and black["blur_px"] is None


def test_json_carries_the_hub_width_with_its_uncertainty(files, capsys) -> None:
    """The hub's width from its two long edges, with its standard uncertainty: the drawn
    width within 3 sd (the sd a few micrometres to a tenth of a millimetre: a 2 DN frame's
    edges, not zero or the rough locator's millimetres); None on a frame with no beam."""
    from vision.synthetic.scene import SceneSpec

    drawn_m = SceneSpec.hub_width_m  # the renderer's default hub, 40 mm
    argv = ["measure", str(files["frame.jpg"]), str(files["black.png"])]
    assert main([*argv, "--calibration", str(files["cal.json"]), "--json"]) == 0
    good, black = (json.loads(x) for x in capsys.readouterr().out.splitlines())
    assert 1e-6 < good["hub_width_sd_m"] < 1e-4
    assert abs(good["hub_width_m"] - drawn_m) < 3 * good["hub_width_sd_m"]
    assert black["hub_width_m"] is None and black["hub_width_sd_m"] is None


def test_text_output(files, capsys) -> None:
    assert main(["measure", str(files["frame.jpg"]), "--calibration", str(files["cal.json"])]) == 0
    out = capsys.readouterr().out
    hub = float(out.split("hub angle ")[1].split(" deg")[0])
    assert hub == pytest.approx(290.0, abs=0.02) and "tip lateral +25." in out
    width = float(out.split("hub width ")[1].split(" mm")[0])
    assert width == pytest.approx(40.0, abs=0.05)
    assert out.split("hub width ")[1].startswith(f"{width:.2f} mm (sd 0.00")  # micrometres


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["junk.jpg", "--calibration", "cal.json"], "junk.jpg: not a readable image"),
        (["missing.jpg", "--calibration", "cal.json"], "missing.jpg: no such file"),
        (["frame.jpg", "--calibration", "frame.jpg"], "frame.jpg: cannot be read"),
        (["frame.jpg", "--calibration", "nope.json"], "nope.json: no such file"),
    ],
)
def test_bad_files_exit_2_with_one_line(files, capsys, args, words) -> None:
    d = files["cal.json"].parent
    argv = ["measure"] + [str(d / a) if not a.startswith("--") else a for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and words in err and err.count("\n") == 1


def test_a_truncated_image_gives_one_line_and_nothing_from_opencv(files, capfd) -> None:
    """At the file-descriptor level: OpenCV's own warning about damaged data would be a
    second line before ours."""
    d = files["cal.json"].parent
    ok, png = cv2.imencode(".png", np.full((64, 64), 128, np.uint8))
    assert ok
    (d / "cut.png").write_bytes(png.tobytes()[:50])
    assert main(["measure", str(d / "cut.png"), "--calibration", str(d / "cal.json")]) == 2
    err = capfd.readouterr().err
    assert err.startswith("error: ") and "cut.png" in err and err.count("\n") == 1


def _one_error_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


def test_a_mirrored_calibration_is_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the case: a mirrored plane measured hub 250 deg and tip -25 mm with exit 0
    data = json.loads(files["cal.json"].read_text())
    data["registration"]["plane_points_m"] = [
        [x, -y] for x, y in data["registration"]["plane_points_m"]
    ]
    cal = tmp_path / "mirror.json"
    cal.write_text(json.dumps(data))
    err = _one_error_line(["measure", str(files["frame.jpg"]), "--calibration", str(cal)], capsys)
    assert str(cal) in err and "mirrored" in err


def test_calibration_points_outside_the_image_are_refused(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(files["cal.json"].read_text())
    data["registration"]["image_points_px"] = [
        [x + 3000.0, y] for x, y in data["registration"]["image_points_px"]
    ]
    cal = tmp_path / "outside.json"
    cal.write_text(json.dumps(data))
    err = _one_error_line(["measure", str(files["frame.jpg"]), "--calibration", str(cal)], capsys)
    assert str(cal) in err and "outside the 2048 x 1536 image" in err


@pytest.mark.parametrize("points", [5, None, "abc", [1, 2, 3, 4], [[1, 2, 3]] * 4, [[True, 1]] * 4])
def test_calibration_points_of_the_wrong_shape_are_one_error_line(
    points: object, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(files["cal.json"].read_text())
    data["registration"]["image_points_px"] = points
    cal = tmp_path / "shape.json"
    cal.write_text(json.dumps(data))
    err = _one_error_line(["measure", str(files["frame.jpg"]), "--calibration", str(cal)], capsys)
    assert f"{cal}: registration.image_points_px must be" in err


@pytest.mark.parametrize("value", ["long", [1], None, True])
def test_calibration_beam_values_must_be_numbers(
    value: object, files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(files["cal.json"].read_text())
    data["beam"]["length_m"] = value
    cal = tmp_path / "beam.json"
    cal.write_text(json.dumps(data))
    err = _one_error_line(["measure", str(files["frame.jpg"]), "--calibration", str(cal)], capsys)
    assert "beam.length_m must be a number" in err


def test_a_calibration_with_its_covariance_adds_it_in_quadrature(files, tmp_path, capsys) -> None:
    from vision import decode, load_calibration
    from vision.registration import calibration_from_registration

    known = load_calibration(files["cal.json"])
    image = decode(files["frame.jpg"].read_bytes())
    detected = calibration_from_registration(
        image, RegistrationConfig(), known.camera_matrix, known.distortion
    )
    assert detected.plane_from_ideal_cov is not None
    (tmp_path / "detected.json").write_text(detected.to_json())
    out = {}
    for name, path in (("known", files["cal.json"]), ("detected", tmp_path / "detected.json")):
        argv = ["measure", str(files["frame.jpg"]), "--calibration", str(path), "--json"]
        assert main(argv) == 0
        out[name] = json.loads(capsys.readouterr().out)
    for sd in ("hub_angle_sd_rad", "tip_lateral_sd_m", "tip_longitudinal_sd_m"):
        share = out["detected"][f"calibration_{sd}"]
        assert share > 0.0
        # the frame's own noise (as measured with the known calibration) and the
        # calibration's share, in quadrature
        assert out["detected"][sd] == pytest.approx(math.hypot(out["known"][sd], share), rel=0.05)


class _Stream:
    def __init__(self, tty: bool) -> None:
        self.tty, self.text = tty, ""

    def isatty(self) -> bool:
        return self.tty

    def write(self, s: str) -> int:
        self.text += s
        return len(s)

    def flush(self) -> None:
        pass


def test_a_cold_kernel_cache_is_said_on_a_terminal_only() -> None:
    """The first run after an install waits ~25 s for numba's compile: on a terminal it
    says so before the first image; a pipe (scripts, logs, these tests' capture) and a
    warm cache get nothing."""
    from pipelines.commands.measure import COMPILING_NOTE, compiling_note

    for tty, cold, said in ((True, True, True), (False, True, False), (True, False, False)):
        stream = _Stream(tty)
        compiling_note(cold, stream)  # type: ignore[arg-type]
        assert stream.text == (COMPILING_NOTE + "\n" if said else ""), (tty, cold)


def test_measure_says_so_when_the_cache_is_cold(files, capsys, monkeypatch) -> None:
    import pipelines.commands.measure as measure_command
    import vision.jit

    asked: list[bool] = []
    monkeypatch.setattr(vision.jit, "cached", lambda package=None: False)
    monkeypatch.setattr(measure_command, "compiling_note", lambda cold: asked.append(cold))
    assert main(["measure", str(files["frame.jpg"]), "--calibration", str(files["cal.json"])]) == 0
    assert asked == [True]
