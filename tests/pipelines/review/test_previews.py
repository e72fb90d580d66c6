"""The recording's frames made ahead, in a thread while the frames are measured: the
``.rrd`` is the one made without them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from daq.log import iter_frames
from pipelines.demo import capture_synthetic
from pipelines.process.run import process_run
from pipelines.review.overlays import FramePreviews, stream_processed
from pipelines.review.viewer import open_viewer
from pipelines.rig import load_rig
from vision.codec import preview


def _data_rows(path: Path) -> dict[tuple[str, str], list[tuple[Any, ...]]]:
    """(entity, component) -> its rows (time, frame, value), the recording's own
    properties left out."""
    out: dict[tuple[str, str], list[tuple[Any, ...]]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.entity_path.startswith("/__properties"):
            continue
        rb = chunk.to_record_batch()
        names = rb.schema.names
        times = rb.column("time").cast(pa.int64()).to_pylist() if "time" in names else None
        frames = rb.column("frame").to_pylist() if "frame" in names else None
        for name in (n for n in names if ":" in n):
            for k, v in enumerate(rb.column(name).to_pylist()):
                if v is not None:
                    row = (times[k] if times else None, frames[k] if frames else None, repr(v))
                    out.setdefault((chunk.entity_path, name), []).append(row)
    return {k: sorted(v, key=repr) for k, v in out.items()}


@pytest.mark.slow
def test_previews_made_during_the_frames_give_the_same_recording(tmp_path: Path) -> None:
    reduction = 4  # not the default 2
    log_path = tmp_path / "run.mcap"
    capture_synthetic(load_rig(), log_path, 2.0)
    previews = FramePreviews(log_path, reduction, "region").start()
    # the previews follow the measurements (most frames show only the measured region)
    processed = process_run(log_path, model="modal", workers=1, on_measured=previews.feed)
    made = dict(previews.take())
    assert previews.composer is not None and previews.composer.region_frames > 0
    frames = list(iter_frames(log_path))
    assert sorted(made) == [f.sequence for f in frames]
    image = cv2.imdecode(np.frombuffer(made[frames[0].sequence][0], np.uint8), 0)
    assert image is not None and image.shape == (
        frames[0].height_px // reduction,
        frames[0].width_px // reduction,
    )
    ahead, inline = tmp_path / "ahead.rrd", tmp_path / "inline.rrd"
    with open_viewer("beambench-test", rrd_path=ahead) as viewer:
        stream_processed(
            processed,
            log_path,
            viewer,
            frame_reduction=reduction,
            previews=previews,
            frame_previews="region",
        )
    with open_viewer("beambench-test", rrd_path=inline) as viewer:
        stream_processed(
            processed, log_path, viewer, frame_reduction=reduction, frame_previews="region"
        )
    rows = _data_rows(ahead)
    assert len(rows[("/camera/image", "EncodedImage:blob")]) == len(frames)
    assert rows == _data_rows(inline)
    # previews made at another size, or made whole, are not used (and the thread is stopped)
    for other in (
        FramePreviews(log_path, 2, "region"),
        FramePreviews(log_path, reduction, "whole"),
    ):
        other.start()
        again = tmp_path / "again.rrd"
        with open_viewer("beambench-test", rrd_path=again) as viewer:
            stream_processed(
                processed,
                log_path,
                viewer,
                frame_reduction=reduction,
                previews=other,
                frame_previews="region",
            )
        assert _data_rows(again) == rows
        again.unlink()


@pytest.mark.slow
def test_whole_previews_are_every_frame_reduced_whole(tmp_path: Path) -> None:
    log_path = tmp_path / "run.mcap"
    capture_synthetic(load_rig(), log_path, 1.0)
    previews = FramePreviews(log_path, 2, "whole").start()
    processed = process_run(log_path, model="modal", workers=1, on_measured=previews.feed)
    frames = list(iter_frames(log_path))
    made = dict(previews.take())
    assert made == {f.sequence: (preview(f.data, 2), "jpeg", 0.5) for f in frames}
    ahead, inline = tmp_path / "ahead.rrd", tmp_path / "inline.rrd"
    with open_viewer("beambench-test", rrd_path=ahead) as viewer:
        stream_processed(processed, log_path, viewer, previews=previews, frame_previews="whole")
    with open_viewer("beambench-test", rrd_path=inline) as viewer:
        stream_processed(processed, log_path, viewer, frame_previews="whole")
    rows = _data_rows(ahead)
    assert rows == _data_rows(inline)
    summary = rows[("/summary", "TextDocument:text")]
    assert "whole" not in repr(summary)
    with open_viewer("beambench-test", rrd_path=inline) as viewer:
        stream_processed(processed, log_path, viewer)  # the default: every frame whole
    assert _data_rows(inline) == rows
    with open_viewer("beambench-test", rrd_path=inline) as viewer:
        stream_processed(processed, log_path, viewer, frame_previews="region")  # says so
    assert "last whole frame" in repr(_data_rows(inline)[("/summary", "TextDocument:text")])


@pytest.mark.slow
def test_the_recording_shows_the_overlays_made_frame_by_frame(tmp_path: Path) -> None:
    """The overlays, made at once after the frames from the parts made while they were
    measured, are those of frame_overlay frame by frame at scipy's simulated shape."""
    from scipy.interpolate import CubicSpline

    from pipelines.review.overlays import frame_overlay

    log_path = tmp_path / "run.mcap"
    capture_synthetic(load_rig(), log_path, 1.0)
    previews = FramePreviews(log_path, 2, "whole").start()
    processed = process_run(log_path, model="modal", workers=1, on_measured=previews.feed)
    assert all(p is not None for p in previews.overlay_parts(processed.frames))
    streamed = tmp_path / "streamed.rrd"
    with open_viewer("beambench-test", rrd_path=streamed) as viewer:
        stream_processed(processed, log_path, viewer, previews=previews)
    ds, sim, cal = processed.results, processed.sim, processed.calibration
    lat = CubicSpline(sim.time_s, sim.station_lateral_m, axis=0)
    lon = CubicSpline(sim.time_s, sim.station_longitudinal_m, axis=0)
    logged = {f.sequence: f for f in iter_frames(log_path)}
    times, images, overlays = [], [], []
    for f, t in zip(processed.frames, ds["frame_time"].values, strict=True):
        shape = (sim.stations_m, lat(t), lon(t)) if sim.time_s[0] <= t <= sim.time_s[-1] else None
        m = f.measurement
        overlays.append(frame_overlay(m, cal.to_px, shape, cal.beam_length_m, scale=0.5))
        times.append(float(t))
        images.append(preview(logged[f.sequence].data, 2))
    assert sum(o.sim_beam_px is not None for o in overlays) > len(overlays) // 2
    reference = tmp_path / "reference.rrd"
    with open_viewer("beambench-test", rrd_path=reference) as viewer:
        viewer.log_results(ds)
        viewer.log_frames(times, images, ["jpeg"] * len(times), overlays)
        viewer.log_events(processed.events, t0_ns=int(ds.attrs["t_zero_ns"]))
    rows = _data_rows(streamed)
    assert len(rows[("/camera/image/difference", "LineStrips2D:strips")]) > 0
    assert rows == _data_rows(reference)


class _Logged:
    def __init__(self, sequence: int) -> None:
        self.sequence = sequence


def test_the_log_is_read_only_for_frames_without_a_preview(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pipelines.process.frames import MeasuredFrame
    from pipelines.review import overlays

    # the log's order (7 is in the log but was not measured)
    log_seqs = [3, 4, 7, 5, 6, 9]
    reads: list[Path] = []

    def fake_iter_frames(path: Path) -> Any:
        reads.append(path)
        return iter([_Logged(s) for s in log_seqs])

    monkeypatch.setattr(overlays, "iter_frames", fake_iter_frames)
    log_path = tmp_path / "gone.mcap"  # never opened while every frame has its preview
    measured = [MeasuredFrame(0, s, None) for s in (3, 4, 5, 6, 9)]  # type: ignore[arg-type]
    shown = (b"", "jpeg", 0.5)
    made = {s: shown for s in (3, 4, 5, 6, 9)}
    got = list(overlays._measured_in_log_order(log_path, measured, made))
    assert got == [(s, None) for s in (3, 4, 5, 6, 9)] and reads == []
    # the previews stopped before 5: the log is read from there, in its order
    made = {s: shown for s in (3, 4)}
    got = list(overlays._measured_in_log_order(log_path, measured, made))
    assert [s for s, _ in got] == [3, 4, 7, 5, 6, 9] and reads == [log_path]
    assert [f is None for _, f in got] == [True, True, False, False, False, False]
    # a repeated sequence number: the whole log, as it has them
    reads.clear()
    twice = [*measured, MeasuredFrame(1, 3, None)]  # type: ignore[arg-type]
    got = list(overlays._measured_in_log_order(log_path, twice, made))
    assert [s for s, _ in got] == log_seqs and reads == [log_path]


class _Frame:
    def __init__(self, sequence: int, data: bytes) -> None:
        self.sequence, self.data, self.encoding = sequence, data, "jpeg"


def _whole_previews_of(
    frames: list[_Frame], monkeypatch: pytest.MonkeyPatch
) -> dict[int, tuple[bytes, str, float]]:
    from pipelines.review import overlays

    monkeypatch.setattr(overlays, "iter_frames", lambda path: iter(frames))
    previews = FramePreviews(Path("never-opened.mcap"), 2, "whole").start()
    made = dict(previews.take())
    assert previews.composer is not None
    assert previews.composer.whole_frames == len(made) and previews.cpu_s > 0
    return made


def test_whole_previews_made_several_at_a_time_keep_the_logs_order_up_to_a_failure(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from pipelines.review import overlays

    rng = np.random.default_rng(5)
    images = [rng.integers(0, 256, (64, 96), dtype=np.uint8) for _ in range(12)]
    data = [bytes(cv2.imencode(".jpg", im)[1]) for im in images]
    frames = [_Frame(10 + k, d) for k, d in enumerate(data)]
    assert _whole_previews_of(frames, monkeypatch) == {
        f.sequence: (preview(f.data, 2), "jpeg", 0.5) for f in frames
    }
    # a frame that does not decode: shown without an image (None), the others as they are
    broken = [*frames[:7], _Frame(17, b"\xff\xd8 not a JPEG"), *frames[8:]]
    assert _whole_previews_of(broken, monkeypatch) == {
        f.sequence: (None if f.sequence == 17 else preview(f.data, 2), "jpeg", 0.5) for f in broken
    }
    # the budget: frames kept while those kept before are within it, as one by one
    sizes = np.cumsum([len(preview(f.data, 2)) for f in frames])
    monkeypatch.setattr(overlays, "PREVIEW_BUDGET_BYTES", int(sizes[4]))
    assert sorted(_whole_previews_of(frames, monkeypatch)) == [f.sequence for f in frames[:6]]


class _LoggedFrame:
    def __init__(self, sequence: int, t_ns: int, data: bytes) -> None:
        self.sequence, self.t_ns, self.data, self.encoding = sequence, t_ns, data, "jpeg"


@pytest.mark.parametrize("held", [None, "one"])
def test_region_previews_are_made_from_the_bytes_given_with_the_measurements(
    held: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pipelines.process.frames import MeasuredFrame
    from pipelines.review import overlays

    rng = np.random.default_rng(7)
    images = [rng.integers(0, 256, (64, 96), dtype=np.uint8) for _ in range(6)]
    logged = [
        _LoggedFrame(10 + k, 1000 * k, bytes(cv2.imencode(".jpg", im)[1]))
        for k, im in enumerate(images)
    ]
    opened: list[int | None] = []

    def fake_iter_frames(path: Path, *, start_ns: int | None = None) -> Any:
        opened.append(start_ns)
        return iter([f for f in logged if start_ns is None or f.t_ns >= start_ns])

    monkeypatch.setattr(overlays, "iter_frames", fake_iter_frames)
    if held == "one":  # the bytes held up to the budget: the first frame's only
        monkeypatch.setattr(overlays, "HELD_BYTES", len(logged[0].data))
    previews = FramePreviews(Path("never-opened.mcap"), 2, "region").start()
    # (no measurement: each is shown whole) 10-12 given with their bytes, 13-15 without
    with_bytes = [MeasuredFrame(f.t_ns, f.sequence, None, f.data) for f in logged[:3]]  # type: ignore[arg-type]
    bare = [MeasuredFrame(f.t_ns, f.sequence, None) for f in logged[3:]]  # type: ignore[arg-type]
    previews.feed(with_bytes)
    previews.feed([*with_bytes[:1], *bare])  # a frame given again is not made again
    made = dict(previews.take())
    assert made == {f.sequence: (preview(f.data, 2), "jpeg", 0.5) for f in logged}
    assert previews.composer is not None and previews.composer.whole_frames == len(logged)
    # the log read only from the first frame given without its bytes (or past the budget)
    assert opened == ([logged[3].t_ns] if held is None else [logged[1].t_ns])
