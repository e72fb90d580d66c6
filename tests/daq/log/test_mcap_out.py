"""The run log's own MCAP writer: what the ``mcap`` library reads back, byte-identical
image messages, the CRC arithmetic, and the fsync cadence."""

from __future__ import annotations

import io
import json
import os
import random
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from daq.log import LogWriter, read_run, recover_log
from daq.log import writer as writer_module
from daq.log.format import encode_image, encode_image_parts
from daq.log.mcap_out import ChunkBuffer, McapOut, crc32_combine
from daq.records import Frame, SampleBlock


def test_crc32_combine_is_the_crc_of_the_concatenation() -> None:
    rng = random.Random(7)
    for _ in range(200):
        a = rng.randbytes(rng.randrange(0, 2000))
        b = rng.randbytes(rng.choice([0, 1, 2, 7, rng.randrange(0, 70_000)]))
        assert crc32_combine(zlib.crc32(a), zlib.crc32(b), len(b)) == zlib.crc32(a + b)


@pytest.mark.parametrize("size", [0, 1, 127, 128, 16_383, 16_384, 2_097_152])
@pytest.mark.parametrize("t_ns", [0, 7, 1_000_000_000, 2**40 + 123_456_789])
def test_image_parts_are_the_protobuf_encoding(size: int, t_ns: int) -> None:
    data = np.random.default_rng(size).integers(0, 256, size, np.uint8).tobytes()
    for encoding in ("jpeg", "png"):
        parts = encode_image_parts(t_ns, data, encoding)
        assert parts[1] is data  # passed on, not copied
        joined = b"".join(parts)
        assert joined == encode_image(t_ns, data, encoding)
        msg = CompressedImage()
        msg.ParseFromString(joined)
        assert msg.data == data and msg.format == encoding
        assert msg.timestamp.seconds * 10**9 + msg.timestamp.nanos == t_ns


def test_a_file_of_its_own_reads_back_with_the_mcap_library() -> None:
    """Messages added one by one and by the block, in compressed and uncompressed
    chunks, come back from mcap's seeking and streaming readers with their CRCs checked
    and the summary's statistics and indexes right."""
    buf = io.BytesIO()
    out = McapOut(buf, profile="test-profile", library="test")
    sid = out.schema("s", "jsonschema", b"{}")
    a = out.channel("/a", "json", sid)
    b = out.channel("/b", "json", sid)
    out.metadata("m", {"k": "v"})
    sent: list[tuple[int, int, int, bytes]] = []
    for k, compression in enumerate(["zstd", "", "lz4", ""]):
        chunk = ChunkBuffer()
        times = [1000 * k + 10 * i + 3 for i in range(5)]
        data = [json.dumps({"k": k, "i": i}).encode() for i in range(5)]
        chunk.add_many(a, 5 * k, times, 99, data)
        sent += [(a, 5 * k + i, t, d) for i, (t, d) in enumerate(zip(times, data, strict=True))]
        pieces = (b"head-", os.urandom(300 + k), b"-tail")
        chunk.add(b, 2**32 + k, 1000 * k + 1, 98, pieces)  # sequence wraps at 32 bits
        sent.append((b, k, 1000 * k + 1, b"".join(pieces)))
        out.write_chunk(chunk, compression)
    out.write_chunk(ChunkBuffer(), "zstd")  # empty: nothing written
    out.finish()
    buf.seek(0)
    reader = make_reader(buf, validate_crcs=True)
    got = [
        (c.id, m.sequence, m.log_time, m.data)
        for _, c, m in reader.iter_messages(log_time_order=False)
    ]
    assert sorted(got) == sorted(sent)
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(sent)
    assert dict(summary.statistics.channel_message_counts) == {a: 20, b: 4}
    assert summary.statistics.message_start_time == 1
    assert summary.statistics.message_end_time == 3043
    assert len(summary.chunk_indexes) == 4
    assert {m.name: m.metadata for m in reader.iter_metadata()} == {"m": {"k": "v"}}
    # the streaming reader checks each chunk's CRC and the data section's
    buf.seek(0)
    records = list(StreamReader(buf, validate_crcs=True).records)
    assert sum(type(r).__name__ == "Message" for r in records) == len(sent)


def _block(first: int, n: int) -> SampleBlock:
    rng = np.random.default_rng(first)
    seq = np.arange(first, first + n)
    return SampleBlock(
        seq * 2_500_000,
        rng.normal(size=n),
        rng.normal(size=(n, 4)) * 1e-4,
        rng.normal(size=(n, 5)),
        first,
    )


def test_fsync_once_a_second_while_every_flush_reaches_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """At a 0.1 s flush the writer fsyncs every tenth flush (never more than a second
    apart) and on closing; every flush still hands its chunks to the file, so a killed
    writer's file restores every flushed sample."""
    clock = [100.0]
    syncs: list[float] = []
    monkeypatch.setattr(writer_module.time, "monotonic", lambda: clock[0])
    real_fsync = os.fsync
    monkeypatch.setattr(
        writer_module.os, "fsync", lambda fd: (syncs.append(clock[0]), real_fsync(fd))
    )
    path = tmp_path / "run.mcap"
    w = LogWriter(
        path, rig_json="{}", run_info={"run_id": "x"}, flush_interval_s=0.1, compression="zstd"
    )
    ok, buf = cv2.imencode(".jpg", np.full((8, 8, 3), 77, np.uint8))
    assert ok
    jpeg = buf.tobytes()
    flushed = []
    for k in range(35):
        clock[0] += 0.099  # flushed by the caller, a little early (maybe_flush never)
        w.write_samples(_block(40 * k, 40))
        w.write_frame(Frame(100_000_000 * k + 5, k, jpeg, "jpeg", 8, 8))
        w.flush()
        flushed.append(w.bytes_at_last_flush)
    assert w.flush_count == 36  # and the one on opening
    gaps = np.diff(syncs)
    assert len(syncs) == 4 and np.all(gaps <= 1.0 + 1e-9) and np.all(gaps >= 0.9 - 1e-9)
    w.close()
    assert len(syncs) == 5
    # had it been killed at the last flush: that much of the file (no footer) restores
    # every flushed sample
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: flushed[-1]])
    recover_log(cut, tmp_path / "fixed.mcap")
    assert read_run(tmp_path / "fixed.mcap").samples.t_ns.size == 35 * 40
    assert read_run(path).frame_count == 35
