"""A log's summary: counts, rates, gaps and problem events of a log with known losses."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from daq.log import ChannelSummary, LogError, LogWriter, summarize_log
from daq.records import Event, Frame, SampleBlock

JPEG = bytes.fromhex("ffd8ffc0000b080030004003011100ffd9")  # SOF0 48 x 64: enough for a header
FRAME_SEQUENCES = [0, 1, 2, 5, 6, 7]  # frames 3 and 4 lost
FRAME_PERIOD_NS = 66_666_667


def _block(first: int, stop: int) -> SampleBlock:
    n = stop - first
    t_ns = np.arange(first, stop) * 2_500_000
    return SampleBlock(t_ns, np.zeros(n), np.zeros((n, 4)), np.zeros((n, 5)), first)


def _write(path: Path) -> None:
    with LogWriter(
        path,
        rig_json=json.dumps({}),
        run_info={"run_id": "r1", "backend_daq": "fake", "acquisition_rate_hz": 2000.0},
    ) as w:
        w.write_event(Event(0, "info", "start", ""))
        w.write_samples(_block(0, 200))
        w.write_samples(_block(210, 400))  # 10 samples lost
        for s in FRAME_SEQUENCES:
            w.write_frame(Frame(10_000_000 + s * FRAME_PERIOD_NS, s, JPEG, "jpeg", 64, 48))
        w.write_event(Event(500_000_000, "warning", "dropped_samples", "10 samples"))
        w.write_event(Event(510_000_000, "warning", "dropped_frames", "2 frames"))
        w.write_event(Event(1_200_000_000, "info", "stop", ""))


def test_counts_rates_gaps_and_problems_of_a_log_with_losses(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path)
    s = summarize_log(path)
    assert s.path == str(path) and s.library.startswith("beambench ")
    assert (s.run_id, s.start_utc, s.acquisition_rate_hz) == ("r1", None, 2000.0)
    assert s.backends == ("fake", None)
    assert s.size_bytes == path.stat().st_size and s.chunks >= 2
    ch = {c.topic: c for c in s.channels}
    assert [c.topic for c in s.channels] == sorted(ch)
    samples = ch["/daq/samples"]
    assert (samples.count, samples.sequence_gaps, samples.missing, samples.time_gaps) == (
        390,
        1,
        10,
        1,
    )
    assert samples.rate_hz == pytest.approx(389 / (399 * 0.0025))
    assert samples.largest_gap_s == pytest.approx(11 * 0.0025)
    frames = ch["/camera/image"]
    assert (frames.count, frames.sequence_gaps, frames.missing, frames.time_gaps) == (6, 1, 2, 1)
    assert frames.largest_gap_s == pytest.approx(3 * FRAME_PERIOD_NS * 1e-9)
    assert ch["/events"] == ChannelSummary(
        "/events", "foxglove.Log", "protobuf", 4, rate_hz=pytest.approx(3 / 1.2)
    )
    assert ch["/camera/info"] == ChannelSummary(
        "/camera/info", "foxglove.CameraCalibration", "protobuf", 0
    )
    assert s.problems == {"dropped_samples": 1, "dropped_frames": 1}
    assert s.duration_s == pytest.approx(1.2)


def test_a_damaged_log_has_no_summary(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:2000])
    with pytest.raises(LogError, match="try beambench recover"):
        summarize_log(cut)
