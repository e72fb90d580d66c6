"""Capture from fakes into the MCAP log: identical records back, honest losses, errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from daq.antialias import SETTLE_REL, design_antialias
from daq.fakes import CameraFaults, DaqFaults, FakeCamera, FakeStrainDaq
from daq.log import iter_frames, read_run
from daq.records import Event, Frame, SampleBlock
from daq.replay import replay_records
from daq.stream import SampleStream
from pipelines.acquire.capture import capture_run, preroll
from pipelines.cli import main
from pipelines.errors import BeambenchError
from pipelines.rig import Rig, load_rig

RIG = load_rig()
_, _JPEG = cv2.imencode(".jpg", np.full((48, 64, 3), 128, np.uint8))
JPEG = _JPEG.tobytes()


def strain_fn(t: np.ndarray) -> np.ndarray:
    return 3e-4 * np.sin(2 * np.pi * np.outer(t, [0.92, 1.84, 3.7, 23.0]))


def angle_fn(t: np.ndarray) -> np.ndarray:
    return 1.85 + 0.77 * np.sin(2 * np.pi * 0.92 * t)


def render(t_start_s: float, exposure_s: float) -> bytes:
    return JPEG


def make_daq(rig: Rig = RIG, **kw: object) -> FakeStrainDaq:
    return FakeStrainDaq(
        rig.gauges,
        rig.potentiometer,
        rig.daq,
        strain_fn=strain_fn,
        angle_fn=angle_fn,
        strain_noise=2e-6,
        pot_noise_v=5e-4,
        seed=11,
        **kw,
    )  # type: ignore[arg-type]


def make_camera(**kw: object) -> FakeCamera:
    args: dict[str, object] = dict(
        render_fn=render,
        width_px=64,
        height_px=48,
        frame_rate_hz=15.0,
        clock_drift_ppm=20.0,
        clock_jitter_s=20e-6,
        latency_s=0.03,
        seed=5,
    )
    args.update(kw)
    return FakeCamera(**args)  # type: ignore[arg-type]


def expected_samples(n_blocks: int, rig: Rig = RIG) -> SampleBlock:
    """The 400 Hz stream computed directly from an identical fake (no log involved),
    started the capture's pre-roll before zero, from the sample at t = 0 numbered 0."""
    design = design_antialias(rig.daq, rig.daq.acquisition_rate_hz)
    preroll_ns, _ = preroll(design)
    daq = make_daq(rig)
    daq.start(first_sample_ns=-preroll_ns)
    stream = SampleStream(design, rig.gauges, rig.potentiometer)
    got = SampleBlock.concatenate([stream.process(daq.read_block(1.0)) for _ in range(n_blocks)])
    return SampleBlock(got.t_ns, got.rocker_angle_rad, got.strain, got.raw_volts, 0)


def test_capture_then_replay_gives_identical_records(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    info = {"width": 64, "height": 48, "K": [90.0, 0, 31.5, 0, 90.0, 23.5, 0, 0, 1]}
    s = capture_run(RIG, make_daq(), make_camera(), out, 2.0, realtime=False, camera_info=info)
    run = read_run(out)
    want = expected_samples(21).slice(0, 800)
    assert run.samples == want  # bit-identical, group delay already removed from times
    # the acquisition starts the filter's settling (45 ms, less its 11.5 ms of group
    # delay) before zero: the log holds duration x 400 samples from t = 0 (issue #16;
    # it used to withhold the first 18)
    assert s.samples == len(want) == 800
    np.testing.assert_array_equal(run.samples.t_ns, np.arange(800) * 2_500_000)
    cam = make_camera()
    cam.start()
    truth = [cam.read_frame(1.0) for _ in range(30)]
    assert list(iter_frames(out)) == truth
    assert [e.name for e in run.events] == ["start", "stop"]
    assert run.camera_info is not None and run.camera_info["K"][0] == 90.0
    ri = run.run_info
    assert ri["backend_daq"] == "fake" and ri["backend_camera"] == "fake"
    assert ri["acquisition_rate_hz"] == 2000.0 and ri["output_rate_hz"] == 400.0
    assert ri["filter"]["order"] == 18 and ri["filter"]["group_delay_s"] > 0
    assert ri["start_utc"].endswith("Z") and len(ri["run_id"]) == 32
    assert Rig.to_json(RIG) == run.rig_json
    # the replay iterator hands back the same records, in order
    records = list(replay_records(out))
    assert SampleBlock.concatenate([r for r in records if isinstance(r, SampleBlock)]) == want
    assert [r for r in records if isinstance(r, Frame)] == truth
    assert [r for r in records if isinstance(r, Event)] == run.events


def test_the_log_starts_settled_at_zero(tmp_path: Path) -> None:
    """The pre-roll is the filter's settling: the first samples equal those of a run
    pre-rolled a whole second longer (on the same sample grid; no noise, so that the
    two runs see the same volts), to the settling criterion: a ramp's error below
    SETTLE_REL x the group delay x its slope."""

    def quiet() -> FakeStrainDaq:
        return FakeStrainDaq(
            RIG.gauges, RIG.potentiometer, RIG.daq, strain_fn=strain_fn, angle_fn=angle_fn
        )

    out = tmp_path / "run.mcap"
    capture_run(RIG, quiet(), None, out, 0.5, realtime=False)
    run = read_run(out)
    assert len(run.samples) == 200 and run.samples.t_ns[0] == 0
    design = design_antialias(RIG.daq, 2000.0)
    preroll_ns, _ = preroll(design)
    daq = quiet()
    daq.start(first_sample_ns=-preroll_ns - 1_000_000_000)
    stream = SampleStream(design, RIG.gauges, RIG.potentiometer)
    long = SampleBlock.concatenate([stream.process(daq.read_block(1.0)) for _ in range(16)])
    long = long.slice(int(np.searchsorted(long.t_ns, 0)), len(long)).slice(0, 200)
    np.testing.assert_array_equal(run.samples.t_ns, long.t_ns)
    t = np.arange(-2000, 2000) / 2000.0
    slope_rad_s = float(np.max(np.abs(np.gradient(angle_fn(t), t))))
    bound = SETTLE_REL * design.group_delay_s * slope_rad_s
    err = np.abs(run.samples.rocker_angle_rad - long.rocker_angle_rad)
    assert err.max() <= bound
    assert err[-40:].max() < 1e-3 * bound  # long settled: the two runs agree


def test_losses_become_events_and_counts(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    daq = make_daq(faults=DaqFaults(drop_blocks=(3,), overflow_blocks=(7,)))
    cam = make_camera(faults=CameraFaults(drop_frames=(4, 5, 6)))
    s = capture_run(RIG, daq, cam, out, 1.5, realtime=False)
    run = read_run(out)
    names = [e.name for e in run.events]
    assert names.count("dropped_samples") == 2 and names.count("overrun") == 1
    # a gap mid-run restarts the filter: its settling is withheld and said so
    drop = next(e for e in run.events if e.name == "dropped_samples")
    assert drop.message.endswith("withholds its 45.0 ms of settling")
    after = run.samples.t_ns[run.samples.t_ns > drop.t_ns][0]
    assert after - drop.t_ns >= 45_000_000 - 11_507_910
    assert names.count("dropped_frames") == 1
    assert (s.dropped_samples, s.overruns, s.dropped_frames) == (400, 1, 3)
    assert s.frames == 22 - 3
    clipped = dataclasses.replace(RIG, daq=dataclasses.replace(RIG.daq, pot_range_v=2.0))
    s2 = capture_run(clipped, make_daq(clipped), None, tmp_path / "clip.mcap", 1.0, realtime=False)
    assert s2.frames == 0
    clip_events = [e for e in read_run(tmp_path / "clip.mcap").events if e.name == "clipping"]
    # one event per clipping episode: count the 0.1 s blocks where the true pot voltage
    # (noise aside) leaves the +-2 V range, and the episodes they form
    from daq.bridge import pot_volts_from_angle

    t = np.arange(2000) / 2000.0
    over = pot_volts_from_angle(angle_fn(t), RIG.potentiometer) > 2.0
    per_block = over.reshape(10, 200).any(axis=1)
    episodes = int(per_block[0]) + int(np.sum(per_block[1:] & ~per_block[:-1]))
    assert 0 < per_block.sum() < 10 and episodes == 2
    assert len(clip_events) == s2.clipping_events == episodes
    assert "potentiometer" in clip_events[0].message


def test_device_errors_end_or_degrade_the_run_cleanly(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    with pytest.raises(BeambenchError, match="FakeStrainDaq"):
        capture_run(
            RIG,
            make_daq(faults=DaqFaults(timeout_at_block=5)),
            make_camera(),
            out,
            3.0,
            realtime=False,
        )
    run = read_run(out)  # finished properly: readable without recover
    # five blocks acquired from -33.5 ms (the pre-roll): outputs up to 0.5 s less the
    # pre-roll and the 11.5 ms group delay
    assert len(run.samples) == 5 * 40 - 18
    assert [e.name for e in run.events][-2:] == ["device_error", "stop"]
    s = capture_run(
        RIG,
        make_daq(),
        make_camera(faults=CameraFaults(timeout_at_frame=3)),
        tmp_path / "cam.mcap",
        1.0,
        realtime=False,
    )
    assert s.frames == 3 and s.device_errors == 3 and s.samples == 400


def test_output_path_problems_are_clear_errors(tmp_path: Path) -> None:
    existing = tmp_path / "old.mcap"
    existing.write_bytes(b"keep me")
    with pytest.raises(BeambenchError, match="already exists"):
        capture_run(RIG, make_daq(), None, existing, 1.0, realtime=False)
    assert existing.read_bytes() == b"keep me"
    with pytest.raises(BeambenchError, match="does not exist"):
        capture_run(RIG, make_daq(), None, tmp_path / "no" / "run.mcap", 1.0, realtime=False)
    with pytest.raises(BeambenchError, match="duration"):
        capture_run(RIG, make_daq(), None, tmp_path / "x.mcap", -1.0, realtime=False)


def test_realtime_capture_keeps_up_without_drops(tmp_path: Path) -> None:
    out = tmp_path / "rt.mcap"
    s = capture_run(
        RIG, make_daq(realtime=True), make_camera(realtime=True), out, 0.6, realtime=True
    )
    assert (s.dropped_samples, s.dropped_frames, s.overruns) == (0, 0, 0)
    assert s.samples == 240 and s.frames == 9
    # paced: a realtime capture cannot finish before its duration (how fast it keeps up
    # under load is measured by `beambench bench daq`, not asserted here)
    assert s.wall_time_s > 0.55


def test_hardware_backend_without_nidaqmx_suggests_the_fake(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import importlib.util

    if importlib.util.find_spec("nidaqmx") is not None:
        pytest.skip("nidaqmx is installed")
    out = tmp_path / "hw.mcap"
    code = main(["capture", "--duration", "1", "--out", str(out), "--backend", "hardware"])
    err = capsys.readouterr().err
    assert code == 2 and "--backend fake" in err and err.count("\n") == 1
    assert not out.exists()


def test_log_passes_rerun_mcap_tools_and_images_decode(tmp_path: Path) -> None:
    """design.md: /camera/image must be decoded as an image by Rerun's MCAP importer."""
    import subprocess
    import sys

    rerun = Path(sys.executable).parent / "rerun"
    if not rerun.exists():
        pytest.skip("rerun CLI not installed next to the interpreter")
    out = tmp_path / "run.mcap"
    capture_run(RIG, make_daq(), make_camera(), out, 1.0, realtime=False)
    check = subprocess.run(
        [str(rerun), "mcap", "check", str(out)], capture_output=True, text=True, timeout=60
    )
    assert check.returncode == 0, check.stdout + check.stderr
    for topic in ("/daq/samples", "/camera/image", "/events"):
        assert any(
            line.split()[:1] == ["ok"] and topic in line for line in check.stdout.splitlines()
        ), check.stdout
    rrd = tmp_path / "run.rrd"
    subprocess.run(
        [str(rerun), "mcap", "convert", str(out), "-o", str(rrd)],
        check=True,
        capture_output=True,
        timeout=60,
    )
    printed = subprocess.run(
        [str(rerun), "rrd", "print", "-v", str(rrd)],
        check=True,
        capture_output=True,
        text=True,
        timeout=60,
    ).stdout
    assert "/camera/image@EncodedImage:blob" in printed


def test_slow_renderer_drops_frames_honestly_unless_rendered_ahead(tmp_path: Path) -> None:
    """A renderer slower than the frame period loses frames in real time (and says so);
    rendering ahead in two workers keeps up."""
    import time

    def slow(t_start_s: float, exposure_s: float) -> bytes:
        time.sleep(0.1)  # 1.5 frame periods at 15 frames/s
        return JPEG

    late = capture_run(
        RIG,
        make_daq(realtime=True),
        make_camera(render_fn=slow, realtime=True),
        tmp_path / "late.mcap",
        1.0,
        realtime=True,
    )
    assert late.dropped_frames > 0
    assert late.frames + late.dropped_frames == 15
    events = [e for e in read_run(tmp_path / "late.mcap").events if e.name == "dropped_frames"]
    assert events
    ahead = capture_run(
        RIG,
        make_daq(realtime=True),
        make_camera(render_fn=slow, realtime=True, render_workers=2),
        tmp_path / "ahead.mcap",
        1.0,
        realtime=True,
    )
    assert (ahead.frames, ahead.dropped_frames, ahead.dropped_samples) == (15, 0, 0)


def test_realtime_capture_flushes_every_flush_interval_of_data(tmp_path: Path) -> None:
    """Crash safety (issue #16): in real time the log is flushed once the data written
    since the last flush spans the flush interval (0.1 s by default, one block), so a
    kill loses at most about a block plus the filter's group delay. The DAQ runs on a
    manual clock, so the wall clock cannot cause the flushes counted here."""
    from daq.clock import ManualClock

    assert RIG.daq.flush_interval_s == 0.1 == RIG.daq.block_duration_s
    daq = FakeStrainDaq(
        RIG.gauges,
        RIG.potentiometer,
        RIG.daq,
        strain_fn=strain_fn,
        angle_fn=angle_fn,
        realtime=True,
        clock=ManualClock(),
    )
    out = tmp_path / "rt.mcap"
    s = capture_run(RIG, daq, None, out, 3.0, realtime=True)
    # one flush on opening, one per block from the second (the first block's outputs
    # span 55 ms), one at the end
    assert s.flushes >= 30
    s2 = capture_run(RIG, make_daq(), None, tmp_path / "fast.mcap", 3.0, realtime=False)
    assert s2.flushes < s.flushes  # faster than real time the wall clock decides
