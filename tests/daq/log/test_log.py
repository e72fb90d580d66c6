"""The run log: round trip, the format contract, damaged files, recovery."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from daq.log import (
    LogError,
    LogWriter,
    iter_frames,
    opens_as_log,
    read_run,
    recover_log,
    scan_log,
)
from daq.records import Event, Frame, SampleBlock

RIG_JSON = json.dumps({"daq": {"output_rate_hz": 400.0}, "gauges": {"bridge": "quarter"}})
CAMERA_INFO = {
    "width": 64,
    "height": 48,
    "K": [80.0, 0, 31.5, 0, 80.0, 23.5, 0, 0, 1],
    "D": [0.01, 0, 0, 0, 0],
    "distortion_model": "plumb_bob",
}


def _jpeg(value: int, w: int = 64, h: int = 48) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((h, w, 3), value, np.uint8))
    assert ok
    return buf.tobytes()


def _png(w: int = 20, h: int = 10) -> bytes:
    ok, buf = cv2.imencode(".png", np.zeros((h, w), np.uint8))
    assert ok
    return buf.tobytes()


def _samples(first: int, n: int, rng: np.random.Generator) -> SampleBlock:
    seq = np.arange(first, first + n)
    return SampleBlock(
        seq * 2_500_000 + 7,
        rng.normal(size=n),
        rng.normal(size=(n, 4)) * 1e-4,
        rng.normal(size=(n, 5)),
        first,
    )


def _write(
    path: Path, blocks: list[SampleBlock], frames: list[Frame], events: list[Event], **kw: object
) -> None:
    with LogWriter(
        path,
        rig_json=RIG_JSON,
        run_info={"run_id": "abc", "n": 3, "rates": {"daq": 2000.0}},
        camera_info=CAMERA_INFO,
        **kw,
    ) as w:  # type: ignore[arg-type]
        for b in blocks:
            w.write_samples(b)
        for f in frames:
            w.write_frame(f)
        for e in events:
            w.write_event(e)


def test_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    blocks = [_samples(0, 40, rng), _samples(40, 40, rng), _samples(90, 10, rng)]
    awkward = blocks[2].rocker_angle_rad.copy()
    awkward[:3] = [np.nan, 1e-300, -0.0]
    blocks[2] = SampleBlock(blocks[2].t_ns, awkward, blocks[2].strain, blocks[2].raw_volts, 90)
    frames = [
        Frame(10_000_000, 0, _jpeg(10), "jpeg", 64, 48),
        Frame(76_000_000, 2, _png(), "png", 20, 10),
    ]
    events = [
        Event(0, "info", "start", "go"),
        Event(5, "warning", "clipping", "gauge 2 ✓"),
        Event(9, "error", "device_error", ""),
    ]
    path = tmp_path / "run.mcap"
    _write(path, blocks, frames, events)
    run = read_run(path)
    assert run.samples == SampleBlock.concatenate(blocks)
    assert np.isnan(run.samples.rocker_angle_rad[80])
    assert np.signbit(run.samples.rocker_angle_rad[82])
    assert run.events == events
    assert run.rig_json == RIG_JSON
    assert run.run_info["run_id"] == "abc" and run.run_info["n"] == 3
    assert run.run_info["rates"] == {"daq": 2000.0}
    assert run.camera_info == {
        **CAMERA_INFO,
        "K": [float(k) for k in CAMERA_INFO["K"]],
        "D": [0.01, 0.0, 0.0, 0.0, 0.0],
    }
    assert run.frame_count == 2
    assert list(iter_frames(path)) == frames
    np.testing.assert_array_equal(run.sample_sequences, [*range(80), *range(90, 100)])


def test_file_follows_the_log_contract(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    path = tmp_path / "run.mcap"
    _write(
        path,
        [_samples(0, 5, rng)],
        [Frame(1000, 0, _jpeg(3), "jpeg", 64, 48)],
        [Event(0, "info", "start", "go")],
    )
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "beambench"
        assert header.library.startswith("beambench ")
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic: c for c in summary.channels.values()}
        assert set(topics) == {"/daq/samples", "/camera/image", "/camera/info", "/events"}
        names = {t: summary.schemas[c.schema_id].name for t, c in topics.items()}
        assert names == {
            "/daq/samples": "beambench.DaqSample",
            "/camera/image": "foxglove.CompressedImage",
            "/camera/info": "foxglove.CameraCalibration",
            "/events": "foxglove.Log",
        }
        schema = json.loads(summary.schemas[topics["/daq/samples"].schema_id].data)
        assert schema["title"] == "beambench.DaqSample"
        assert {m.name for m in reader.iter_metadata()} == {"rig", "run"}
        samples = []
        for _, _, message in reader.iter_messages(topics=["/daq/samples"]):
            samples.append((message, json.loads(message.data)))
            assert message.publish_time > 1.6e18  # wall clock of the write
        assert [m.sequence for m, _ in samples] == list(range(5))
        first = samples[1][1]
        assert first["timestamp"] == {"sec": 0, "nsec": 2_500_007}
        assert samples[1][0].log_time == 2_500_007
        assert len(first["strain"]) == 4 and len(first["raw_volts"]) == 5
        decoded = list(reader.iter_decoded_messages(topics=["/camera/image", "/events"]))
        image = next(d.decoded_message for d in decoded if d.channel.topic == "/camera/image")
        assert image.format == "jpeg" and image.data[:2] == b"\xff\xd8"
        log_msg = next(d.decoded_message for d in decoded if d.channel.topic == "/events")
        assert log_msg.name == "start" and log_msg.level == 2


def test_frame_chunks_are_stored_uncompressed_and_read_back(tmp_path: Path) -> None:
    """JPEG and PNG gain nothing from zstd, so the chunks holding frames are written
    uncompressed and those holding samples and events with the log's compression; every
    message reads back with the ``mcap`` library and with beambench's reader."""
    import zstandard
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    rng = np.random.default_rng(12)
    frames = [
        Frame(30_000_000 * k + 11, k, _jpeg(40 + k, 48, 36), "jpeg", 48, 36) for k in range(9)
    ]
    frames.append(Frame(400_000_000, 9, _png(12, 8), "png", 12, 8))
    path = tmp_path / "run.mcap"
    _write(
        path, [_samples(0, 150, rng), _samples(150, 30, rng)], frames, [Event(3, "info", "a", "")]
    )
    with open(path, "rb") as f:
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
        f.seek(0)
        reader = make_reader(f)
        topic_of = {c.id: c.topic for c in reader.get_summary().channels.values()}  # type: ignore[union-attr]
        f.seek(0)
        images = [
            m.data
            for _, c, m in make_reader(f).iter_messages()
            if topic_of[c.id] == "/camera/image"
        ]
    assert {c.compression for c in chunks} == {"", "zstd"}
    for c in chunks:
        raw = c.data if c.compression == "" else zstandard.decompress(c.data, c.uncompressed_size)
        holds_image = b"\xff\xd8\xff" in raw or b"\x89PNG\r\n" in raw
        assert holds_image == (c.compression == ""), (c.compression, len(raw))
    assert len(images) == len(frames)
    assert list(iter_frames(path)) == frames
    assert read_run(path).samples.t_ns.size == 180


def test_topic_and_time_filters(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    path = tmp_path / "run.mcap"
    frames = [Frame(k * 66_000_000, k, _jpeg(k), "jpeg", 64, 48) for k in range(6)]
    _write(path, [_samples(0, 160, rng)], frames, [Event(3, "info", "start", "")])
    run = read_run(path, topics=["/daq/samples"], start_ns=100_000_000, end_ns=200_000_000)
    assert run.events == []
    assert run.samples.t_ns.min() >= 100_000_000 and run.samples.t_ns.max() < 200_000_000
    assert len(run.samples) == 40
    picked = [f.sequence for f in iter_frames(path, start_ns=100_000_000, end_ns=300_000_000)]
    assert picked == [2, 3, 4]
    with pytest.raises(ValueError, match="topics"):
        read_run(path, topics=["/nope"])


def test_writer_never_overwrites_and_validates(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError):
        LogWriter(path, rig_json=RIG_JSON, run_info={})
    assert path.read_bytes() == b"precious"
    with pytest.raises(ValueError, match="flush_interval_s"):
        LogWriter(tmp_path / "b.mcap", rig_json=RIG_JSON, run_info={}, flush_interval_s=2.0)
    with pytest.raises(ValueError, match="rig_json"):
        LogWriter(tmp_path / "c.mcap", rig_json="not json", run_info={})
    with pytest.raises(ValueError, match="camera_info"):
        LogWriter(tmp_path / "d.mcap", rig_json=RIG_JSON, run_info={}, camera_info={"width": 1})


def test_damaged_files_give_a_clear_error(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    path = tmp_path / "run.mcap"
    _write(path, [_samples(0, 400, rng)], [], [])
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(LogError, match=r"cut\.mcap: .*try beambench recover"):
        read_run(cut)
    with pytest.raises(LogError, match="try beambench recover"):
        list(iter_frames(cut))
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello world, not a log at all")
    with pytest.raises(LogError, match=r"junk\.mcap: not an MCAP file"):
        read_run(junk)
    with pytest.raises(LogError, match="no such file"):
        read_run(tmp_path / "missing.mcap")
    flipped = bytearray(data)
    mid = len(data) // 3
    flipped[mid : mid + 64] = bytes(64)
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(flipped))
    with pytest.raises(LogError, match=r"bad\.mcap"):
        read_run(bad)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_any_damage_is_a_log_error(tmp_path: Path, compression: str) -> None:
    """Cuts and flipped bytes anywhere: reading raises LogError and nothing else (mcap,
    lz4, protobuf, struct, overflow...), and recovery salvages or raises LogError."""
    rng = np.random.default_rng(6)
    path = tmp_path / "run.mcap"
    frames = [Frame(33_000_000 * k, k, _jpeg(k), "jpeg", 64, 48) for k in range(10)]
    events = [Event(0, "info", "start", ""), Event(500_000_000, "warning", "dropped", "x")]
    _write(
        path,
        [_samples(0, 200, rng), _samples(200, 200, rng)],
        frames,
        events,
        compression=compression,
    )
    data = path.read_bytes()
    damaged = [data[:cut] for cut in range(0, len(data), len(data) // 40)]
    for _ in range(80):
        b = bytearray(data)
        for i in rng.integers(0, len(b), size=rng.integers(1, 4)):
            b[i] = int(rng.integers(0, 256))
        damaged.append(bytes(b))
    bad = tmp_path / "bad.mcap"
    for k, content in enumerate(damaged):
        bad.write_bytes(content)
        for read in (read_run, lambda p: list(iter_frames(p)), scan_log):
            try:
                read(bad)
            except LogError as exc:
                assert str(exc).startswith(f"{bad}: ")
        try:
            recover_log(bad, tmp_path / f"fixed{k}.mcap")
        except LogError:
            pass
    text = data.replace(b'{"daq": 2000.0}', b'{"daq": 2000.0!')  # no CRC on metadata
    assert text != data
    bad.write_bytes(text)
    with pytest.raises(LogError, match="corrupt metadata"):
        read_run(bad)


def test_other_mcap_profiles_are_not_beambench_logs(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "ros.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="x")
        w.finish()
    with pytest.raises(LogError, match="not a beambench log"):
        read_run(path)


def test_opens_as_log_refuses_what_read_run_refuses_at_its_start(tmp_path: Path) -> None:
    """The quick check before a read (``process`` starts its workers only for a file that
    passes it): a whole log passes; a cut one, another file, another profile or a folder
    does not, and read_run refuses each of them too."""
    from mcap.writer import Writer

    rng = np.random.default_rng(5)
    path = tmp_path / "run.mcap"
    _write(path, [_samples(0, 400, rng)], [], [])
    assert opens_as_log(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:-40])
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello world, not a log at all")
    ros = tmp_path / "ros.mcap"
    with open(ros, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="x")
        w.finish()
    for refused in (cut, junk, ros, tmp_path / "missing.mcap", tmp_path):
        assert not opens_as_log(refused)
        with pytest.raises(LogError):
            read_run(refused)
    assert path.read_bytes() == data  # read only


def test_recover_restores_every_flushed_message_at_any_cut(tmp_path: Path) -> None:
    """Cut the file at many points; everything flushed before the cut comes back."""
    rng = np.random.default_rng(5)
    path = tmp_path / "run.mcap"
    blocks = [_samples(40 * k, 40, rng) for k in range(6)]
    flushed: list[tuple[int, int]] = []  # (file size at flush, samples flushed)
    w = LogWriter(path, rig_json=RIG_JSON, run_info={"run_id": "r"}, flush_interval_s=1.0)
    header_size = w.bytes_at_last_flush  # header, metadata: flushed on opening
    for k, b in enumerate(blocks):
        w.write_samples(b)
        w.write_frame(Frame(b.t_ns[0], k, _jpeg(k), "jpeg", 64, 48))
        w.flush()
        flushed.append((w.bytes_at_last_flush, 40 * (k + 1)))
    w.write_samples(_samples(240, 40, rng))  # never flushed: the process "dies" here
    data = path.read_bytes()
    whole = SampleBlock.concatenate(blocks)
    sizes = sorted(
        {len(data), header_size} | {s for s, _ in flushed} | set(range(200, len(data), 997))
    )
    for size in sizes:
        cut = tmp_path / f"cut{size}.mcap"
        cut.write_bytes(data[:size])
        out = tmp_path / f"fixed{size}.mcap"
        expect = max([n for s, n in flushed if s <= size], default=0)
        if size < header_size:
            # recover reads back what it wrote: a log without metadata is refused and
            # never left behind (it used to be written, and read_run then refused it)
            with pytest.raises(LogError, match=r"metadata|nothing"):
                recover_log(cut, out)
            assert not out.exists()
            continue
        try:
            summary = recover_log(cut, out)
        except LogError as exc:
            # nothing usable restored (no samples flushed yet): refused, no output
            assert expect == 0 and "nothing" in str(exc), size
            assert not out.exists()
            continue
        run = read_run(out)
        got = len(run.samples)
        # everything flushed, and possibly a chunk whose indexes were not yet written
        assert expect <= got <= expect + 40, size
        if got:
            assert got <= len(whole)
            assert run.samples == whole.slice(0, got)
            assert summary.messages_by_topic["/daq/samples"] == got
            assert expect // 40 <= run.frame_count <= got // 40
            assert run.run_info["run_id"] == "r"
        assert not summary.complete
    w.close()
    with pytest.raises(FileExistsError):
        recover_log(path, out)
    os.remove(out)
    done = recover_log(path, out)
    assert done.complete and read_run(out).samples == SampleBlock.concatenate(
        [*blocks, read_run(path).samples.slice(240, 280)]
    )


def test_recover_refuses_what_is_not_a_log(tmp_path: Path) -> None:
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00" * 100)
    with pytest.raises(LogError, match="not an MCAP file"):
        recover_log(junk, tmp_path / "out.mcap")
    assert not (tmp_path / "out.mcap").exists()


def test_each_signal_has_its_own_field_and_each_sample_its_utc_time(tmp_path: Path) -> None:
    """Plotting tools (Foxglove) take one field path per signal and show wall-clock time
    from a header stamp: /daq/samples.strain_g3 is strain[2], and header.stamp is the run's
    UTC start (start_utc + preroll_s) plus the run-clock timestamp. Added fields only."""
    path = tmp_path / "plot.mcap"
    b = _samples(0, 5, np.random.default_rng(4))
    strain = b.strain.copy()
    strain[2, 1] = np.nan  # a missing value is null in both places
    block = SampleBlock(b.t_ns, b.rocker_angle_rad, strain, b.raw_volts, 0)
    run_info = {"run_id": "abc", "start_utc": "2026-11-23T12:00:00.250000Z", "preroll_s": 0.0335}
    with LogWriter(path, rig_json=RIG_JSON, run_info=run_info) as w:
        w.write_samples(block)
    zero_ns = 1_795_435_200_250_000_000 + 33_500_000  # 2026-11-23T12:00:00.25Z + pre-roll
    with path.open("rb") as f:
        messages = [
            json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/daq/samples"])
        ]
    assert len(messages) == 5
    for k, d in enumerate(messages):
        for j in range(4):
            assert d[f"strain_g{j + 1}"] == d["strain"][j]
        t_ns = int(block.t_ns[k])
        stamp = d["header"]["stamp"]
        assert stamp["sec"] * 1_000_000_000 + stamp["nsec"] == zero_ns + t_ns
        assert d["timestamp"]["sec"] * 1_000_000_000 + d["timestamp"]["nsec"] == t_ns
    assert messages[2]["strain_g2"] is None
    run = read_run(path)
    np.testing.assert_array_equal(run.samples.strain, block.strain)  # read as before
