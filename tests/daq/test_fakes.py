"""Fake DAQ and camera: transfer functions, noise, ADC limits, clocks and faults."""

from __future__ import annotations

import numpy as np
import pytest

from daq.bridge import angle_from_pot_volts, strain_from_bridge_volts
from daq.clock import ManualClock
from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from daq.errors import DeviceTimeoutError
from daq.fakes import CameraFaults, DaqFaults, FakeCamera, FakeStrainDaq
from daq.protocols import Camera, StrainDaq

G = GaugeConfig()
P = PotentiometerConfig()
D = DaqConfig()


def strain_fn(t: np.ndarray) -> np.ndarray:
    return 4e-4 * np.sin(2 * np.pi * np.outer(t, [0.92, 1.84, 3.7, 7.0]))


def angle_fn(t: np.ndarray) -> np.ndarray:
    return 1.85 + 0.77 * np.sin(2 * np.pi * 0.92 * t)


def _daq(**kw: object) -> FakeStrainDaq:
    return FakeStrainDaq(G, P, D, strain_fn=strain_fn, angle_fn=angle_fn, **kw)  # type: ignore[arg-type]


def _strain(volts: np.ndarray) -> np.ndarray:
    return strain_from_bridge_volts(
        volts, bridge=G.bridge, gauge_factor=G.gauge_factor, excitation_v=G.excitation_v
    )


def test_fakes_implement_the_protocols() -> None:
    assert isinstance(_daq(), StrainDaq)
    cam = FakeCamera(render_fn=lambda t, e: b"x", width_px=8, height_px=8, frame_rate_hz=10)
    assert isinstance(cam, Camera)


def test_noise_free_volts_calibrate_back_to_the_callables_within_one_lsb() -> None:
    with _daq() as daq:
        block = daq.read_block(1.0)
    assert len(block) == 200 and block.first_sequence == 0
    t_s = block.t_ns * 1e-9
    np.testing.assert_array_equal(block.t_ns, np.arange(200) * 500_000)
    lsb = daq.lsb_v
    # d(strain)/d(volt) of a quarter bridge is about 4 / (GF Vex)
    np.testing.assert_allclose(
        _strain(block.volts[:, 1:]),
        strain_fn(t_s),
        atol=lsb[1] * 4 / (G.gauge_factor * G.excitation_v),
    )
    np.testing.assert_allclose(
        angle_from_pot_volts(block.volts[:, 0], P),
        angle_fn(t_s),
        atol=lsb[0] * P.electrical_range_rad / P.supply_v,
    )
    assert block.clipped_channels == ()


def test_noise_has_the_requested_rms_and_is_reproducible() -> None:
    a = _daq(strain_noise=5e-6, pot_noise_v=1e-3, seed=3)
    b = _daq(strain_noise=5e-6, pot_noise_v=1e-3, seed=3)
    a.start()
    b.start()
    blocks = [a.read_block(1.0) for _ in range(20)]
    again = [b.read_block(1.0) for _ in range(20)]
    volts = np.concatenate([x.volts for x in blocks])
    t_s = np.concatenate([x.t_ns for x in blocks]) * 1e-9
    np.testing.assert_array_equal(volts, np.concatenate([x.volts for x in again]))
    err = _strain(volts[:, 1:]) - strain_fn(t_s)
    assert np.std(err) == pytest.approx(5e-6, rel=0.05)
    pot_err = volts[:, 0] - (angle_fn(t_s) - P.zero_angle_rad) / P.electrical_range_rad * P.supply_v
    assert np.std(pot_err) == pytest.approx(1e-3, rel=0.05)


def test_adc_quantises_and_clips_at_its_range() -> None:
    cfg = DaqConfig(adc_bits=8, pot_range_v=2.0)  # pot swings beyond 2 V: clips
    daq = FakeStrainDaq(G, P, cfg, strain_fn=lambda t: np.full((len(t), 4), 0.1), angle_fn=angle_fn)
    daq.start()
    block = daq.read_block(1.0)
    lsb = daq.lsb_v
    steps = block.volts / lsb
    np.testing.assert_allclose(steps, np.rint(steps), atol=1e-9)
    assert block.clipped_channels == (0, 1, 2, 3, 4)  # 0.1 strain saturates the bridges
    assert block.volts[:, 1:].min() == pytest.approx(-daq.range_v[1])
    assert block.volts[:, 0].max() <= 2.0


def test_timebase_gives_the_rate_the_hardware_can_do() -> None:
    daq = _daq(timebase_hz=50_000.0)
    assert daq.sample_rate_hz == 2000.0
    cfg = DaqConfig(acquisition_rate_hz=2400.0)
    odd = FakeStrainDaq(G, P, cfg, strain_fn=strain_fn, angle_fn=angle_fn, timebase_hz=50_000.0)
    assert odd.sample_rate_hz == pytest.approx(50_000.0 / 21)


def test_daq_faults_drop_overflow_and_timeout() -> None:
    daq = _daq(faults=DaqFaults(drop_blocks=(1,), overflow_blocks=(3,), timeout_at_block=6))
    daq.start()
    seqs, events = [], []
    for _ in range(4):
        b = daq.read_block(1.0)
        seqs.append(b.first_sequence)
        events.extend(b.events)
    assert seqs == [0, 400, 800, 1000]  # blocks 1 and 3 never arrive
    assert [e.name for e in events] == ["overrun"]
    assert "200 samples lost" in events[0].message
    with pytest.raises(DeviceTimeoutError, match="FakeStrainDaq"):
        daq.read_block(0.5)


def test_realtime_daq_paces_with_the_clock_and_overruns_when_late() -> None:
    clock = ManualClock()
    daq = _daq(realtime=True, clock=clock, buffer_s=0.5)
    daq.start()
    daq.read_block(1.0)
    assert clock.now_ns() == 100_000_000  # waited for the block to be acquired
    clock.advance_s(2.0)  # the reader stalls for 2 s
    b = daq.read_block(1.0)
    assert [e.name for e in b.events] == ["overrun"]
    assert b.first_sequence > 200
    # the buffered blocks follow without a gap, then the reader has caught up
    nxt = b.first_sequence + len(b)
    with pytest.raises(DeviceTimeoutError):
        for _ in range(10):
            c = daq.read_block(0.0)
            assert c.first_sequence == nxt and not c.events
            nxt += len(c)
    assert clock.now_ns() * 1e-9 >= nxt / 2000.0 - 0.1


def _camera(**kw: object) -> tuple[FakeCamera, list[float]]:
    calls: list[float] = []

    def render(t_start_s: float, exposure_s: float) -> bytes:
        calls.append(t_start_s)
        return b"\xff\xd8frame"

    args = dict(
        render_fn=render,
        width_px=64,
        height_px=48,
        frame_rate_hz=15.0,
        exposure_s=0.002,
        latency_s=0.03,
    )
    args.update(kw)
    return FakeCamera(**args), calls  # type: ignore[arg-type]


def test_camera_clock_drift_and_jitter_against_the_daq_clock() -> None:
    cam, calls = _camera(clock_drift_ppm=200.0, clock_offset_s=0.004, clock_jitter_s=50e-6, seed=2)
    cam.start()
    frames = [cam.read_frame(1.0) for _ in range(300)]
    assert all(f is not None for f in frames)
    stamps = np.array([f.t_ns for f in frames if f is not None]) * 1e-9
    true_mid = np.array(calls) + 0.001
    # stamp - true = offset + drift * t (camera clock runs fast) + jitter
    resid = stamps - true_mid
    slope, intercept = np.polyfit(true_mid, resid, 1)
    assert slope == pytest.approx(200e-6, rel=0.05)
    assert intercept == pytest.approx(0.004, abs=2e-5)
    jitter = resid - (slope * true_mid + intercept)
    assert np.std(jitter) == pytest.approx(50e-6, rel=0.15)
    assert [f.sequence for f in frames if f is not None] == list(range(300))


def test_camera_faults_and_realtime_losses() -> None:
    cam, _ = _camera(faults=CameraFaults(drop_frames=(2, 3), timeout_at_frame=6))
    cam.start()
    seqs = [f.sequence for f in (cam.read_frame(1.0) for _ in range(4)) if f is not None]
    assert seqs == [0, 1, 4, 5]
    with pytest.raises(DeviceTimeoutError, match="FakeCamera"):
        cam.read_frame(1.0)

    clock = ManualClock()
    cam, _ = _camera(realtime=True, clock=clock)
    cam.start()
    f0 = cam.read_frame(1.0)
    assert f0 is not None
    # delivered latency after the exposure ends, not before
    assert clock.now_ns() * 1e-9 == pytest.approx(0.5 / 15 + 0.002 + 0.03, abs=1e-6)
    clock.advance_s(1.0)  # a slow reader: the camera overwrote the frames in between
    f1 = cam.read_frame(1.0)
    assert f1 is not None and f1.sequence > 10


def test_rendering_ahead_in_workers_gives_the_same_frames() -> None:
    """Worker threads render ahead (exposure times are known): same frames, same order."""

    def render(t_start_s: float, exposure_s: float) -> bytes:
        return f"{t_start_s:.9f}/{exposure_s}".encode()

    kw = dict(
        render_fn=render,
        width_px=8,
        height_px=8,
        frame_rate_hz=15.0,
        clock_drift_ppm=30.0,
        faults=CameraFaults(drop_frames=(3,)),
    )
    plain = FakeCamera(**kw)  # type: ignore[arg-type]
    ahead = FakeCamera(**kw, render_workers=2)  # type: ignore[arg-type]
    with plain, ahead:
        a = [plain.read_frame(1.0) for _ in range(20)]
        b = [ahead.read_frame(1.0) for _ in range(20)]
    assert a == b
    assert ahead._pool is None  # workers shut down on stop
    with pytest.raises(ValueError, match="render_workers"):
        FakeCamera(**kw, render_workers=-1)  # type: ignore[arg-type]
