"""The crank fundamental's fit against signals of known amplitude, phase and noise:
the stated uncertainties must cover the actual errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipelines.campaign.harmonics import (
    crank_frequency,
    fit_fundamental,
    phase_lag,
    wrap_rad,
)


def _signal(t: np.ndarray, f: float, amp: float, phase: float) -> np.ndarray:
    # a fundamental plus a strong 2nd and a 3rd harmonic and an offset, like a rocker
    w = 2 * math.pi * f * t
    return (
        0.3 + amp * np.cos(w - phase) + 0.4 * amp * np.cos(2 * w + 0.7) + 0.1 * amp * np.sin(3 * w)
    )


def test_exact_signal_gives_its_amplitude_and_phase() -> None:
    t = np.linspace(1.3, 9.1, 3000)
    fit = fit_fundamental(t, _signal(t, 1.37, 0.045, 2.5), 1.37)
    assert fit.amplitude == pytest.approx(0.045, rel=1e-10)
    assert fit.phase_rad == pytest.approx(2.5, abs=1e-10)


def test_stated_uncertainty_covers_the_error() -> None:
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(1.0, 7.0, 90))  # irregular, like camera frames
    f, amp, phase, noise = 1.9, 0.02, -2.9, 4e-4
    z_amp, z_phase = [], []
    for _ in range(300):
        y = _signal(t, f, amp, phase) + rng.normal(0.0, noise, t.size)
        fit = fit_fundamental(t, y, f)
        z_amp.append((fit.amplitude - amp) / fit.amplitude_sd)
        z_phase.append(wrap_rad(fit.phase_rad - phase) / fit.phase_sd_rad)
    for z in (np.array(z_amp), np.array(z_phase)):
        # standard uncertainties: about 68 % within 1 sd, 95 % within 2 (300 trials)
        assert 0.6 < np.mean(np.abs(z) < 1) < 0.76
        assert np.mean(np.abs(z) < 2) > 0.91


def test_crank_frequency_found_with_its_uncertainty() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 8.0, 1 / 400)
    f = 1.2345
    errs = []
    for _ in range(40):
        y = _signal(t, f, 0.7, 1.0) + rng.normal(0.0, 1e-3, t.size)
        c = crank_frequency(t, y)
        errs.append((c.frequency_hz - f) / c.frequency_sd_hz)
    assert np.mean(np.abs(errs) < 2) > 0.85
    assert abs(c.frequency_hz - f) < 1e-4


def test_too_short_or_flat_gives_nan() -> None:
    t = np.linspace(0, 0.5, 100)
    assert math.isnan(crank_frequency(t, np.sin(2 * math.pi * t)).frequency_hz)
    assert math.isnan(fit_fundamental(t, np.sin(2 * math.pi * t), 1.0).amplitude)
    assert math.isnan(crank_frequency(t, np.zeros_like(t)).frequency_hz)


def test_phase_lag_wraps() -> None:
    t = np.linspace(0, 5, 2000)
    ref = fit_fundamental(t, np.cos(2 * math.pi * t - 3.0), 1.0)
    sig = fit_fundamental(t, np.cos(2 * math.pi * t + 3.0), 1.0)
    lag, _ = phase_lag(sig, ref)
    # -3 - 3 = -6 rad, wrapped into (-pi, pi]
    assert lag == pytest.approx(2 * math.pi - 6.0, abs=1e-9)
