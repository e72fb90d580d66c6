"""daq's one error tree: bad settings and arguments are ``DaqInputError``, which is both a
``DaqError`` (the CLI's one catch) and a ``ValueError`` (what callers validating a config
already catch)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from daq.antialias import AntiAliasDecimator, design_antialias
from daq.bridge import strain_from_bridge_volts
from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from daq.drivers.nidaq import channel_settings
from daq.drivers.opencv_camera import VideoFileCamera
from daq.errors import DaqError, DaqInputError, DeviceError, DriverUnavailableError, LogError
from daq.fakes import FakeCamera, FakeStrainDaq
from daq.imageinfo import image_size_px
from daq.log import LogWriter, read_run
from daq.replay import replay_records


def test_every_daq_error_has_the_one_root() -> None:
    for cls in (DaqInputError, DeviceError, DriverUnavailableError, LogError):
        assert issubclass(cls, DaqError)
    assert issubclass(DaqInputError, ValueError)


def _zeros(t: np.ndarray) -> np.ndarray:
    return np.zeros((len(t), 4))


BAD_INPUTS: dict[str, tuple[Callable[[Path], object], str]] = {
    "gauge config": (lambda _: GaugeConfig(bridge="double"), "bridge"),
    "potentiometer config": (lambda _: PotentiometerConfig(supply_v=0.0), "supply_v"),
    "daq config": (lambda _: DaqConfig(adc_bits=4), "adc_bits"),
    "bridge calibration": (
        lambda _: strain_from_bridge_volts(0.0, bridge="quarter", gauge_factor=0, excitation_v=5),
        "gauge_factor",
    ),
    "filter design": (lambda _: design_antialias(DaqConfig(), 2100.0), "acquisition_rate_hz"),
    "decimator": (lambda _: AntiAliasDecimator(design_antialias(DaqConfig(), 2000.0), 0), "n_"),
    "fake daq": (
        lambda _: FakeStrainDaq(
            GaugeConfig(),
            PotentiometerConfig(),
            DaqConfig(),
            strain_fn=_zeros,
            angle_fn=np.zeros_like,
            buffer_s=0.0,
        ),
        "buffer_s",
    ),
    "fake camera": (
        lambda _: FakeCamera(render_fn=lambda t, e: b"", width_px=8, height_px=8, frame_rate_hz=0),
        "frame_rate_hz",
    ),
    "nidaq settings": (
        lambda _: channel_settings(
            GaugeConfig(), PotentiometerConfig(), DaqConfig(), strain_range=0.0
        ),
        "strain_range",
    ),
    "video camera": (lambda d: VideoFileCamera(d / "v.avi", encoding="gif"), "encoding"),
    "image header": (lambda _: image_size_px(b"GIF89a...."), "data"),
    "log writer": (
        lambda d: LogWriter(d / "w.mcap", rig_json="[]", run_info={}),
        "rig_json",
    ),
    "camera info": (
        lambda d: LogWriter(
            d / "c.mcap", rig_json=json.dumps({}), run_info={}, camera_info={"width": 1}
        ),
        "camera_info",
    ),
    "log topics": (lambda d: read_run(d / "any.mcap", topics=["/nope"]), "topics"),
    "replay speed": (lambda d: list(replay_records(d / "any.mcap", speed=-1.0)), "speed"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_settings_and_arguments_are_daq_input_errors(case: str, tmp_path: Path) -> None:
    build, parameter = BAD_INPUTS[case]
    with pytest.raises(DaqInputError, match=parameter) as caught:
        build(tmp_path)
    assert isinstance(caught.value, ValueError) and isinstance(caught.value, DaqError)
