"""Drives: the four-bar output, the measured-trace spline and the spin-up profile."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.drives import Drive, FourBarDrive, SinusoidDrive, SpinUpDrive, TraceDrive
from sim.four_bar import FourBar


def _fd_check(drive: Drive, t: np.ndarray, rel: float) -> None:
    h = 1e-5
    rate_fd = (drive.angle(t + h) - drive.angle(t - h)) / (2 * h)
    acc_fd = (drive.rate(t + h) - drive.rate(t - h)) / (2 * h)
    assert drive.rate(t) == pytest.approx(rate_fd, rel=rel, abs=rel * np.abs(rate_fd).max())
    assert drive.accel(t) == pytest.approx(acc_fd, rel=rel, abs=rel * np.abs(acc_fd).max())


def test_four_bar_drive_is_the_rocker_about_mid_stroke() -> None:
    fb = FourBar(0.34, 0.045, 0.33, 0.065)
    d = FourBarDrive(fb, 2 * math.pi * 0.92)
    assert isinstance(d, Drive)
    t = np.linspace(0.0, 1 / 0.92, 20001)
    a = d.angle(t)
    assert a.max() == pytest.approx(-a.min(), abs=1e-7)  # symmetric about mid-stroke
    assert a.max() - a.min() == pytest.approx(fb.extrema().range_rad, abs=1e-7)
    _fd_check(d, np.linspace(0.05, 2.0, 40), 1e-6)
    absolute = FourBarDrive(fb, 2 * math.pi * 0.92, about="absolute")
    assert absolute.angle(0.0) == pytest.approx(fb.rocker_angle_rad(0.0))
    with pytest.raises(ValueError, match="about"):
        FourBarDrive(fb, 1.0, about="middle")


def test_spin_up_profile() -> None:
    d = SpinUpDrive(4.0, 15.0)
    _fd_check(d, np.linspace(0.3, 29.7, 50), 1e-6)
    assert d.rate(np.array([0.0, 15.0, 20.0])) == pytest.approx([0.0, 4.0, 4.0])
    assert d.angle(20.0) == pytest.approx(4.0 * (20.0 - 7.5))
    assert d.accel(np.array([-1.0, 0.0, 7.5, 16.0])) == pytest.approx([0.0, 0.0, 8.0 / 15.0, 0.0])
    assert SinusoidDrive().rate(0.0) == pytest.approx(0.7669 * 4.970)


def test_trace_drive_derivatives_follow_the_signal_it_sampled() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 4.0, 1.0 / 400.0)
    true = SinusoidDrive(0.7669, 4.970)
    angle = true.angle(t) + rng.normal(0.0, 2e-4, t.size)
    angle[500:520] = np.nan  # a gap
    d = TraceDrive(t, angle)
    inner = np.linspace(0.5, 3.5, 200)
    amp = 0.7669
    assert np.abs(d.angle(inner) - true.angle(inner)).max() < 1e-3 * amp
    assert np.abs(d.rate(inner) - true.rate(inner)).max() < 1e-2 * amp * 4.97
    assert np.abs(d.accel(inner) - true.accel(inner)).max() < 5e-2 * amp * 4.97**2
    # consistent: rate and accel are the spline's own derivatives
    _fd_check(d, inner, 1e-4)
    with pytest.raises(ValueError, match="t_s must lie within"):
        d.angle(5.0)


def test_trace_drive_acceleration_holds_up_to_the_ends_of_the_trace() -> None:
    # a trace cut mid-swing (3.95 s: hub acceleration ~ -17 rad/s^2): a natural smoothing
    # spline would force it to zero there and shake the simulated beam at the run's end
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 3.95, 1.0 / 400.0)
    true = SinusoidDrive(0.7669, 4.970)
    d = TraceDrive(t, true.angle(t) + rng.normal(0.0, 2e-4, t.size))
    scale = 0.7669 * 4.970**2
    ends = np.array([t[0], t[-1]])
    # one-sided there: the end cubic's truncation over 0.15 s (A w^4 T^2 / 12 ~ 0.9 rad/s^2)
    # plus three sigma of the noise (3 x 0.27 rad/s^2, over 20 seeds) is 10 % of the peak
    # (a natural spline's zero is 70 % off here)
    assert np.abs(d.accel(ends) - true.accel(ends)).max() < 0.1 * scale
