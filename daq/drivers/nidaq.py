"""NI-DAQmx strain DAQ: four strain-gauge bridges and the potentiometer in one task.

``nidaqmx`` is imported lazily inside functions, so this module imports without it.
The driver only translates: the rig's gauge settings become DAQmx strain channels,
DAQmx's strain readings are turned back into bridge volts with the same exact formula
(``daq.bridge``), and buffer overflows become ``overrun`` events with a jump in
the sample sequence, never silently skipped. Not exercised here without hardware; the
configuration mapping (:func:`channel_settings`) is a pure function with tests.
"""

from __future__ import annotations

import importlib
import logging
import time
from types import TracebackType
from typing import Any

import numpy as np

from daq.bridge import bridge_volts_from_strain
from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from daq.errors import DaqInputError, DeviceError, DeviceTimeoutError, DriverUnavailableError
from daq.records import Event, RawBlock, sample_times_ns

log = logging.getLogger(__name__)

BRIDGE_CONFIGS = {
    "quarter": "QUARTER_BRIDGE_I",
    "half": "HALF_BRIDGE_II",
    "full": "FULL_BRIDGE_I",
}
ERROR_SAMPLES_NO_LONGER_AVAILABLE = -200279
ERROR_READ_TIMEOUT = -200284
_HINT = "install it with `pip install beambench[hardware]` (and NI-DAQmx), or use --backend fake"


def _vendor(module: str = "nidaqmx") -> Any:
    """Import the vendor package (or one of its modules) only when a device is used."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise DriverUnavailableError("nidaqmx", _HINT) from None


def check_nidaqmx() -> None:
    """Raise ``DriverUnavailableError`` (suggesting ``--backend fake``) without nidaqmx."""
    _vendor()


def channel_settings(
    gauges: GaugeConfig,
    potentiometer: PotentiometerConfig,
    daq: DaqConfig,
    *,
    strain_range: float = 0.005,
    poisson_ratio: float = 0.33,
) -> list[dict[str, Any]]:
    """The DAQmx channel settings for the rig, in record order (pot, gauges 1-4).

    Returns one dict per channel: ``kind`` ("voltage" or "strain") and the keyword
    arguments of ``add_ai_voltage_chan`` / ``add_ai_strain_gage_chan`` (enum members
    named by string: ``strain_config`` is a ``StrainGageBridgeType`` name).
    """
    if not strain_range > 0:
        raise DaqInputError(f"strain_range must be positive, got {strain_range!r}")
    settings: list[dict[str, Any]] = [
        {
            "kind": "voltage",
            "physical_channel": potentiometer.channel,
            "min_val": -daq.pot_range_v,
            "max_val": daq.pot_range_v,
        }
    ]
    for i, ch in enumerate(gauges.channels):
        settings.append(
            {
                "kind": "strain",
                "physical_channel": ch,
                "name_to_assign_to_channel": f"gauge{i + 1}",
                "min_val": -strain_range,
                "max_val": strain_range,
                "strain_config": BRIDGE_CONFIGS[gauges.bridge],
                "voltage_excit_source": "INTERNAL",
                "voltage_excit_val": gauges.excitation_v,
                "gage_factor": gauges.gauge_factor,
                "initial_bridge_voltage": 0.0,
                "nominal_gage_resistance": gauges.resistance_ohm,
                "poisson_ratio": poisson_ratio,
                "lead_wire_resistance": 0.0,
            }
        )
    return settings


class NiStrainDaq:
    """Hardware-timed continuous acquisition on an NI chassis (e.g. cDAQ + NI 9237).

    Parameters
    ----------
    gauges, potentiometer, daq : the rig's sections.
    strain_range : float
        Expected strain range (m/m) for the DAQmx channel.
    buffer_s : float
        Device buffer length, s.
    """

    backend = "nidaqmx"

    def __init__(
        self,
        gauges: GaugeConfig,
        potentiometer: PotentiometerConfig,
        daq: DaqConfig,
        *,
        strain_range: float = 0.005,
        buffer_s: float = 10.0,
    ) -> None:
        self.gauges = gauges
        self.potentiometer = potentiometer
        self.daq = daq
        self.settings = channel_settings(gauges, potentiometer, daq, strain_range=strain_range)
        self.strain_range = strain_range
        self.buffer_s = buffer_s
        self._task: Any = None
        self._rate_hz = float(daq.acquisition_rate_hz)
        self._block = max(1, round(daq.block_duration_s * self._rate_hz))
        self._next_seq = 0
        self._start_ns = 0
        self._t0_ns = 0

    @property
    def sample_rate_hz(self) -> float:
        return self._rate_hz

    def describe(self) -> dict[str, object]:
        return {
            "backend": self.backend,
            "device": "NI-DAQmx task",
            "requested_rate_hz": self.daq.acquisition_rate_hz,
            "sample_rate_hz": self._rate_hz,
            "channels": [s["physical_channel"] for s in self.settings],
            "bridge": BRIDGE_CONFIGS[self.gauges.bridge],
            "block_size": self._block,
        }

    def _configure(self) -> Any:
        nidaqmx = _vendor()
        constants = _vendor("nidaqmx.constants")

        task = nidaqmx.Task()
        try:
            for s in self.settings:
                kw = {k: v for k, v in s.items() if k != "kind"}
                if s["kind"] == "voltage":
                    task.ai_channels.add_ai_voltage_chan(**kw)
                else:
                    kw["strain_config"] = getattr(
                        constants.StrainGageBridgeType, kw["strain_config"]
                    )
                    kw["voltage_excit_source"] = getattr(
                        constants.ExcitationSource, kw["voltage_excit_source"]
                    )
                    kw["units"] = constants.StrainUnits.STRAIN
                    task.ai_channels.add_ai_strain_gage_chan(**kw)
            task.timing.cfg_samp_clk_timing(
                self.daq.acquisition_rate_hz,
                sample_mode=constants.AcquisitionType.CONTINUOUS,
                samps_per_chan=max(self._block * 4, round(self.buffer_s * self._rate_hz)),
            )
            rate = float(task.timing.samp_clk_rate)  # what the hardware really uses
        except BaseException:
            task.close()
            raise
        return task, rate

    def start(self, first_sample_ns: int = 0) -> None:
        """Configure and start the task; the first sample is at run-clock time
        ``first_sample_ns`` (capture's pre-roll makes it negative)."""
        errors = _vendor("nidaqmx.errors")
        try:
            self._task, self._rate_hz = self._configure()
            self._block = max(1, round(self.daq.block_duration_s * self._rate_hz))
            self._task.start()
        except errors.DaqError as exc:
            raise DeviceError(f"NI-DAQmx: {exc}") from None
        self._next_seq = 0
        self._t0_ns = int(first_sample_ns)
        self._start_ns = time.monotonic_ns()
        log.info(
            "NI-DAQmx running at %.6g Hz (requested %.6g Hz)",
            self._rate_hz,
            self.daq.acquisition_rate_hz,
        )

    def read_block(self, timeout_s: float) -> RawBlock:
        errors = _vendor("nidaqmx.errors")
        if self._task is None:
            raise DeviceError("NI-DAQmx: read_block before start()")
        events: list[Event] = []
        try:
            data = self._task.read(number_of_samples_per_channel=self._block, timeout=timeout_s)
        except errors.DaqError as exc:
            if exc.error_code == ERROR_READ_TIMEOUT:
                raise DeviceTimeoutError("NI-DAQmx", timeout_s) from None
            if exc.error_code != ERROR_SAMPLES_NO_LONGER_AVAILABLE:
                raise DeviceError(f"NI-DAQmx: {exc}") from None
            # overflow: restart, and place the next samples where the wall clock says
            lost_from = self._next_seq
            self._task.stop()
            self._task.start()
            elapsed = (time.monotonic_ns() - self._start_ns) * 1e-9
            self._next_seq = max(self._next_seq, round(elapsed * self._rate_hz))
            t = int(sample_times_ns(lost_from, 1, self._rate_hz)[0]) + self._t0_ns
            events.append(
                Event(
                    t,
                    "warning",
                    "overrun",
                    f"NI-DAQmx buffer overflow (samples no longer available): about "
                    f"{self._next_seq - lost_from} samples lost; times after it are "
                    f"placed by the host clock",
                )
            )
            data = self._task.read(number_of_samples_per_channel=self._block, timeout=timeout_s)
        arr = np.asarray(data, dtype=np.float64).T  # (N, 5)
        volts = np.empty_like(arr)
        volts[:, 0] = arr[:, 0]
        volts[:, 1:] = bridge_volts_from_strain(
            arr[:, 1:],
            bridge=self.gauges.bridge,
            gauge_factor=self.gauges.gauge_factor,
            excitation_v=self.gauges.excitation_v,
        )
        clipped = []
        if np.any(np.abs(arr[:, 0]) >= 0.999 * self.daq.pot_range_v):
            clipped.append(0)
        for i in range(1, 5):
            if np.any(np.abs(arr[:, i]) >= 0.999 * self.strain_range):
                clipped.append(i)
        seq0 = self._next_seq
        self._next_seq += len(arr)
        t_ns = sample_times_ns(seq0, len(arr), self._rate_hz) + np.int64(self._t0_ns)
        return RawBlock(t_ns, volts, seq0, tuple(clipped), tuple(events))

    def stop(self) -> None:
        if self._task is not None:
            try:
                self._task.stop()
            finally:
                self._task.close()
                self._task = None

    def __enter__(self) -> NiStrainDaq:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
