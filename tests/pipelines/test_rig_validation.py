"""The rig validated completely: every numeric key refuses NaN, infinities and 1e300 with
the file and the key named; physical ranges; the registration plate in view; a missing
key filled from the shipped default only with a warning naming it."""

from __future__ import annotations

import logging
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

from pipelines.errors import RigError
from pipelines.rig import default_rig_text, load_rig, parse_rig

DEFAULT = tomllib.loads(default_rig_text())


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, float):
        return (
            "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        )
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return repr(v)


def dump(data: dict[str, dict[str, Any]]) -> str:
    """A rig as TOML text (tables of scalars and lists)."""
    lines = []
    for section, table in data.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def with_value(section: str, key: str, value: Any) -> str:
    data = {s: dict(t) for s, t in DEFAULT.items()}
    data[section][key] = value
    return dump(data)


NUMERIC_KEYS = [
    (s, k)
    for s, t in DEFAULT.items()
    for k, v in t.items()
    if isinstance(v, int | float) and not isinstance(v, bool)
]
LIST_KEYS = [(s, k) for s, t in DEFAULT.items() for k, v in t.items() if isinstance(v, list)]


def test_the_dump_round_trips() -> None:
    assert parse_rig(dump(DEFAULT)).to_dict() == load_rig().to_dict()


def _refused(text: str, section: str) -> str:
    with pytest.raises(RigError) as info:
        parse_rig(text, source="bad.toml")
    msg = str(info.value)
    assert msg.startswith(f"bad.toml: [{section}"), msg
    assert "\n" not in msg
    return msg


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1e300, -1e300])
@pytest.mark.parametrize(("section", "key"), NUMERIC_KEYS)
def test_every_numeric_key_refuses_non_finite_and_absurd_values(
    section: str, key: str, bad: float
) -> None:
    msg = _refused(with_value(section, key, bad), section)
    field = key[:-4] + "_rad" if key.endswith("_deg") else key
    # the message names the key (a cross-section check names the key it is about)
    assert key in msg or field in msg or "not Grashof" in msg or "registration" in msg, msg


LIST_CASES = [
    (s, k, bad)
    for s, k in LIST_KEYS
    for bad in (
        (1.0, True) if isinstance(DEFAULT[s][k][0], str) else (math.nan, math.inf, 1e300, "x", True)
    )
]


@pytest.mark.parametrize(("section", "key", "bad"), LIST_CASES)
def test_every_list_refuses_a_bad_item(section: str, key: str, bad: object) -> None:
    items = list(DEFAULT[section][key])
    items[-1] = bad
    _refused(with_value(section, key, items), section)


@pytest.mark.parametrize(
    ("section", "key", "value", "words"),
    [
        ("beam", "hub_offset_m", 2.0, "shorter than the beam"),
        ("camera", "width_px", 20000, "16384"),
        ("camera", "height_px", 20000, "16384"),
        ("camera", "frame_rate_hz", 1000.0, "158.9 frames/s for a 2048 x 1536 camera"),
        ("camera", "latency_s", -0.01, "latency_s"),
        ("camera", "focal_length_px", 10.0, "fisheye"),
        ("daq", "block_duration_s", 1e6, "at most 10 s"),
        ("synthetic", "warmup_s", 1e6, "at most 600 s"),
        ("synthetic", "beam_dn", 30.0, "must exceed background_dn"),
        ("synthetic", "background_dn", 300.0, "within 0..255 DN"),
        ("synthetic", "lighting_gradient", -1.5, "within +/-1"),
        ("synthetic", "stamp_latency_s", 0.6, "at most 0.25 s"),
        ("synthetic", "drawn_hub_length_m", 2.0, "0 (draw [hub]) or a length of at most 1 m"),
        ("synthetic", "drawn_hub_width_m", -0.04, "0 (draw [hub]) or a length of at most 0.3 m"),
        ("registration", "center_m", [5.0, 5.0], "not wholly in the camera's view"),
        ("camera_pose", "target_m", [3.0, 0.0], "not wholly in the camera's view"),
        ("beam", "youngs_modulus_pa", 1.0, "rubber to diamond"),
        ("linkage", "crank_frequency_hz", 1e4, "a bench motor"),
    ],
)
def test_physical_ranges_state_their_limit(
    section: str, key: str, value: object, words: str
) -> None:
    where = "registration" if "view" in words else section  # the plate is what is out of view
    msg = _refused(with_value(section, key, value), where)
    assert words in msg, msg


def test_a_missing_key_is_filled_with_a_warning_naming_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    data = {s: dict(t) for s, t in DEFAULT.items()}
    del data["camera"]["latency_s"]
    del data["potentiometer"]["zero_angle_deg"]
    data["beam"]["length_m"] = 0.9  # the given keys are kept
    with caplog.at_level(logging.WARNING, logger="pipelines.rig"):
        rig = parse_rig(dump(data), source="short.toml")
    messages = [r.getMessage() for r in caplog.records]
    assert any("short.toml: [camera.latency_s] is missing" in m and "0.03" in m for m in messages)
    assert any("[potentiometer.zero_angle_deg] is missing" in m for m in messages)
    assert len(messages) == 2
    default = load_rig()
    assert rig.camera.latency_s == default.camera.latency_s
    assert rig.potentiometer.zero_angle_rad == pytest.approx(default.potentiometer.zero_angle_rad)
    assert rig.beam.length_m == 0.9


def test_a_complete_rig_and_the_default_load_without_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with caplog.at_level(logging.WARNING, logger="pipelines.rig"):
        load_rig()
        parse_rig(default_rig_text(), source="copy.toml")
    assert caplog.records == []


def test_the_rad_twin_of_a_deg_key_is_not_missing(caplog: pytest.LogCaptureFixture) -> None:
    data = {s: dict(t) for s, t in DEFAULT.items()}
    del data["camera_pose"]["tilt_deg"]
    data["camera_pose"]["tilt_rad"] = 0.3
    with caplog.at_level(logging.WARNING, logger="pipelines.rig"):
        rig = parse_rig(dump(data), source="rad.toml")
    assert caplog.records == []
    assert rig.camera_pose.tilt_rad == 0.3


def test_the_cli_warns_on_stderr_and_runs(tmp_path: Path) -> None:
    data = {s: dict(t) for s, t in DEFAULT.items()}
    del data["camera"]["exposure_s"]
    path = tmp_path / "rig.toml"
    path.write_text(dump(data))
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run(
        [sys.executable, "-m", "pipelines.cli", "sim", "linkage", "--rig", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=root,
        env={**os.environ, "PYTHONPATH": str(root)},
    )
    assert proc.returncode == 0, proc.stderr
    assert f"{path}: [camera.exposure_s] is missing; using the shipped default" in proc.stderr
