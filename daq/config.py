"""Configuration of the acquisition hardware: gauges, potentiometer and DAQ.

Frozen dataclasses validated on construction; a bad value raises ``DaqInputError``
(a ``ValueError``) whose message starts with the field name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from daq.errors import DaqInputError

BRIDGE_TYPES = ("quarter", "half", "full")


def _positive(name: str, value: float) -> None:
    if not math.isfinite(value) or value <= 0.0:
        raise DaqInputError(f"{name} must be a positive finite number, got {value!r}")


def _at_most(name: str, value: float, limit: float, unit: str, why: str) -> None:
    if not abs(value) <= limit:
        raise DaqInputError(f"{name} must be at most {limit:g} {unit} ({why}), got {value!r}")


# Limits of the hardware this package drives (each error states its reason).
MAX_POSITION_M = 10.0  # a gauge on a laboratory beam
MAX_RESISTANCE_OHM = 1e5  # foil and semiconductor gauges are 120 ohm .. 5 kohm
MAX_GAUGE_FACTOR = 200.0  # semiconductor gauges reach ~150
MAX_VOLTS = 100.0  # bridge excitation, potentiometer supply and input range
MAX_ACQUISITION_HZ = 1e6  # a DAQ card's per-channel rate
MAX_RIPPLE_DB = 10.0
MAX_ATTENUATION_DB = 200.0  # beyond a 32-bit converter's dynamic range
MAX_BLOCK_S = 10.0  # one read's worth of samples


@dataclass(frozen=True)
class GaugeConfig:
    """Four axial strain gauges (paper §2): positions from the clamp, in gauge order.

    Gauge factor, bridge and excitation are not in the paper; the defaults
    (quarter bridge, GF 2.0, 5 V) are the usual choice for 120 ohm foil gauges.
    """

    positions_m: tuple[float, ...] = (0.005, 0.204, 0.403, 0.603)
    resistance_ohm: float = 120.0
    resistance_tolerance_ohm: float = 0.3
    gauge_factor: float = 2.0
    bridge: str = "quarter"
    excitation_v: float = 5.0
    channels: tuple[str, ...] = ("cDAQ1Mod1/ai0", "cDAQ1Mod1/ai1", "cDAQ1Mod1/ai2", "cDAQ1Mod1/ai3")

    def __post_init__(self) -> None:
        if len(self.positions_m) != 4:
            raise DaqInputError(f"positions_m must list 4 gauges, got {len(self.positions_m)}")
        for x in self.positions_m:
            if not math.isfinite(x) or x < 0.0:
                raise DaqInputError(f"positions_m must be non-negative distances, got {x!r}")
            _at_most("positions_m", x, MAX_POSITION_M, "m", "a gauge on a laboratory beam")
        if any(b <= a for a, b in zip(self.positions_m, self.positions_m[1:], strict=False)):
            raise DaqInputError(
                f"positions_m must increase from the clamp outwards, got {self.positions_m!r}"
            )
        _positive("resistance_ohm", self.resistance_ohm)
        _at_most("resistance_ohm", self.resistance_ohm, MAX_RESISTANCE_OHM, "ohm", "a gauge")
        if not 0.0 <= self.resistance_tolerance_ohm < self.resistance_ohm:
            raise DaqInputError(
                f"resistance_tolerance_ohm must be >= 0 and below resistance_ohm "
                f"({self.resistance_ohm!r}), got {self.resistance_tolerance_ohm!r}"
            )
        _positive("gauge_factor", self.gauge_factor)
        _at_most("gauge_factor", self.gauge_factor, MAX_GAUGE_FACTOR, "(1)", "semiconductor ~150")
        _positive("excitation_v", self.excitation_v)
        _at_most("excitation_v", self.excitation_v, MAX_VOLTS, "V", "a bridge excitation")
        if self.bridge not in BRIDGE_TYPES:
            raise DaqInputError(f"bridge must be one of {BRIDGE_TYPES}, got {self.bridge!r}")
        if len(self.channels) != len(self.positions_m):
            raise DaqInputError(
                f"channels must name one DAQ channel per gauge ({len(self.positions_m)}), "
                f"got {len(self.channels)}"
            )


@dataclass(frozen=True)
class PotentiometerConfig:
    """Precision potentiometer on the rocker's ground pivot, read as a voltage.

    angle = zero_angle_rad + (volts / supply_v) * electrical_range_rad. The paper gives
    no calibration; the defaults are a 5 V supply over a 340 deg electrical range, with
    the zero set so the rocker's stroke sits mid-range.
    """

    supply_v: float = 5.0
    electrical_range_rad: float = math.radians(340.0)
    zero_angle_rad: float = math.radians(-63.4)
    channel: str = "cDAQ1Mod2/ai0"

    def __post_init__(self) -> None:
        _positive("supply_v", self.supply_v)
        _at_most("supply_v", self.supply_v, MAX_VOLTS, "V", "a potentiometer supply")
        _positive("electrical_range_rad", self.electrical_range_rad)
        if self.electrical_range_rad > 2.0 * math.pi:
            raise DaqInputError(
                f"electrical_range_rad must be at most 2 pi, got {self.electrical_range_rad!r}"
            )
        if not abs(self.zero_angle_rad) <= 2.0 * math.pi:
            raise DaqInputError(
                f"zero_angle_rad must be finite and within +/-2 pi (one turn), "
                f"got {self.zero_angle_rad!r}"
            )


@dataclass(frozen=True)
class DaqConfig:
    """Sampling and the anti-alias filter (paper §2: 400 Hz, Butterworth 150/200 Hz).

    The filter runs at ``acquisition_rate_hz`` before decimation to ``output_rate_hz``;
    ripple and attenuation are not in the paper (defaults 1 dB, 40 dB).
    """

    output_rate_hz: float = 400.0
    acquisition_rate_hz: float = 2000.0
    passband_hz: float = 150.0
    stopband_hz: float = 200.0
    passband_ripple_db: float = 1.0
    stopband_attenuation_db: float = 40.0
    block_duration_s: float = 0.1
    pot_range_v: float = 10.0
    adc_bits: int = 24
    flush_interval_s: float = 0.1

    def __post_init__(self) -> None:
        for name in (
            "output_rate_hz",
            "acquisition_rate_hz",
            "passband_hz",
            "stopband_hz",
            "passband_ripple_db",
            "stopband_attenuation_db",
            "block_duration_s",
            "pot_range_v",
            "flush_interval_s",
        ):
            _positive(name, getattr(self, name))
        _at_most(
            "acquisition_rate_hz",
            self.acquisition_rate_hz,
            MAX_ACQUISITION_HZ,
            "Hz",
            "a DAQ card's per-channel rate",
        )
        _at_most("passband_ripple_db", self.passband_ripple_db, MAX_RIPPLE_DB, "dB", "a filter")
        _at_most(
            "stopband_attenuation_db",
            self.stopband_attenuation_db,
            MAX_ATTENUATION_DB,
            "dB",
            "beyond a 32-bit converter's range",
        )
        _at_most("block_duration_s", self.block_duration_s, MAX_BLOCK_S, "s", "one read")
        _at_most("pot_range_v", self.pot_range_v, MAX_VOLTS, "V", "an input range")
        if self.passband_hz >= self.stopband_hz:
            raise DaqInputError(
                f"passband_hz ({self.passband_hz!r}) must be below "
                f"stopband_hz ({self.stopband_hz!r})"
            )
        if self.stopband_hz > 0.5 * self.acquisition_rate_hz:
            raise DaqInputError(
                f"acquisition_rate_hz ({self.acquisition_rate_hz!r}) must be at least twice "
                f"stopband_hz ({self.stopband_hz!r})"
            )
        ratio = self.acquisition_rate_hz / self.output_rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise DaqInputError(
                f"acquisition_rate_hz ({self.acquisition_rate_hz!r}) must be a whole multiple "
                f"of output_rate_hz ({self.output_rate_hz!r})"
            )
        if self.stopband_hz > 0.5 * self.output_rate_hz + 1e-9:
            raise DaqInputError(
                f"stopband_hz ({self.stopband_hz!r}) must not exceed the output Nyquist "
                f"frequency ({0.5 * self.output_rate_hz!r} Hz)"
            )
        if not 8 <= self.adc_bits <= 32:
            raise DaqInputError(f"adc_bits must be between 8 and 32, got {self.adc_bits!r}")
        if self.flush_interval_s > 1.0:
            raise DaqInputError(
                f"flush_interval_s must be at most 1 s (crash-safety contract), "
                f"got {self.flush_interval_s!r}"
            )

    @property
    def decimation(self) -> int:
        return round(self.acquisition_rate_hz / self.output_rate_hz)
