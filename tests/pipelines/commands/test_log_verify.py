"""Logs are verified as they are read: CRCs with the damage located, every message against
its schema with the first bad one named, and the command line's one ``error:`` line.

The logs here are written with the ``mcap`` library directly, as another recorder would
(its own schema text, a 500 Hz stream, no ``_json_keys`` unless a case needs it), not with
``daq.log.LogWriter``.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from daq.log import LogError, iter_frames, read_run, scan_log
from pipelines.cli import main
from pipelines.rig import load_rig

RATE_HZ = 500.0  # not beambench's 400 Hz on purpose
PERIOD_NS = 2_000_000
N_SAMPLES = 300
FRAME_PERIOD_NS = 50_000_000  # 20 frames/s
RIG = json.loads(load_rig().to_json())  # the rig other commands accept
assert RIG["synthetic"]["warmup_s"] == 6.0
RUN = {"run_id": "other-recorder-7", "start_utc": "2026-11-01T10:00:00Z"}
SCHEMA = json.dumps({"type": "object", "title": "beambench.DaqSample"}).encode()

Sample = dict[str, Any]


def _jpeg(value: int) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((30, 40), value, np.uint8))
    assert ok
    return buf.tobytes()


def _sample(k: int) -> Sample:
    t = k * PERIOD_NS
    return {
        "timestamp": {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000},
        "rocker_angle_rad": 1.1 + 0.3 * np.sin(k / 40),
        "strain": [1e-4 * np.cos(k / 30 + g) for g in range(4)],
        "raw_volts": [2.5 + 0.1 * g + 1e-3 * k for g in range(5)],
    }


def _image(t_ns: int, data: bytes, fmt: str = "jpeg") -> bytes:
    msg = CompressedImage(frame_id="cam", data=data, format=fmt)
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)
    return msg.SerializeToString()


def _event(t_ns: int, name: str) -> bytes:
    msg = Log(level=Log.WARNING, message="x", name=name)
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(t_ns, 1_000_000_000)
    return msg.SerializeToString()


def write_log(
    path: Path,
    *,
    samples: list[tuple[int, int, bytes]] | None = None,
    images: list[tuple[int, int, bytes]] | None = None,
    events: list[tuple[int, int, bytes]] | None = None,
    rig: dict[str, str] | None = None,
    run: dict[str, str] | None = None,
    data_crcs: bool = True,
    no_rig: bool = False,
    extra_channel: bool = False,
) -> None:
    """A log as another recorder writes it: (log time, sequence, payload) per message."""
    if samples is None:
        samples = [(k * PERIOD_NS, k, json.dumps(_sample(k)).encode()) for k in range(N_SAMPLES)]
    if images is None:
        images = [(k * FRAME_PERIOD_NS, k, _image(k * FRAME_PERIOD_NS, _jpeg(k))) for k in range(8)]
    if events is None:
        events = [(0, 0, _event(0, "start"))]
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=4096, compression=CompressionType.ZSTD, enable_data_crcs=data_crcs)
        w.start(profile="beambench", library="another-recorder 0.3")
        sid = w.register_schema("beambench.DaqSample", "jsonschema", SCHEMA)
        channels = {"/daq/samples": w.register_channel("/daq/samples", "json", sid)}
        for topic, cls in (("/camera/image", CompressedImage), ("/events", Log)):
            fds = build_file_descriptor_set(cls).SerializeToString()
            sid = w.register_schema(cls.DESCRIPTOR.full_name, "protobuf", fds)
            channels[topic] = w.register_channel(topic, "protobuf", sid)
        if extra_channel:  # another recorder's own channel, with its own schema
            sid = w.register_schema("other.Temperature", "jsonschema", b'{"type":"object"}')
            other = w.register_channel("/diagnostics/temperature", "json", sid)
            for k in range(3):
                w.add_message(other, k * 10**9, b'{"c": 31.5}', k * 10**9, k)
        if not no_rig:
            w.add_metadata("rig", rig if rig is not None else {"json": json.dumps(RIG)})
        w.add_metadata("run", run if run is not None else RUN)
        for topic, messages in (
            ("/daq/samples", samples),
            ("/camera/image", images),
            ("/events", events),
        ):
            for t, seq, data in messages:
                w.add_message(channels[topic], t, data, t + 1000, seq)
        w.finish()


def _samples_with(k: int, change: Callable[[Sample], Any]) -> list[tuple[int, int, bytes]]:
    out = []
    for j in range(N_SAMPLES):
        s = _sample(j)
        if j == k:
            s = change(s) or s
        out.append((j * PERIOD_NS, j, json.dumps(s).encode()))
    return out


def _set(key: str, value: Any) -> Callable[[Sample], None]:
    return lambda s: s.__setitem__(key, value)


def test_a_foreign_log_reads_back_exactly(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_log(path)
    run = read_run(path, require_samples=True)
    assert len(run.samples) == N_SAMPLES
    np.testing.assert_array_equal(run.samples.t_ns, np.arange(N_SAMPLES) * PERIOD_NS)
    want = np.array([_sample(k)["strain"] for k in range(N_SAMPLES)])
    np.testing.assert_array_equal(run.samples.strain, want)
    assert json.loads(run.rig_json) == RIG
    assert run.run_info == RUN
    frames = list(iter_frames(path))
    assert [f.sequence for f in frames] == list(range(8))
    assert (frames[0].width_px, frames[0].height_px) == (40, 30)
    stats, _ = scan_log(path)
    assert len(stats["/daq/samples"].sequence) == N_SAMPLES


def test_unknown_rig_keys_are_the_rig_loaders_business(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    rig = {"beam": {"length_m": 0.61}, "unknown_section": {"x": 1}}
    write_log(path, rig={"json": json.dumps(rig), "beam": "flat string"})
    assert json.loads(read_run(path).rig_json) == rig
    path.unlink()
    write_log(path, rig={"beam.length_m": "0.61"})  # another recorder's flat strings
    assert read_run(path).rig_json == ""


def test_a_flat_or_absent_rig_record_is_read_as_written(tmp_path: Path) -> None:
    """Another recorder's flat entries reach the rig loader as they are; a log without a
    rig record reads (the rig then comes from --rig or the default); no run record is
    still refused."""
    path = tmp_path / "run.mcap"
    flat = {"beam_length_m": "0.61", "software": "another recorder"}
    write_log(path, rig=flat)
    run = read_run(path)
    assert run.rig_record == flat and run.rig_json == ""
    path.unlink()
    write_log(path, rig={"json": json.dumps(RIG)})
    assert read_run(path).rig_record == {"json": json.dumps(RIG)}
    path.unlink()
    write_log(path, rig=None, no_rig=True)
    run = read_run(path)
    assert run.rig_record is None and run.rig_json == ""
    assert len(run.samples) == N_SAMPLES


def test_another_recorders_own_channel_is_counted_not_decoded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "run.mcap"
    write_log(path, extra_channel=True)
    assert len(read_run(path, require_samples=True).samples) == N_SAMPLES
    stats, info = scan_log(path)
    assert len(stats["/diagnostics/temperature"].sequence) == 3
    assert info["library"] == "another-recorder 0.3"
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("/diagnostics/temperature"))
    assert line.split()[2] == "3"
    assert "backends: daq not recorded, camera not recorded; acquired at an unrecorded" in out


def _record_offsets(path: Path) -> dict[str, list[int]]:
    """Offsets of the chunks (data section) and metadata records, from the summary."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None
        image_id = next(c.id for c in summary.channels.values() if c.topic == "/camera/image")
        return {
            "chunks": [c.chunk_start_offset for c in summary.chunk_indexes],
            "image_chunks": [
                c.chunk_start_offset
                for c in summary.chunk_indexes
                if image_id in c.message_index_offsets
            ],
            "metadata": [m.offset for m in summary.metadata_indexes],
        }


def _flip(path: Path, out: Path, offset: int, new: int | None = None) -> None:
    data = bytearray(path.read_bytes())
    data[offset] = data[offset] ^ 0x04 if new is None else new
    out.write_bytes(bytes(data))


def test_a_flipped_byte_in_a_chunk_names_the_chunk_and_does_not_suggest_recover(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "run.mcap"
    write_log(path)
    chunk = _record_offsets(path)["chunks"][2]
    bad = tmp_path / "bad.mcap"
    _flip(bad.parent / "run.mcap", bad, chunk + 9 + 8 + 8 + 8 + 4 + 4 + 4 + 8 + 40)
    for read in (read_run, scan_log):
        with pytest.raises(LogError) as err:
            read(bad)
        text = str(err.value)
        assert text.startswith(f"{bad}: damaged at byte {chunk}: a chunk") and "recover" not in text
    list(iter_frames(bad))  # frames are read lazily: a samples chunk is not theirs to check
    image_chunk = _record_offsets(path)["image_chunks"][0]
    frames_bad = tmp_path / "frames_bad.mcap"
    _flip(path, frames_bad, image_chunk + 9 + 8 + 8 + 8 + 4 + 4 + 4 + 8 + 40)
    with pytest.raises(LogError, match=rf"damaged at byte {image_chunk}: a chunk"):
        list(iter_frames(frames_bad))
    for argv in (["info", str(bad)], ["replay", str(bad), "--rrd", str(tmp_path / "o.rrd")]):
        assert main(argv) == 2
        err_text = capsys.readouterr().err
        assert err_text.count("\n") == 1 and err_text.startswith(f"error: {bad}: damaged at")
    assert main(["process", str(bad), "--out", str(tmp_path / "r.nc")]) == 2
    err_text = capsys.readouterr().err
    assert err_text.count("\n") == 1 and f"{bad}: damaged at byte {chunk}" in err_text
    assert not (tmp_path / "r.nc").exists()


def test_a_changed_rig_value_is_caught_by_the_data_crc(tmp_path: Path) -> None:
    """The issue's case: a flip turned warmup_s 6.0 into 6.4 and nothing noticed."""
    path = tmp_path / "run.mcap"
    write_log(path)
    data = path.read_bytes()
    at = data.index(b'"warmup_s": 6.0') + len(b'"warmup_s": 6.')
    bad = tmp_path / "bad.mcap"
    _flip(path, bad, at, ord("4"))
    meta = _record_offsets(path)["metadata"]
    with pytest.raises(LogError) as err:
        read_run(bad)
    # the JSON still parses, so the record cannot be named: the data-section CRC can
    assert "fail the data-section CRC" in str(err.value) and "recover" not in str(err.value)
    # a rig record that no longer parses is named with its offset
    _flip(path, bad, data.index(b'"warmup_s"'), ord("{"))
    with pytest.raises(LogError, match=rf"damaged at byte {meta[0]}: corrupt metadata record"):
        read_run(bad)


def test_truncated_or_summary_damage_suggests_recover(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_log(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) - 50])
    with pytest.raises(LogError, match=r"cut\.mcap: truncated.*\(try beambench recover\)$"):
        read_run(cut)
    with open(path, "rb") as f:
        f.seek(-(29 + 8), 2)
        summary_start = struct.unpack("<BQQQI", f.read(29))[2]
    bad = tmp_path / "bad.mcap"
    _flip(path, bad, summary_start + 20)
    with pytest.raises(LogError, match=r"summary section fails its CRC \(try beambench recover\)"):
        read_run(bad)


def test_every_single_byte_flip_is_refused(tmp_path: Path) -> None:
    """With CRCs on the data section, the chunks and the summary, no byte of the file can
    change unnoticed: read_run refuses every flip (one every 11 bytes)."""
    path = tmp_path / "run.mcap"
    write_log(
        path,
        samples=[(k * PERIOD_NS, k, json.dumps(_sample(k)).encode()) for k in range(30)],
        images=[(0, 0, _image(0, _jpeg(1)))],
    )
    data = path.read_bytes()
    bad = tmp_path / "bad.mcap"
    for offset in range(0, len(data), 11):
        b = bytearray(data)
        b[offset] ^= 0x10
        bad.write_bytes(bytes(b))
        with pytest.raises(LogError) as err:
            read_run(bad)
        assert str(err.value).startswith(f"{bad}: "), offset


def test_logs_without_a_data_crc_still_get_their_chunks_checked(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_log(path, data_crcs=False)
    assert len(read_run(path).samples) == N_SAMPLES
    chunk = _record_offsets(path)["chunks"][1]
    bad = tmp_path / "bad.mcap"
    _flip(path, bad, chunk + 80)
    with pytest.raises(LogError, match=rf"damaged at byte {chunk}: a chunk"):
        read_run(bad)


SAMPLE_CASES: dict[str, tuple[Callable[[Sample], Any], str]] = {
    "boolean angle": (_set("rocker_angle_rad", True), "rocker_angle_rad must be a number"),
    "string angle": (_set("rocker_angle_rad", "1.2"), "the string '1.2'"),
    "nested angle": (_set("rocker_angle_rad", [1.0]), "a JSON array"),
    "five strains": (lambda s: s["strain"].append(0.0), "strain must hold 4 numbers, got 5"),
    "four volts": (lambda s: s["raw_volts"].pop() and None, "raw_volts must hold 5 numbers, got 4"),
    "null strain list": (_set("strain", None), "strain must be an array"),
    "huge volts": (lambda s: s["raw_volts"].__setitem__(2, 1e300), r"raw_volts\[2\] = 1e\+300"),
    "huge strain": (lambda s: s["strain"].__setitem__(1, 3.0), r"strain\[1\] = 3.0 is outside"),
    "nested volt": (lambda s: s["raw_volts"].__setitem__(0, {"v": 1}), "a JSON object"),
    "no timestamp": (lambda s: s.pop("timestamp"), "lacks 'timestamp'"),
    "negative time": (_set("timestamp", {"sec": -1, "nsec": 0}), "timestamp.sec = -1"),
    "float time": (_set("timestamp", {"sec": 0.5, "nsec": 0}), "timestamp.sec must be an integer"),
    "nsec overflow": (_set("timestamp", {"sec": 0, "nsec": 10**9}), "timestamp.nsec"),
    "a list": (lambda s: [1, 2, 3], "must be a JSON object"),
}


@pytest.mark.parametrize("case", sorted(SAMPLE_CASES))
def test_nonsense_sample_contents_name_the_first_bad_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    change, problem = SAMPLE_CASES[case]
    path = tmp_path / "run.mcap"
    k = 117
    write_log(path, samples=_samples_with(k, change))
    where = rf"bad /daq/samples message \(sequence {k}, log time {k * PERIOD_NS} ns\): "
    with pytest.raises(LogError, match=where + ".*" + problem):
        read_run(path)
    with pytest.raises(LogError, match=where):
        scan_log(path)
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {path}: bad /daq/samples")
    assert "recover" not in err


def test_non_json_and_non_finite_literals_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    for text, problem in (
        (b'{"timestamp": {"sec": 0, "nsec": 0}, "rocker_angle_rad": NaN', "not a JSON number"),
        (b"\xff\xfe not text", "not UTF-8 JSON"),
        (b"[" * 100_000, "nested too deeply|not JSON"),
        (b'{"rocker_angle_rad": 1e999}', "lacks 'timestamp'"),
    ):
        samples = [(k * PERIOD_NS, k, json.dumps(_sample(k)).encode()) for k in range(5)]
        samples[3] = (3 * PERIOD_NS, 3, text)
        path.unlink(missing_ok=True)
        write_log(path, samples=samples)
        with pytest.raises(LogError, match=rf"sequence 3, .*({problem})"):
            read_run(path)
    s = _sample(3)
    s["strain"][0] = 10**400  # an integer beyond any float
    samples[3] = (3 * PERIOD_NS, 3, json.dumps(s).encode())
    path.unlink()
    write_log(path, samples=samples)
    with pytest.raises(LogError, match=r"strain\[0\] = .* is outside"):
        read_run(path)


def _stream(times: list[int], seqs: list[int]) -> list[tuple[int, int, bytes]]:
    out = []
    for t, q in zip(times, seqs, strict=True):
        s = _sample(q)
        s["timestamp"] = {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000}
        out.append((t, q, json.dumps(s).encode()))
    return out


def test_time_and_sequence_order_are_checked(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    times = [k * PERIOD_NS for k in range(50)]
    seqs = list(range(50))
    backwards = list(times)
    backwards[20] = times[10]  # sequence 20 stamped at sequence 10's time
    write_log(path, samples=_stream(backwards, seqs))
    with pytest.raises(
        LogError, match=r"sequence 20, log time 20000000 ns\): time does not advance"
    ):
        read_run(path)
    path.unlink()
    dup = list(seqs)
    dup[31] = 30
    write_log(path, samples=_stream(times, dup))
    with pytest.raises(LogError, match=r"sequence 30 appears twice"):
        read_run(path)
    with pytest.raises(LogError, match=r"sequence 30 appears twice"):
        scan_log(path)
    path.unlink()
    # the payload's time and the log time are the same acquisition time
    samples = _stream(times, seqs)
    samples[7] = (samples[7][0] + 1, 7, samples[7][2])
    write_log(path, samples=samples)
    with pytest.raises(LogError, match=r"sequence 7, .*timestamp 14000000 ns is not its log"):
        read_run(path)
    path.unlink()
    # a gap (lost samples) is not an error: it is what the sequence numbers are for
    gap = [*range(20), *range(25, 50)]
    write_log(path, samples=_stream([q * PERIOD_NS for q in gap], gap))
    assert list(read_run(path).sample_sequences) == gap


IMAGE_CASES: dict[str, tuple[bytes, str]] = {
    "not protobuf": (b"\xff\xff\xff\xff garbage", "not a foxglove.CompressedImage"),
    "a GIF": (_image(0, b"GIF89a" + bytes(40), "gif"), "is not a JPEG or PNG"),
    "empty": (_image(0, b"", "jpeg"), "is not a JPEG or PNG"),
    "format lies": (_image(0, _jpeg(3), "png"), "format says 'png' but the image is a jpeg"),
    "huge png": (
        _image(
            0,
            b"\x89PNG\r\n\x1a\n" + struct.pack(">I4sII", 13, b"IHDR", 100_000, 100_000) + bytes(5),
            "png",
        ),
        "claims 100000 x 100000 px",
    ),
    "jpeg without frame header": (_image(0, b"\xff\xd8\xff\xd9", "jpeg"), "without a frame"),
}


@pytest.mark.parametrize("case", sorted(IMAGE_CASES))
def test_bad_images_name_the_frame(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    payload, problem = IMAGE_CASES[case]
    path = tmp_path / "run.mcap"
    images = [(k * FRAME_PERIOD_NS, k, _image(k * FRAME_PERIOD_NS, _jpeg(k))) for k in range(6)]
    images[4] = (4 * FRAME_PERIOD_NS, 4, payload.replace(b"", b"") if payload else payload)
    if case != "not protobuf":  # the timestamps must agree for the payload to be judged
        msg = CompressedImage()
        msg.ParseFromString(payload)
        msg.timestamp.seconds, msg.timestamp.nanos = 0, 4 * FRAME_PERIOD_NS
        images[4] = (4 * FRAME_PERIOD_NS, 4, msg.SerializeToString())
    write_log(path, images=images)
    where = rf"bad /camera/image message \(sequence 4, log time {4 * FRAME_PERIOD_NS} ns\): "
    got = []
    with pytest.raises(LogError, match=where + ".*" + problem):
        for frame in iter_frames(path):
            got.append(frame.sequence)
    assert got == [0, 1, 2, 3]
    with pytest.raises(LogError, match=where):
        scan_log(path)
    for argv in (
        ["info", str(path)],
        ["process", str(path), "--out", str(tmp_path / "r.nc")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: ") and "bad /camera/image" in err


def test_frame_counter_and_time_order(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    images = [(k * FRAME_PERIOD_NS, k, _image(k * FRAME_PERIOD_NS, _jpeg(k))) for k in range(6)]
    images[3] = (3 * FRAME_PERIOD_NS, 2, images[3][2])
    write_log(path, images=images)
    with pytest.raises(LogError, match=r"sequence 2, .*appears twice"):
        list(iter_frames(path))


def test_bad_events_and_metadata(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "run.mcap"
    write_log(path, events=[(0, 0, _event(0, "start")), (5, 1, b"\xff\xff\xff\xffnot")])
    with pytest.raises(LogError, match=r"bad /events message \(sequence 1, log time 5 ns\)"):
        read_run(path)
    path.unlink()
    write_log(path, events=[(0, 0, _event(0, "start")), (5, 0, _event(5, "stop"))])
    with pytest.raises(LogError, match=r"/events .*sequence 0 appears twice"):
        read_run(path)
    path.unlink()
    write_log(path, run={"_json_keys": "rates", "rates": '{"daq": 2000.0!', "run_id": "x"})
    with pytest.raises(LogError, match=r"corrupt metadata record 'run': 'rates' is not valid"):
        read_run(path)
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "corrupt metadata record 'run'" in err
    path.unlink()
    write_log(path, rig={"json": "[1, 2]"})
    with pytest.raises(LogError, match=r"corrupt metadata record 'rig': 'json' must be a JSON"):
        read_run(path)
    path.unlink()
    write_log(path, rig={"json": "{not json"})
    assert main(["process", str(path), "--out", str(tmp_path / "r.nc")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "corrupt metadata record 'rig'" in err


def test_a_log_without_samples_is_an_error_for_process(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "run.mcap"
    write_log(path, samples=[])
    assert len(read_run(path).samples) == 0  # reading it is fine (info shows it)
    with pytest.raises(LogError, match=r"run\.mcap: no /daq/samples messages"):
        read_run(path, require_samples=True)
    assert main(["process", str(path), "--out", str(tmp_path / "r.nc")]) == 2
    err = capsys.readouterr().err
    assert (
        err == f"error: {path}: no /daq/samples messages: the DAQ stream (rocker angle "
        "and strains) is missing\n"
    )


def test_a_channel_never_measured_is_an_error_for_process(tmp_path: Path) -> None:
    """null is the writer's missing value (read as NaN): a few are data, a channel that
    is null throughout was never measured."""
    path = tmp_path / "run.mcap"

    def gauge3_dead(s: Sample) -> None:
        s["strain"][2] = None

    samples = []
    for k in range(N_SAMPLES):
        s = _sample(k)
        gauge3_dead(s)
        if 10 <= k < 20:
            s["rocker_angle_rad"] = None
        samples.append((k * PERIOD_NS, k, json.dumps(s).encode()))
    write_log(path, samples=samples)
    run = read_run(path)
    assert np.isnan(run.samples.rocker_angle_rad[10:20]).all()
    assert np.isfinite(run.samples.rocker_angle_rad[20:]).all()
    with pytest.raises(LogError, match=r"the gauge 3 strain is null in all 300 samples"):
        read_run(path, require_samples=True)
