"""The sensors' electrical conversions, pure functions: bridge volts <-> strain,
potentiometer volts <-> angle.

Sign convention (NI-DAQmx's): a bridge's output ratio ``Vr = Vout / Vexcitation`` is
negative for tensile strain. Bridge configurations:

- ``quarter`` (quarter bridge I, one active gauge): ``Vr = -GF e / (4 + 2 GF e)``,
  exactly, from the Wheatstone divider with the gauge at ``R (1 + GF e)``; not linear.
- ``half`` (half bridge II, two active gauges on opposite faces, +e and -e in adjacent
  arms): ``Vr = -GF e / 2``, exactly linear.
- ``full`` (full bridge I, four active gauges, two +e and two -e): ``Vr = -GF e``,
  exactly linear.
The unstrained bridge is assumed balanced (offset nulled).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from daq.config import BRIDGE_TYPES, PotentiometerConfig
from daq.errors import DaqInputError


def _check_bridge(bridge: str, gauge_factor: float, excitation_v: float) -> None:
    if bridge not in BRIDGE_TYPES:
        raise DaqInputError(f"bridge must be one of {BRIDGE_TYPES}, got {bridge!r}")
    if not gauge_factor > 0:
        raise DaqInputError(f"gauge_factor must be positive, got {gauge_factor!r}")
    if not excitation_v > 0:
        raise DaqInputError(f"excitation_v must be positive, got {excitation_v!r}")


def bridge_volts_from_strain(
    strain: ArrayLike, *, bridge: str, gauge_factor: float, excitation_v: float
) -> np.ndarray:
    """Bridge output volts produced by ``strain`` (m/m), any shape."""
    _check_bridge(bridge, gauge_factor, excitation_v)
    x = gauge_factor * np.asarray(strain, dtype=np.float64)
    if bridge == "quarter":
        vr = -x / (4.0 + 2.0 * x)
    elif bridge == "half":
        vr = -0.5 * x
    else:
        vr = -x
    return vr * excitation_v


def strain_from_bridge_volts(
    volts: ArrayLike, *, bridge: str, gauge_factor: float, excitation_v: float
) -> np.ndarray:
    """Strain (m/m) from bridge output volts, the exact inverse of
    :func:`bridge_volts_from_strain` (quarter: ``e = -4 Vr / (GF (1 + 2 Vr))``)."""
    _check_bridge(bridge, gauge_factor, excitation_v)
    vr = np.asarray(volts, dtype=np.float64) / excitation_v
    if bridge == "quarter":
        return -4.0 * vr / (gauge_factor * (1.0 + 2.0 * vr))
    if bridge == "half":
        return -2.0 * vr / gauge_factor
    return -vr / gauge_factor


def pot_volts_from_angle(angle_rad: ArrayLike, pot: PotentiometerConfig) -> np.ndarray:
    """Potentiometer wiper volts for a rocker angle (rad), any shape."""
    a = np.asarray(angle_rad, dtype=np.float64)
    return (a - pot.zero_angle_rad) / pot.electrical_range_rad * pot.supply_v


def angle_from_pot_volts(volts: ArrayLike, pot: PotentiometerConfig) -> np.ndarray:
    """Rocker angle (rad) from potentiometer volts:
    ``zero_angle_rad + volts / supply_v * electrical_range_rad``."""
    v = np.asarray(volts, dtype=np.float64)
    return pot.zero_angle_rad + v / pot.supply_v * pot.electrical_range_rad
