"""Bridge and potentiometer calibration against the Wheatstone divider, in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daq.bridge import (
    angle_from_pot_volts,
    bridge_volts_from_strain,
    pot_volts_from_angle,
    strain_from_bridge_volts,
)
from daq.config import PotentiometerConfig

GF = 2.1
VEX = 5.0
R = 120.0
STRAINS = np.array([-5e-3, -1e-3, -1e-5, 0.0, 2e-6, 1e-3, 5e-3])


def _divider(top: np.ndarray, bottom: np.ndarray) -> np.ndarray:
    return bottom / (top + bottom)


def _wheatstone(strain: np.ndarray, bridge: str) -> np.ndarray:
    """Vout = V(left midpoint) - V(right midpoint) from the four arm resistances, with
    the gauges wired as NI's quarter I / half II / full I (tension gives negative Vout)."""
    up = R * (1 + GF * strain)  # gauge in tension
    down = R * (1 - GF * strain)  # gauge in compression (opposite face)
    fixed = np.full_like(strain, R)
    if bridge == "quarter":
        left = _divider(up, fixed)
        right = _divider(fixed, fixed)
    elif bridge == "half":
        left = _divider(up, down)
        right = _divider(fixed, fixed)
    else:
        left = _divider(up, down)
        right = _divider(down, up)
    return VEX * (left - right)


@pytest.mark.parametrize("bridge", ["quarter", "half", "full"])
def test_bridge_volts_match_the_wheatstone_divider(bridge: str) -> None:
    got = bridge_volts_from_strain(STRAINS, bridge=bridge, gauge_factor=GF, excitation_v=VEX)
    np.testing.assert_allclose(got, _wheatstone(STRAINS, bridge), rtol=1e-9, atol=1e-15 * VEX)


@pytest.mark.parametrize("bridge", ["quarter", "half", "full"])
def test_strain_from_volts_inverts_exactly(bridge: str) -> None:
    volts = _wheatstone(STRAINS, bridge)
    back = strain_from_bridge_volts(volts, bridge=bridge, gauge_factor=GF, excitation_v=VEX)
    np.testing.assert_allclose(back, STRAINS, rtol=1e-9, atol=1e-15)


def test_quarter_bridge_nonlinearity_is_corrected() -> None:
    """The linear reading -4 Vr / GF is off by about GF e / 2 (0.1 % at 1000 ue);
    the exact inverse is not."""
    e = 1e-3
    v = _wheatstone(np.array([e]), "quarter")[0]
    linear = -4 * v / VEX / GF
    assert abs(linear / e - 1) == pytest.approx(GF * e / 2, rel=2e-3)
    exact = strain_from_bridge_volts(v, bridge="quarter", gauge_factor=GF, excitation_v=VEX)
    assert exact == pytest.approx(e, rel=1e-12)


def test_potentiometer_calibration_endpoints_and_round_trip() -> None:
    pot = PotentiometerConfig(
        supply_v=5.0, electrical_range_rad=math.radians(340.0), zero_angle_rad=-1.0
    )
    assert angle_from_pot_volts(0.0, pot) == pytest.approx(-1.0)
    assert angle_from_pot_volts(5.0, pot) == pytest.approx(-1.0 + math.radians(340.0))
    assert angle_from_pot_volts(2.5, pot) == pytest.approx(-1.0 + math.radians(170.0))
    angles = np.linspace(0.5, 2.7, 50)
    np.testing.assert_allclose(
        angle_from_pot_volts(pot_volts_from_angle(angles, pot), pot), angles, rtol=0, atol=1e-14
    )


def test_bad_bridge_arguments_name_the_parameter() -> None:
    with pytest.raises(ValueError, match="bridge"):
        bridge_volts_from_strain(0.0, bridge="double", gauge_factor=2, excitation_v=5)
    with pytest.raises(ValueError, match="gauge_factor"):
        strain_from_bridge_volts(0.0, bridge="quarter", gauge_factor=0, excitation_v=5)
    with pytest.raises(ValueError, match="excitation_v"):
        strain_from_bridge_volts(0.0, bridge="quarter", gauge_factor=2, excitation_v=-1)
