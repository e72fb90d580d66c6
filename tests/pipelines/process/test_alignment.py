from __future__ import annotations

import numpy as np
import pytest

from pipelines.process.alignment import estimate_offset


def _rocker(t: np.ndarray) -> np.ndarray:
    # non-sinusoidal, like the crank-rocker output at 0.92 Hz
    w = 2 * np.pi * 0.92
    return 1.86 + 0.74 * np.sin(w * t) + 0.08 * np.sin(2 * w * t + 0.4)


def test_recovers_a_known_offset_and_frame_rotation() -> None:
    rng = np.random.default_rng(3)
    t_daq = np.arange(0, 20, 1 / 400)
    rocker = _rocker(t_daq) + rng.normal(0, 2e-4, t_daq.size)
    t_cam = np.arange(0.3, 19.7, 1 / 15)
    true_dt, true_c = 0.0173, np.pi - 0.02
    hub = _rocker(t_cam + true_dt) + true_c + rng.normal(0, 7e-5, t_cam.size)
    hub = (hub + np.pi) % (2 * np.pi) - np.pi  # image angles come wrapped
    hub[::17] = np.nan  # failed frames
    a = estimate_offset(t_cam, hub, t_daq, rocker)
    assert a.ok, a.reason
    # angle noise / (rms rocker rate * sqrt(frames)) ~ 1e-6 s; 2e-5 leaves room for pot noise
    assert a.offset_s == pytest.approx(true_dt, abs=2e-5)
    assert a.angle_offset_rad == pytest.approx(true_c, abs=1e-4)
    assert a.rms_residual_rad < 3e-4


def test_a_still_rocker_cannot_be_aligned() -> None:
    t = np.arange(0, 5, 1 / 400)
    a = estimate_offset(np.arange(1, 4, 0.1), np.full(30, 1.0), t, np.full(t.size, 1.0))
    assert not a.ok and "barely moved" in a.reason


def test_too_few_frames() -> None:
    t = np.arange(0, 5, 1 / 400)
    a = estimate_offset([1.0, 2.0], [0.1, 0.2], t, _rocker(t))
    assert not a.ok and "fewer than 3" in a.reason


def test_recovers_a_camera_clock_drift() -> None:
    rng = np.random.default_rng(5)
    t_daq = np.arange(0, 60, 1 / 400)
    rocker = _rocker(t_daq) + rng.normal(0, 2e-4, t_daq.size)
    t_cam = np.arange(0.3, 59.7, 1 / 15)
    true_dt, true_ppm = -0.0123, 40.0
    t_ref = 0.5 * (t_cam[0] + t_cam[-1])
    t_true = t_cam + true_dt + true_ppm * 1e-6 * (t_cam - t_ref)
    hub = _rocker(t_true) + 0.3 + rng.normal(0, 7e-5, t_cam.size)
    a = estimate_offset(t_cam, hub, t_daq, rocker)
    assert a.ok, a.reason
    # timing noise per frame ~ 7e-5 rad / 4 rad/s ~ 2e-5 s; over 900 frames spread across
    # 60 s the rate is known to ~2e-5 / (60 * sqrt(900 / 12)) ~ 0.04 ppm: 1 ppm is loose
    assert a.drift_ppm == pytest.approx(true_ppm, abs=1.0)
    assert np.max(np.abs(a.to_daq_time(t_cam) - t_true)) < 2e-5
    # without the rate the ends of the run would be off by 1.2 ms
    assert np.max(np.abs(t_cam + a.offset_s - t_true)) > 1e-3
