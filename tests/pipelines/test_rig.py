from __future__ import annotations

import math
from pathlib import Path

import pytest

from pipelines.errors import RigError
from pipelines.rig import Rig, default_rig_text, load_rig, parse_rig, rig_from_json

ROOT = Path(__file__).resolve().parents[2]


def test_default_rig_is_the_papers_bench() -> None:
    rig = load_rig()
    assert (rig.linkage.ground_m, rig.linkage.crank_m) == (0.340, 0.045)
    assert (rig.linkage.coupler_m, rig.linkage.rocker_m) == (0.330, 0.065)
    assert rig.beam.length_m == 0.835
    assert rig.beam.pivot_to_tip_m == pytest.approx(0.843, abs=1e-12)
    assert rig.beam.second_moment_m4 == pytest.approx(0.01905 * 0.003175**3 / 12, rel=1e-5)
    assert rig.gauges.positions_m == (0.005, 0.204, 0.403, 0.603)
    assert rig.daq.output_rate_hz == 400.0
    assert (rig.daq.passband_hz, rig.daq.stopband_hz) == (150.0, 200.0)
    assert rig.damping.a0_per_s == rig.damping.a1_s == 0.1
    assert rig.camera.width_px == 2048 and rig.camera.height_px == 1536
    assert rig.linkage.beam_mount_angle_rad == pytest.approx(math.pi)


def test_sample_data_copy_matches_the_packaged_rig() -> None:
    assert (ROOT / "sample_data" / "rig.toml").read_text("utf-8") == default_rig_text()


def test_defaults_of_the_dataclasses_match_the_file() -> None:
    """The file is the documented default; the dataclass defaults must not drift."""
    from_file = load_rig()
    assert {k: v for k, v in from_file.to_dict().items()} == Rig().to_dict()


def test_json_round_trip() -> None:
    rig = load_rig()
    again = rig_from_json(rig.to_json())
    assert again.to_dict() == rig.to_dict()


def _edit(old: str, new: str) -> str:
    text = default_rig_text()
    assert old in text
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ("length_m = 0.835", "length_m = -0.835", "beam", "length_m must be a positive"),
        ("crank_m = 0.045", "crank_m = 0.2", "linkage", "crank_m"),
        ("coupler_m = 0.330", "coupler_m = 0.05", "linkage", "not Grashof"),
        ("crank_m = 0.045", 'crank_m = "45 mm"', "linkage.crank_m", "must be a number"),
        ("gauge_factor = 2.0", "gauge_factr = 2.0", "gauges.gauge_factr", "unknown key"),
        ('bridge = "quarter"', 'bridge = "third"', "gauges", "bridge must be one of"),
        ("stopband_hz = 200.0", "stopband_hz = 100.0", "daq", "passband_hz"),
        ("acquisition_rate_hz = 2000.0", "acquisition_rate_hz = 2100.0", "daq", "whole multiple"),
        (
            "positions_m = [0.005, 0.204, 0.403, 0.603]",
            "positions_m = [0.005, 0.204, 0.403, 0.9]",
            "gauges.positions_m",
            "not on the beam",
        ),
        ("second_moment_m4 = 5.08095e-11", "second_moment_m4 = 5.08e-10", "beam", "disagrees"),
        ("[drive]", "[drivee]", "drivee", "unknown section"),
    ],
)
def test_bad_values_name_the_key_and_the_file(old: str, new: str, key: str, words: str) -> None:
    with pytest.raises(RigError) as info:
        parse_rig(_edit(old, new), source="bad.toml")
    msg = str(info.value)
    assert msg.startswith(f"bad.toml: [{key}]"), msg
    assert words in msg, msg
    assert "\n" not in msg


def test_missing_section_is_named() -> None:
    text = default_rig_text()
    start = text.index("[synthetic]")
    with pytest.raises(RigError, match=r"\[synthetic\] section is missing"):
        parse_rig(text[:start], source="short.toml")


def test_invalid_toml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(RigError, match="not valid TOML"):
        parse_rig("[beam\nlength_m = 1", source="x.toml")
    with pytest.raises(RigError, match="no such file"):
        load_rig(tmp_path / "nope.toml")


def test_degree_keys_convert_and_cannot_be_doubled() -> None:
    rig = parse_rig(_edit("tilt_deg = 15.0", "tilt_deg = 30.0"))
    assert rig.camera_pose.tilt_rad == pytest.approx(math.radians(30.0))
    with pytest.raises(RigError, match="given twice"):
        parse_rig(_edit("tilt_deg = 15.0", "tilt_deg = 15.0\ntilt_rad = 0.2"))
