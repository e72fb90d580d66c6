"""A log's rig record from another recorder: our JSON, flat string entries or none; what
is understood is used, the rest comes from --rig or the shipped default, in one warning
line; a value understood but impossible is refused as in a rig file."""

from __future__ import annotations

import math

import pytest

from pipelines.errors import RigError
from pipelines.rig import DEFAULT_SOURCE, load_rig, parse_rig, rig_from_log_record

SOURCE = "run.mcap (rig record)"


def test_flat_entries_are_read_by_section_prefix_dotted_or_bare_name() -> None:
    record = {
        "beam_length_m": "0.61",  # section_key
        "hub.width_m": "0.051",  # section.key
        "camera/frame_rate_hz": "20",  # section/key
        "crank_frequency_hz": "1.1",  # bare: only [linkage] has it
        "camera_pose_tilt_deg": "10",  # a _deg spelling of a _rad key
        "gauges_positions_m": "0.01, 0.2, 0.4, 0.55",  # a list without brackets
        "camera_device": "0",  # a string key keeps its text
        "camera_encoding": "png",
    }
    rig, note = rig_from_log_record(record, source=SOURCE)
    assert rig.beam.length_m == 0.61
    assert rig.hub.width_m == 0.051
    assert rig.camera.frame_rate_hz == 20.0
    assert rig.linkage.crank_frequency_hz == 1.1
    assert rig.camera_pose.tilt_rad == pytest.approx(math.radians(10.0))
    assert rig.gauges.positions_m == (0.01, 0.2, 0.4, 0.55)
    assert (rig.camera.device, rig.camera.encoding) == ("0", "png")
    default = load_rig()
    assert rig.beam.width_m == default.beam.width_m  # not in the record: the default's
    assert note is not None and "\n" not in note
    assert note.startswith(f"{SOURCE}: the rig record is flat entries")
    assert "read 8" in note and "the shipped default rig" in note and DEFAULT_SOURCE in note
    assert "not understood" not in note


def test_what_is_not_understood_is_named_in_the_one_line() -> None:
    record = {
        "beam_length_m": "0.835",
        "width_m": "0.02",  # [beam] and [hub] both have it
        "software": "another recorder 2.1",
        "camera_exposure_s": "2 ms",  # not a number
        "json_keys": "",
    }
    rig, note = rig_from_log_record(record, source=SOURCE)
    assert note is not None and "\n" not in note
    tail = note.split("not understood: ", 1)[1]
    assert "width_m (ambiguous)" in tail and "software" in tail and "json_keys" in tail
    assert "camera_exposure_s ('2 ms' is not a number)" in tail
    assert rig.camera.exposure_s == load_rig().camera.exposure_s


def test_the_rest_comes_from_the_given_rig() -> None:
    given = parse_rig(_rig_text(crank_hz=0.8), source="mine.toml")
    rig, note = rig_from_log_record({"beam_length_m": "0.7"}, source=SOURCE, given=given)
    assert rig.beam.length_m == 0.7 and rig.linkage.crank_frequency_hz == 0.8
    assert note is not None and "the rest from the rig of mine.toml" in note


def _rig_text(crank_hz: float) -> str:
    from pipelines.rig import default_rig_text

    text = default_rig_text()
    assert "crank_frequency_hz = 0.92" in text
    return text.replace("crank_frequency_hz = 0.92", f"crank_frequency_hz = {crank_hz}", 1)


def test_no_record_takes_the_given_or_default_rig_with_a_warning() -> None:
    rig, note = rig_from_log_record(None, source=SOURCE)
    assert rig.to_dict() == load_rig().to_dict()
    assert note == (
        f"{SOURCE}: the log has no rig record; using the shipped default rig "
        f"({DEFAULT_SOURCE}; pass --rig RIG.toml for yours)"
    )
    given = parse_rig(_rig_text(crank_hz=0.8), source="mine.toml")
    rig, note = rig_from_log_record(None, source=SOURCE, given=given)
    assert rig is given and note is not None and "using the rig of mine.toml" in note


def test_our_json_form_reads_silently_and_given_replaces_it() -> None:
    rig = load_rig()
    got, note = rig_from_log_record({"json": rig.to_json(), "beam": "{}"}, source=SOURCE)
    assert got.to_dict() == rig.to_dict() and note is None
    given = parse_rig(_rig_text(crank_hz=0.8), source="mine.toml")
    got, note = rig_from_log_record({"json": rig.to_json()}, source=SOURCE, given=given)
    assert got is given and note is None


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("beam_length_m", "-0.835", "[beam] length_m must be a positive"),
        ("beam_length_m", "NaN", "[beam.length_m] must be a finite number"),
        ("hub_width_m", "0.01", "[hub.width_m] the hub (0.01 m) must be wider than the beam"),
        ("hub_length_m", "1e300", "[hub] length_m must be at most 1 m"),
    ],
)
def test_a_value_understood_but_impossible_is_refused_naming_the_log(
    key: str, value: str, words: str
) -> None:
    with pytest.raises(RigError) as err:
        rig_from_log_record({key: value}, source=SOURCE)
    msg = str(err.value)
    assert msg.startswith(SOURCE) and words in msg and "\n" not in msg, msg


def test_a_rig_file_without_a_hub_section_takes_the_default_hints_with_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from pipelines.rig import default_rig_text

    text = default_rig_text()
    start = text.index("[hub]")
    end = text.index("[synthetic]")
    with caplog.at_level("WARNING", logger="pipelines.rig"):
        rig = parse_rig(text[:start] + text[end:], source="old.toml")
    assert rig.hub == load_rig().hub
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and messages[0].startswith("old.toml: [hub] is missing")


def test_a_plate_our_synthetic_camera_would_not_see_is_not_refused_in_a_log() -> None:
    """Another bench's camera looks where it looks: the synthetic camera's view (a rig
    file's check) is not asked of a log's record."""
    record = {"registration_center_m": "[2.5, 1.0]"}
    rig, note = rig_from_log_record(record, source=SOURCE)
    assert rig.registration.center_m == (2.5, 1.0) and note is not None
    from pipelines.rig import default_rig_text

    text = default_rig_text().replace("center_m = [0.50, 0.05]", "center_m = [2.5, 1.0]", 1)
    with pytest.raises(RigError, match="not wholly in the camera's view"):
        parse_rig(text, source="file.toml")
