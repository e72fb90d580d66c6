"""beambench replay: a small log written with daq.log.LogWriter, streamed to a .rrd."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from daq.log import LogWriter
from daq.records import Event, Frame, SampleBlock
from pipelines.cli import main
from pipelines.commands.replay import parse_speed, replay_log
from pipelines.review.viewer import open_viewer, rrd_entities
from pipelines.rig import Rig

T0_NS = 1_000_000_000  # the run clock does not start at zero
FS_HZ = 400
N = 800  # 2 s
FRAME_SEQUENCES = [0, 1, 2, 3, 4, 6, 7, 8, 9, 10]  # frame 5 was dropped
FRAME_PERIOD_NS = 1_000_000_000 // 15


def _png(k: int) -> bytes:
    img = np.zeros((24, 32), np.uint8)
    img[:, k % 32] = 255
    return cv2.imencode(".png", img)[1].tobytes()


def _write_log(path: Path) -> None:
    t_ns = T0_NS + np.arange(N, dtype=np.int64) * (1_000_000_000 // FS_HZ)
    t = (t_ns - T0_NS) * 1e-9
    rocker = 1.8 + 0.7669 * np.sin(5.78 * t)
    strain = np.column_stack([1e-4 * np.sin(5.78 * t + k) for k in range(4)])
    volts = np.column_stack([rocker, strain * 1e3])
    with LogWriter(path, rig_json=Rig().to_json(), run_info={"run_id": "test"}) as w:
        w.write_event(Event(T0_NS - 10_000_000, "info", "start", "capture started"))
        w.write_samples(SampleBlock(t_ns[:400], rocker[:400], strain[:400], volts[:400], 0))
        for seq in FRAME_SEQUENCES:
            ft = T0_NS + 20_000_000 + seq * FRAME_PERIOD_NS
            w.write_frame(Frame(ft, seq, _png(seq), "png", 32, 24))
        w.write_event(Event(T0_NS + 400_000_000, "warning", "dropped_frames", "1 frame"))
        w.write_samples(SampleBlock(t_ns[400:], rocker[400:], strain[400:], volts[400:], 400))
        w.write_event(Event(t_ns[-1], "info", "stop", "capture stopped"))


@pytest.fixture
def run_log(tmp_path: Path) -> Path:
    path = tmp_path / "run.mcap"
    _write_log(path)
    return path


def _times_ns(path: Path, entity: str, timeline: str = "time") -> list[int]:
    out: list[int] = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == entity and timeline in chunk.timeline_names:
            out += chunk.to_record_batch().column(timeline).cast(pa.int64()).to_pylist()
    return sorted(out)


def test_replay_writes_samples_frames_and_events_on_the_run_time(
    run_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "review.rrd"
    assert main(["replay", str(run_log), "--rrd", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"replayed {N} samples, {len(FRAME_SEQUENCES)} frames and 3 events" in printed
    e = rrd_entities(out)
    assert e["/daq/rocker_angle"].rows == N
    for j in range(1, 5):
        assert e[f"/daq/strain/g{j}"].rows == N
    assert e["/camera/image"].rows == len(FRAME_SEQUENCES)
    assert e["/events"].rows == 3
    # Raw replay: no overlays, no simulation.
    assert not [k for k in e if k.startswith(("/camera/image/", "/sim", "/fig11"))]
    # Seconds since the first DAQ sample; the camera's own frame counter on "frame".
    assert _times_ns(out, "/daq/rocker_angle")[:3] == [0, 2_500_000, 5_000_000]
    assert _times_ns(out, "/camera/image", "frame") == FRAME_SEQUENCES
    assert _times_ns(out, "/camera/image") == [
        20_000_000 + s * FRAME_PERIOD_NS for s in FRAME_SEQUENCES
    ]
    assert _times_ns(out, "/events") == [-10_000_000, 400_000_000, (N - 1) * 2_500_000]


def test_replay_without_destination_saves_beside_the_log(run_log: Path) -> None:
    assert main(["replay", str(run_log)]) == 0
    assert rrd_entities(run_log.with_suffix(".rrd"))["/daq/rocker_angle"].rows == N


def test_paced_replay_takes_the_run_time_over_speed_and_sends_the_same(
    run_log: Path, tmp_path: Path
) -> None:
    now = [0.0]
    sleeps: list[float] = []

    def sleep(s: float) -> None:
        sleeps.append(s)
        now[0] += s

    out = tmp_path / "paced.rrd"
    with open_viewer("beambench-test", rrd_path=out) as viewer:
        summary = replay_log(run_log, viewer, speed=2.0, sleep=sleep, monotonic=lambda: now[0])
    duration_s = (N - 1) / FS_HZ
    assert summary.samples == N and summary.frames == len(FRAME_SEQUENCES)
    # Paced in 0.1 s steps of run time: about duration / speed of waiting in total.
    assert sum(sleeps) == pytest.approx(duration_s / 2.0, abs=0.1 / 2.0)
    assert len(sleeps) >= 15
    e = rrd_entities(out)
    assert e["/daq/rocker_angle"].rows == N
    assert e["/camera/image"].rows == len(FRAME_SEQUENCES)
    assert e["/events"].rows == 3
    assert _times_ns(out, "/daq/strain/g3") == [i * 2_500_000 for i in range(N)]


def test_bad_input_is_one_error_line_and_keeps_the_old_recording(
    tmp_path: Path, run_log: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "keep.rrd"
    out.write_bytes(b"previous recording")
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(run_log.read_bytes()[:300])
    cases = [
        ([str(tmp_path / "missing.mcap"), "--rrd", str(out)], "missing.mcap"),
        ([str(broken), "--rrd", str(out)], "broken.mcap"),
        ([str(run_log), "--speed", "fast", "--rrd", str(out)], "--speed"),
        ([str(run_log), "--speed", "-1", "--rrd", str(out)], "--speed"),
        ([str(run_log), "--rrd", str(tmp_path / "run.mcap")], ".rrd"),
        ([str(run_log), "--rrd", str(tmp_path / "no" / "x.rrd")], "does not exist"),
        ([str(run_log), "--connect", "localhost:9876"], "rerun+http://"),
    ]
    for argv, needle in cases:
        assert main(["replay", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1, err
        assert needle in err, (needle, err)
    assert out.read_bytes() == b"previous recording"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "broken.mcap",
        "keep.rrd",
        "run.mcap",
    ]


def test_parse_speed() -> None:
    assert parse_speed("max") is None
    assert parse_speed("MAX") is None
    assert parse_speed("0.5") == 0.5
    for bad in ("0", "nan", "inf", "x"):
        with pytest.raises(Exception, match="--speed"):
            parse_speed(bad)


def test_replay_of_a_daq_only_log(tmp_path: Path) -> None:
    path = tmp_path / "daq_only.mcap"
    t_ns = np.arange(40, dtype=np.int64) * 2_500_000
    zeros = np.zeros(40)
    with LogWriter(path, rig_json=Rig().to_json(), run_info={"run_id": "daq"}) as w:
        w.write_samples(
            SampleBlock(t_ns, zeros, np.zeros((40, 4)), np.zeros((40, 5)), first_sequence=0)
        )
    out = tmp_path / "daq_only.rrd"
    with open_viewer("beambench-test", rrd_path=out) as viewer:
        summary = replay_log(path, viewer, speed=100.0, sleep=lambda s: None)
    assert (summary.samples, summary.frames, summary.events) == (40, 0, 0)
    e = rrd_entities(out)
    assert e["/daq/rocker_angle"].rows == 40
    assert "/camera/image" not in e and "/events" not in e


def test_the_replay_layout_has_no_empty_panel(run_log: Path, tmp_path: Path) -> None:
    """A raw log has no simulation, no tip and no Fig. 11: its layout shows none of them,
    and every panel it has shows something that was logged."""
    from pipelines.review.rrd import blueprint_views

    out = tmp_path / "raw.rrd"
    assert main(["replay", str(run_log), "--rrd", str(out)]) == 0
    logged = [k for k in rrd_entities(out) if not k.startswith("/__")]
    views = blueprint_views(out)
    assert views
    for v in views:
        assert any(v.shows(e) for e in logged), f"empty panel: {v}"
    assert not any(v.origin == "/fig11" for v in views)


def test_frames_can_be_replayed_reduced_or_as_logged(run_log: Path, tmp_path: Path) -> None:
    small, full = tmp_path / "small.rrd", tmp_path / "full.rrd"
    assert main(["replay", str(run_log), "--rrd", str(small), "--frame-reduction", "2"]) == 0
    assert main(["replay", str(run_log), "--rrd", str(full), "--frame-reduction", "1"]) == 0
    sizes = []
    for path in (small, full):
        for chunk in RrdReader(path).stream():
            if chunk.entity_path == "/camera/image":
                rb = chunk.to_record_batch()
                if "EncodedImage:blob" in rb.schema.names:
                    blob = rb.column("EncodedImage:blob").to_pylist()[0][0]
                    img = cv2.imdecode(np.frombuffer(bytes(blob), np.uint8), cv2.IMREAD_GRAYSCALE)
                    sizes.append(img.shape)
                    break
    (h_small, w_small), (h_full, w_full) = sizes
    assert (2 * h_small, 2 * w_small) == (h_full, w_full)
