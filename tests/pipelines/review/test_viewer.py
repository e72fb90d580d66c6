"""Rerun review: write a .rrd from known arrays and frames, read it back, check it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from pipelines.results.compare import summarise_errors
from pipelines.results.dataset import make_results
from pipelines.review.rrd import blueprint_views
from pipelines.review.viewer import FrameOverlay, OverlayColumns, open_viewer, rrd_entities
from pipelines.rig import Rig

FS_HZ = 400.0


@dataclass(frozen=True)
class Event:
    """The shape of daq.log's Event (duck-typed by the viewer)."""

    t_ns: int
    level: Any
    name: str
    message: str


def _png(width: int = 64, height: int = 48) -> bytes:
    img = np.zeros((height, width, 3), np.uint8)
    cv2.line(img, (5, 40), (60, 8), (255, 255, 255), 2)
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return buf.tobytes()


def _rows(path: Path, entity: str, component: str) -> list[tuple[int | None, Any]]:
    """(time in ns or None for static, value) of every row of ``entity`` holding ``component``."""
    out: list[tuple[int | None, Any]] = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity:
            continue
        rb = chunk.to_record_batch()
        if component not in rb.schema.names:
            continue
        values = rb.column(component).to_pylist()
        if "time" in rb.schema.names:
            times = rb.column("time").cast(pa.int64()).to_pylist()
        else:
            times = [None] * len(values)
        out.extend(zip(times, values, strict=True))
    return sorted(out, key=lambda r: -1 if r[0] is None else r[0])


def test_samples_and_sim_go_in_as_columns_with_exact_times(tmp_path: Path) -> None:
    n = 1000
    t = np.arange(n) / FS_HZ
    rocker = 0.7669 * np.sin(4.97 * t)
    strain = np.column_stack([1e-4 * np.cos(4.97 * t + k) for k in range(4)])
    strain[10, 2] = np.nan  # a missing sample is skipped, not drawn as a value
    path = tmp_path / "run.rrd"
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_samples(t, rocker, strain)
        viewer.log_sim(t, 0.02 * np.sin(4.97 * t), 0.5 * strain)
    entities = rrd_entities(path)
    assert entities["/daq/rocker_angle"].rows == n
    assert entities["/daq/strain/g3"].rows == n - 1
    assert entities["/sim/strain/g4"].rows == n
    assert entities["/sim/tip_lateral"].rows == n
    assert "Scalars:scalars" in entities["/daq/strain/g1"].components
    rows = _rows(path, "/daq/rocker_angle", "Scalars:scalars")
    times = np.array([r[0] for r in rows])
    np.testing.assert_array_equal(times, np.round(t * 1e9).astype(np.int64))
    # shown in degrees and microstrain (the results keep SI)
    np.testing.assert_allclose([r[1][0] for r in rows], np.degrees(rocker), rtol=1e-14)
    g2 = _rows(path, "/sim/strain/g2", "Scalars:scalars")
    np.testing.assert_allclose([r[1][0] for r in g2], 1e6 * 0.5 * strain[:, 1], rtol=1e-14)
    tip = _rows(path, "/sim/tip_lateral", "Scalars:scalars")
    np.testing.assert_allclose([r[1][0] for r in tip], 20.0 * np.sin(4.97 * t), atol=1e-12)
    # A blueprint travels with the recording.
    assert RrdReader(path).blueprints()


def test_frames_keep_their_bytes_and_overlays_draw_on_the_image(tmp_path: Path) -> None:
    png = _png()
    jpeg = cv2.imencode(".jpg", np.full((48, 64, 3), 128, np.uint8))[1].tobytes()
    centre = np.array([[5.0, 40.0], [30.0, 25.0], [60.0, 8.0]])
    overlay = FrameOverlay(
        centreline_px=centre,
        hub_line_px=[[5.0, 40.0], [12.0, 36.0]],
        rigid_line_px=[[5.0, 40.0], [62.0, 10.0]],
        sim_beam_px=centre + 0.5,
        difference_px=centre + 2.0,
        tip_px=[60.0, 8.0],
        ok=True,
    )
    path = tmp_path / "frames.rrd"
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_frame(0.1, png, "png", overlay)
        viewer.log_frame(0.2, jpeg, "JPEG", FrameOverlay(ok=False, reason="beam not found"))
        viewer.log_frame(0.3, png, "png", None)
    entities = rrd_entities(path)
    image = entities["/camera/image"]
    assert image.rows == 3
    assert {"time", "frame"} <= image.timelines
    blobs = _rows(path, "/camera/image", "EncodedImage:blob")
    assert [bytes(b[1][0]) for b in blobs] == [png, jpeg, png]
    media = _rows(path, "/camera/image", "EncodedImage:media_type")
    assert [m[1][0] for m in media] == ["image/png", "image/jpeg", "image/png"]
    strips = _rows(path, "/camera/image/centreline", "LineStrips2D:strips")
    assert len(strips) == 1 and strips[0][0] == 100_000_000
    np.testing.assert_allclose(np.array(strips[0][1][0]), centre)
    tip = _rows(path, "/camera/image/tip", "Points2D:positions")
    np.testing.assert_allclose(tip[0][1], [[60.0, 8.0]])
    diff = _rows(path, "/camera/image/difference", "LineStrips2D:strips")
    np.testing.assert_allclose(np.array(diff[0][1][0]), centre + 2.0)
    dots = _rows(path, "/camera/image/sim_stations", "Points2D:positions")
    np.testing.assert_allclose(np.array(dots[0][1]), centre + 0.5)
    # The failed frame clears the previous overlays so nothing stale is drawn over it.
    for name in (
        "centreline",
        "hub_line",
        "rigid_line",
        "sim_beam",
        "sim_stations",
        "difference",
        "tip",
    ):
        cleared = _rows(path, f"/camera/image/{name}", "Clear:is_recursive")
        assert [c[0] for c in cleared] == [200_000_000], name
    reasons = _rows(path, "/events/frames", "TextLog:text")
    assert len(reasons) == 1 and "beam not found" in reasons[0][1][0]
    frames = [r[0] for r in _rows(path, "/camera/image", "EncodedImage:blob")]
    assert frames == [100_000_000, 200_000_000, 300_000_000]


def test_events_tip_deflection_and_fig11(tmp_path: Path) -> None:
    events = [
        Event(t_ns=5_000_000_000, level=2, name="start", message="capture started"),
        Event(t_ns=5_250_000_000, level="warning", name="dropped_frames", message="2 frames"),
        Event(t_ns=6_000_000_000, level=4, name="device_error", message="timeout"),
    ]
    path = tmp_path / "ev.rrd"
    t = np.arange(400) / FS_HZ
    ft = np.array([0.1, 0.2, 0.3])
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_events(events, t0_ns=5_000_000_000)
        viewer.log_tip_deflection(ft, [0.01, np.nan, 0.012], t, 0.01 * np.ones(400))
        viewer.log_fig11(
            np.radians([10.0, -20.0]),
            [0.005, -0.004],
            np.radians(np.linspace(-40, 40, 30)),
            np.linspace(-0.02, 0.02, 30),
        )
    texts = _rows(path, "/events", "TextLog:text")
    levels = _rows(path, "/events", "TextLog:level")
    assert [r[0] for r in texts] == [0, 250_000_000, 1_000_000_000]
    assert [r[1][0] for r in levels] == ["INFO", "WARN", "ERROR"]
    assert texts[1][1][0] == "dropped_frames: 2 frames"
    assert rrd_entities(path)["/tip_lateral/image"].rows == 2  # the NaN frame is skipped
    measured = _rows(path, "/fig11/measured", "Points2D:positions")
    assert measured[0][0] is None  # static: the figure, not a moment of the run
    # Degrees across, millimetres up (the 2D view's y points down, hence the sign).
    np.testing.assert_allclose(measured[0][1], [[10.0, -5.0], [-20.0, 4.0]], rtol=1e-6)
    loop = _rows(path, "/fig11/sim", "LineStrips2D:strips")
    assert np.array(loop[0][1][0]).shape == (30, 2)


def _results() -> Any:
    t = np.arange(0, 8.0, 1 / FS_HZ)
    omega = 2 * np.pi * 0.92
    rocker = 0.7669 * np.sin(omega * t)
    tip = 0.02 * np.sin(omega * t - 0.5)
    idx = np.arange(0, t.size, 27)
    ok = np.ones(idx.size, dtype=bool)
    ok[4] = False
    strain = 3e-4 * np.outer(np.sin(omega * t), [1.0, 0.7, 0.45, 0.2])
    return make_results(
        time_s=t,
        rocker_angle_rad=rocker,
        strain=strain,
        gauge_m=[0.005, 0.204, 0.403, 0.603],
        frame_time_s=t[idx],
        hub_angle_image_rad=rocker[idx],
        tip_lateral_m=tip[idx] + 1e-4,
        tip_longitudinal_m=np.zeros(idx.size),
        frame_ok=ok,
        tip_lateral_strain_m=tip * 1.01,
        sim_tip_lateral_m=tip,
        sim_strain=strain,
        attrs={
            "source_log": "run.mcap",
            "rig_json": Rig().to_json(),
            "software_version": "test",
            "sim_model": "modal",
            "sim_settings": {},
            "camera_to_daq_offset_s": 0.0,
            "settle_time_s": 2.0,
        },
    )


def test_log_results_shows_everything_in_the_results(tmp_path: Path) -> None:
    ds = _results()
    path = tmp_path / "results.rrd"
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_results(ds)
    e = rrd_entities(path)
    n = ds.sizes["time"]
    for entity in ("/daq/rocker_angle", "/daq/strain/g4", "/sim/strain/g1", "/sim/tip_lateral"):
        assert e[entity].rows == n, entity
    assert e["/tip_lateral/strain"].rows == n
    assert e["/tip_lateral/image"].rows == int(ds["frame_ok"].sum())
    # Fig. 11: the simulated loop of the last three crank cycles (0.92 Hz: 3.26 s) under
    # the frames measured after the simulation's start-up (settle_time_s).
    ft = ds["frame_time"].values
    expected = int(np.sum(ds["frame_ok"].values & (ft >= 2.0)))
    measured = _rows(path, "/fig11/measured", "Points2D:positions")
    assert len(measured[0][1]) == expected
    assert 0 < expected < int(ds["frame_ok"].sum())
    loop = np.array(_rows(path, "/fig11/sim", "LineStrips2D:strips")[0][1][0])
    t = ds["time"].values
    assert loop.shape[0] == np.count_nonzero(t >= t[-1] - 3 / 0.92)
    # Fig. 11's marker: one point per measured frame, on the time line, moving along the loop
    assert e["/fig11/now"].rows == int(ds["frame_ok"].sum())
    assert {"ticks", "axes"} <= {k.split("/")[-1] for k in e if k.startswith("/fig11/")}
    # The layout shown is the one sent with the data: Fig. 11's view bounds fit the loop
    assert len(RrdReader(path).blueprints()) >= 1
    # The error summary travels as a markdown document, in mm.
    doc = _rows(path, "/summary", "TextDocument:text")[0][1][0]
    rms_mm = 1e3 * summarise_errors(ds)["tip_lateral_image_vs_sim_rms_m"]
    assert rms_mm == pytest.approx(0.1, rel=1e-6)  # the image was offset by 0.1 mm
    # RMS and max side by side, so the table is read without scrolling
    assert "| tip lateral, image - sim | 0.1 | 0.1 | mm |" in doc


def test_rrd_is_replaced_only_when_the_run_succeeds(tmp_path: Path) -> None:
    path = tmp_path / "keep.rrd"
    path.write_bytes(b"previous recording")
    with pytest.raises(RuntimeError, match="processing failed"):
        with open_viewer("beambench-test", rrd_path=path) as viewer:
            viewer.log_samples(np.arange(3.0), np.zeros(3), np.zeros((3, 4)))
            raise RuntimeError("processing failed")
    assert path.read_bytes() == b"previous recording"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.rrd"]
    viewer = open_viewer("beambench-test", rrd_path=path)
    viewer.log_samples(np.arange(3.0), np.zeros(3), np.zeros((3, 4)))
    assert viewer.close() == path
    assert rrd_entities(path)["/daq/rocker_angle"].rows == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.rrd"]


def test_bad_arguments_name_the_parameter(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="exactly one destination"):
        open_viewer("x")
    with pytest.raises(ValueError, match="exactly one destination"):
        open_viewer("x", rrd_path=tmp_path / "a.rrd", connect_url="rerun+http://h:1/proxy")
    with pytest.raises(ValueError, match="does not exist"):
        open_viewer("x", rrd_path=tmp_path / "nope" / "a.rrd")
    with pytest.raises(ValueError, match="connect_url"):
        open_viewer("x", connect_url="localhost:9876")
    with open_viewer("x", rrd_path=tmp_path / "a.rrd") as viewer:
        with pytest.raises(ValueError, match="encoding"):
            viewer.log_frame(0.0, _png(), "bmp", None)
        with pytest.raises(ValueError, match="hub_line_px"):
            viewer.log_frame(0.0, _png(), "png", FrameOverlay(hub_line_px=[[0, 0], [1, 1], [2, 2]]))
        with pytest.raises(ValueError, match="strain"):
            viewer.log_samples(np.arange(3.0), np.zeros(3), np.zeros((2, 4)))
    with pytest.raises(FileNotFoundError):
        rrd_entities(tmp_path / "missing.rrd")
    junk = tmp_path / "junk.rrd"
    junk.write_bytes(b"not a recording")
    with pytest.raises(ValueError, match=r"junk\.rrd"):
        rrd_entities(junk)


def test_the_blueprint_lays_out_every_logged_entity(tmp_path: Path) -> None:
    path = tmp_path / "full.rrd"
    overlay = FrameOverlay(
        centreline_px=[[1.0, 2.0], [3.0, 4.0]],
        hub_line_px=[[1.0, 2.0], [2.0, 3.0]],
        rigid_line_px=[[1.0, 2.0], [5.0, 6.0]],
        sim_beam_px=[[1.0, 2.0], [3.0, 4.5]],
        tip_px=[3.0, 4.0],
    )
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_results(_results())
        viewer.log_frame(0.5, _png(), "png", overlay)
        viewer.log_frame(0.6, _png(), "png", FrameOverlay(ok=False, reason="blurred"))
        viewer.log_events([Event(0, 2, "start", "")])
    views = [(v.kind, v.origin, list(v.queries)) for v in blueprint_views(path)]
    classes = sorted(c for c, _, _ in views)
    # camera, Fig. 11; summary, events; rocker, 4 x (strain, residual), tip, tip residual
    assert classes == ["2D", "2D", "TextDocument", "TextLog"] + ["TimeSeries"] * 11
    assert {o for c, o, _ in views if c == "2D"} == {"/camera", "/fig11"}
    logged = [k for k in rrd_entities(path) if not k.startswith("/__")]
    # 5 daq, 5 sim, 2 tip, 6 residuals, image + 7 overlays, 5 fig11, 3 text
    assert len(logged) == 34
    orphans = [e for e in logged if not any(v.shows(e) for v in blueprint_views(path))]
    assert not orphans, f"logged but in no view: {orphans}"
    # Each gauge's panel shows its measured and simulated strain together.
    strain_panels = [qs for c, _, qs in views if c == "TimeSeries" and "/daq/strain/g2" in qs]
    assert strain_panels == [["/daq/strain/g2", "/sim/strain/g2"]]


def _all_rows(path: Path) -> dict[tuple[str, str], list[tuple[Any, ...]]]:
    """Every (entity, component) of a recording's data: its rows as (time, frame, value),
    sorted; the blueprint and the recording's properties left out."""
    out: dict[tuple[str, str], list[tuple[Any, ...]]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.entity_path.startswith("/__properties"):
            continue
        rb = chunk.to_record_batch()
        names = rb.schema.names
        times = rb.column("time").cast(pa.int64()).to_pylist() if "time" in names else None
        frames = rb.column("frame").to_pylist() if "frame" in names else None
        for name in names:
            if ":" not in name:
                continue
            values = rb.column(name).to_pylist()
            for k, v in enumerate(values):
                if v is None:
                    continue
                key = (times[k] if times else None, frames[k] if frames else None, repr(v))
                out.setdefault((chunk.entity_path, name), []).append(key)
    return {k: sorted(v, key=repr) for k, v in out.items()}


def test_frames_sent_as_columns_are_the_frames_logged_one_by_one(tmp_path: Path) -> None:
    """``log_frames`` (the processed run's path) writes what ``log_frame`` per frame
    writes: the same entities, components, times, frame numbers and values, with
    overlays, failed frames (clearing and a reason), frames without overlays, and
    overlays with some parts missing."""
    rng = np.random.default_rng(3)
    jpeg = cv2.imencode(".jpg", rng.integers(0, 255, (36, 52, 3), np.uint8))[1].tobytes()
    png = _png(30, 20)

    def full(k: int) -> FrameOverlay:
        centre = rng.uniform(0, 50, (5 + k, 2))
        return FrameOverlay(
            centreline_px=centre,
            hub_line_px=rng.uniform(0, 50, (2, 2)),
            rigid_line_px=rng.uniform(0, 50, (2, 2)),
            sim_beam_px=centre + 0.25,
            difference_px=centre - 1.5,
            tip_px=rng.uniform(0, 50, 2),
            ok=True,
        )

    frames: list[tuple[float, bytes, str, FrameOverlay | None]] = [
        (0.0125, jpeg, "jpeg", full(0)),
        (0.0791, png, "PNG", FrameOverlay(ok=False, reason="beam not found")),
        (0.1457, jpeg, "jpeg", None),
        (0.2123, jpeg, "jpeg", full(3)),
        (0.2789, png, "png", FrameOverlay(ok=False, reason="")),
        (0.3455, jpeg, "jpeg", FrameOverlay(centreline_px=[[1.0, 2.0], [3.0, 4.0]], ok=True)),
        (0.4121, jpeg, "jpeg", full(1)),
    ]
    one = tmp_path / "one.rrd"
    with open_viewer("beambench-test", rrd_path=one) as viewer:
        for t, d, e, o in frames:
            viewer.log_frame(t, d, e, o)
    columns = tmp_path / "columns.rrd"
    with open_viewer("beambench-test", rrd_path=columns) as viewer:
        viewer.log_frames(
            [f[0] for f in frames], [f[1] for f in frames], [f[2] for f in frames],
            [f[3] for f in frames],
        )  # fmt: skip
    expected = _all_rows(one)
    assert ("/camera/image/sim_stations", "Points2D:positions") in expected
    assert ("/events/frames", "TextLog:text") in expected
    assert _all_rows(columns) == expected
    # the frames first, a few at a time, and then all their overlays, as columns
    split = tmp_path / "split.rrd"
    with open_viewer("beambench-test", rrd_path=split) as viewer:
        first = viewer.frame_index
        for k in range(0, len(frames), 3):
            part = frames[k : k + 3]
            viewer.log_frames([f[0] for f in part], [f[1] for f in part], [f[2] for f in part])
        overlays = OverlayColumns.from_overlays([f[3] for f in frames])
        viewer.log_frame_overlays([f[0] for f in frames], overlays, first_index=first)
    assert _all_rows(split) == expected


def test_a_frame_that_did_not_decode_is_logged_without_an_image(tmp_path: Path) -> None:
    # its time has no image, and the image is cleared there: the frame before it is not
    # shown in its place
    path = tmp_path / "frames.rrd"
    t = [0.0, 0.1, 0.2]
    with open_viewer("beambench-test", rrd_path=path) as viewer:
        viewer.log_frames(t, [_png(), None, _png()], ["png", "png", "png"])
        assert viewer.frame_index == 3
    blobs = _rows(path, "/camera/image", "EncodedImage:blob")
    assert [r[0] for r in blobs] == [0, 200_000_000]
    cleared = _rows(path, "/camera/image", "Clear:is_recursive")
    assert [r[0] for r in cleared] == [100_000_000]
    with open_viewer("beambench-test", rrd_path=tmp_path / "bad.rrd") as viewer:
        with pytest.raises(TypeError, match="bytes or None"):
            viewer.log_frames([0.0], ["not bytes"], ["png"])  # type: ignore[list-item]
