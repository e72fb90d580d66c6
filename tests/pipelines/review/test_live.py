"""The live view while capturing: it never costs the log a sample or a frame, it shows the
stream, the events and the frames it has time for, and it measures what it shows."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from daq.log import read_run
from daq.records import SampleBlock
from pipelines.acquire.capture import capture_run
from pipelines.bench.daq import _devices, synthetic_frames
from pipelines.review.live import LiveView
from pipelines.review.rrd import blueprint_views
from pipelines.review.viewer import open_viewer, rrd_entities
from pipelines.rig import load_rig


@pytest.mark.slow
def test_a_10_s_realtime_capture_with_the_view_keeps_every_sample_and_frame(
    tmp_path: Path,
) -> None:
    rig = load_rig()
    frames = synthetic_frames(rig, 6)
    daq_device, camera = _devices(rig, frames, realtime=True)
    viewer = open_viewer("beambench-test", rrd_path=tmp_path / "live.rrd", layout="live")
    live = LiveView(viewer, rig, frame_rate_hz=3.0, frame_reduction=4)
    try:
        s = capture_run(
            rig, daq_device, camera, tmp_path / "run.mcap", 10.0, realtime=True, monitor=live
        )
    finally:
        stats = live.close()
        viewer.close()
    assert (s.samples, s.frames) == (4000, 150)
    assert (s.dropped_samples, s.dropped_frames, s.overruns) == (0, 0, 0)
    run = read_run(tmp_path / "run.mcap")
    assert len(run.samples) == 4000 and run.frame_count == 150
    e = rrd_entities(tmp_path / "live.rrd")
    if stats.dropped == 0:  # the view kept up (it may not on a loaded machine: its loss)
        assert e["/daq/rocker_angle"].rows == 4000
        assert stats.frames_shown == 30  # 3 of the 15 frames a second
    assert e["/camera/image"].rows == stats.frames_shown
    assert stats.frames_measured == stats.frames_shown
    assert e["/tip_lateral/image"].rows == stats.frames_shown
    assert {v.origin for v in blueprint_views(tmp_path / "live.rrd")} >= {"/camera", "/events"}


class _SlowViewer:
    """A viewer that takes 50 ms for everything: the view falls behind."""

    def __getattr__(self, name: str) -> object:
        return lambda *args, **kwargs: time.sleep(0.05)


def test_a_view_that_falls_behind_drops_its_own_records_and_never_blocks() -> None:
    slow: Any = _SlowViewer()
    live = LiveView(slow, load_rig(), queue_size=8)
    block = SampleBlock(
        np.arange(40, dtype=np.int64) * 2_500_000,
        np.zeros(40),
        np.zeros((40, 4)),
        np.zeros((40, 5)),
        0,
    )
    t0 = time.perf_counter()
    for _ in range(200):
        live.samples(block)
    offered_s = time.perf_counter() - t0
    stats = live.close(timeout_s=5.0)
    assert offered_s < 0.5  # 200 offers while the view needs 50 ms for each it takes
    assert stats.dropped >= 150
    assert stats.sample_blocks + stats.dropped == 200


def test_the_live_recording_never_names_the_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pipelines.cli import main

    out = tmp_path / "run.mcap"
    assert main(["capture", "--duration", "1", "--out", str(out), "--rrd", str(out)]) == 2
    assert "name the same file" in capsys.readouterr().err
    assert not out.exists()
