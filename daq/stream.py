"""Raw blocks in, calibrated 400 Hz sample blocks out: filter, decimate, calibrate."""

from __future__ import annotations

import numpy as np

from daq.antialias import AntiAliasDecimator, AntiAliasDesign
from daq.bridge import angle_from_pot_volts, strain_from_bridge_volts
from daq.config import GaugeConfig, PotentiometerConfig
from daq.records import N_CHANNELS, RawBlock, SampleBlock


def calibrate(
    t_ns: np.ndarray,
    volts: np.ndarray,
    first_sequence: int,
    gauges: GaugeConfig,
    potentiometer: PotentiometerConfig,
) -> SampleBlock:
    """A :class:`SampleBlock` from volts (N, 5): potentiometer to angle, bridges to strain."""
    v = np.asarray(volts, dtype=np.float64)
    strain = strain_from_bridge_volts(
        v[:, 1:],
        bridge=gauges.bridge,
        gauge_factor=gauges.gauge_factor,
        excitation_v=gauges.excitation_v,
    )
    angle = angle_from_pot_volts(v[:, 0], potentiometer)
    return SampleBlock(t_ns, angle, strain, v, first_sequence)


class SampleStream:
    """Streaming anti-alias filter + decimation + calibration (state carried across blocks)."""

    def __init__(
        self, design: AntiAliasDesign, gauges: GaugeConfig, potentiometer: PotentiometerConfig
    ) -> None:
        self.design = design
        self.gauges = gauges
        self.potentiometer = potentiometer
        self._decimator = AntiAliasDecimator(design, N_CHANNELS)

    def process(self, block: RawBlock) -> SampleBlock:
        out = self._decimator.process(block.t_ns, block.volts, block.first_sequence)
        return calibrate(out.t_ns, out.volts, out.first_sequence, self.gauges, self.potentiometer)
