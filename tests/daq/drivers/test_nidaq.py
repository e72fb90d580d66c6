"""The NI-DAQmx driver's pure parts: the rig mapped onto DAQmx channel settings."""

from __future__ import annotations

import importlib.util

import pytest

from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from daq.drivers.nidaq import NiStrainDaq, channel_settings, check_nidaqmx
from daq.errors import DriverUnavailableError


def test_channel_settings_follow_the_rig() -> None:
    g = GaugeConfig(gauge_factor=2.1, excitation_v=2.5, bridge="half", resistance_ohm=350.0)
    p = PotentiometerConfig(channel="cDAQ1Mod3/ai7")
    d = DaqConfig(pot_range_v=5.0)
    s = channel_settings(g, p, d, strain_range=0.002)
    assert [c["physical_channel"] for c in s] == ["cDAQ1Mod3/ai7", *g.channels]
    assert s[0] == {
        "kind": "voltage",
        "physical_channel": "cDAQ1Mod3/ai7",
        "min_val": -5.0,
        "max_val": 5.0,
    }
    for i, c in enumerate(s[1:]):
        assert c["kind"] == "strain"
        assert c["name_to_assign_to_channel"] == f"gauge{i + 1}"
        assert c["strain_config"] == "HALF_BRIDGE_II"
        assert c["gage_factor"] == 2.1 and c["voltage_excit_val"] == 2.5
        assert c["nominal_gage_resistance"] == 350.0
        assert (c["min_val"], c["max_val"]) == (-0.002, 0.002)
    assert channel_settings(GaugeConfig(), p, d)[1]["strain_config"] == "QUARTER_BRIDGE_I"
    with pytest.raises(ValueError, match="strain_range"):
        channel_settings(g, p, d, strain_range=0.0)


@pytest.mark.skipif(importlib.util.find_spec("nidaqmx") is not None, reason="nidaqmx installed")
def test_without_nidaqmx_the_error_suggests_the_fake_backend() -> None:
    with pytest.raises(DriverUnavailableError, match="--backend fake"):
        check_nidaqmx()
    daq = NiStrainDaq(GaugeConfig(), PotentiometerConfig(), DaqConfig())
    with pytest.raises(DriverUnavailableError, match="nidaqmx"):
        daq.start()
