"""Rayleigh damping relations (Eqs. 37-39) and the log decrement."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.damping import (
    coefficients_from_damping_ratios,
    damping_ratio_from_log_decrement,
    damping_ratios_from_coefficients,
    identify_equal_coefficients,
    log_decrement,
    log_decrement_from_damping_ratio,
    modal_damping_ratio,
)


def test_eqs_37_to_39_round_trip() -> None:
    w1, w2 = 23.40, 146.6
    z1, z2 = damping_ratios_from_coefficients(0.1, 0.1, w1, w2)
    # the paper's a0 = a1 = 0.1 overdamps the first mode (zeta ~ 1.2)
    assert z1 == pytest.approx(0.1 / (2 * w1) + 0.1 * w1 / 2)
    assert z1 > 1.0
    a0, a1 = coefficients_from_damping_ratios(z1, z2, w1, w2)
    assert (a0, a1) == pytest.approx((0.1, 0.1), rel=1e-12)
    a0, a1 = coefficients_from_damping_ratios(0.02, 0.05, w1, w2)
    assert modal_damping_ratio(a0, a1, np.array([w1, w2])) == pytest.approx([0.02, 0.05], rel=1e-12)
    with pytest.raises(ValueError, match="omega1_rad_s"):
        coefficients_from_damping_ratios(0.1, 0.1, -1.0, 2.0)


def test_log_decrement_and_damping_ratio_are_inverse() -> None:
    for zeta in (0.001, 0.05, 0.5):
        assert damping_ratio_from_log_decrement(
            log_decrement_from_damping_ratio(zeta)
        ) == pytest.approx(zeta)


@pytest.mark.parametrize(("noise", "rel"), [(0.0, 1e-3), (0.01, 0.01), (0.03, 0.03)])
def test_log_decrement_of_a_noisy_offset_decay(noise: float, rel: float) -> None:
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 10.0, 1.0 / 400.0)
    zeta, w = 0.02, 2 * math.pi * 3.7
    wd = w * math.sqrt(1 - zeta**2)
    y = 0.3 + np.exp(-zeta * w * t) * np.cos(wd * t + 0.4) + rng.normal(0.0, noise, t.size)
    expected = log_decrement_from_damping_ratio(zeta)  # = zeta w * (2 pi / wd)
    assert log_decrement(t, y) == pytest.approx(expected, rel=rel)


def test_log_decrement_refuses_a_signal_without_oscillations() -> None:
    t = np.linspace(0, 1, 400)
    with pytest.raises(ValueError, match="signal"):
        log_decrement(t, np.exp(-t))


def test_identify_equal_coefficients_recovers_the_value_used() -> None:
    t = np.arange(0.0, 8.0, 1.0 / 400.0)
    w = 2 * math.pi * 3.7

    def simulate(a: float) -> tuple[np.ndarray, np.ndarray]:
        z = float(modal_damping_ratio(a, a, w))
        wd = w * math.sqrt(1 - z * z)
        return t, np.exp(-z * w * t) * np.cos(wd * t)

    target = log_decrement(*simulate(0.00087))
    assert identify_equal_coefficients(simulate, target, upper=0.01) == pytest.approx(
        0.00087, rel=1e-3
    )
