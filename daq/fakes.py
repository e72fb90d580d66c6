"""Synthetic hardware with the real devices' interfaces, fed by callables.

No physics here: ``pipelines`` passes the beam's strains, the rocker angle and a frame
renderer in as plain functions. The fakes add what the hardware adds (bridge and
potentiometer transfer functions, noise, ADC range, quantisation and clipping, camera
clock drift, jitter, exposure and latency) and can inject faults. ``realtime=False``
(the default) never sleeps: blocks and frames come as fast as they are asked for.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from types import TracebackType

import numpy as np

from daq.bridge import bridge_volts_from_strain, pot_volts_from_angle
from daq.clock import Clock, MonotonicClock
from daq.config import DaqConfig, GaugeConfig, PotentiometerConfig
from daq.errors import DaqInputError, DeviceError, DeviceTimeoutError
from daq.records import N_GAUGES, Event, Frame, RawBlock, sample_times_ns

log = logging.getLogger(__name__)

StrainFn = Callable[[np.ndarray], np.ndarray]  # t_s (N,) -> strain (N, 4)
AngleFn = Callable[[np.ndarray], np.ndarray]  # t_s (N,) -> rocker angle (N,) rad
RenderFn = Callable[[float, float], bytes]  # (t_exposure_start_s, exposure_s) -> encoded image


@dataclass(frozen=True)
class DaqFaults:
    """Fault switches of :class:`FakeStrainDaq` (block indices count from 0).

    drop_blocks : blocks silently never delivered (the sequence number jumps).
    overflow_blocks : blocks lost to a buffer overflow, reported as an ``overrun`` event.
    timeout_at_block : from this block on, ``read_block`` raises ``DeviceTimeoutError``.
    """

    drop_blocks: tuple[int, ...] = ()
    overflow_blocks: tuple[int, ...] = ()
    timeout_at_block: int | None = None


@dataclass(frozen=True)
class CameraFaults:
    """Fault switches of :class:`FakeCamera` (frame indices count from 0).

    drop_frames : frames never delivered (the sequence number jumps).
    timeout_at_frame : from this frame on, ``read_frame`` raises ``DeviceTimeoutError``.
    """

    drop_frames: tuple[int, ...] = ()
    timeout_at_frame: int | None = None


class FakeStrainDaq:
    """A fake bridge-and-voltage DAQ (one hardware-timed task, five channels).

    Parameters
    ----------
    gauges, potentiometer, daq : GaugeConfig, PotentiometerConfig, DaqConfig
        The rig's acquisition settings (bridge, gauge factor, excitation, calibration,
        rates, block length, ADC bits, potentiometer input range).
    strain_fn : callable
        ``strain_fn(t_s) -> (N, 4)`` true surface strain (m/m) at times ``t_s`` (N,) s.
    angle_fn : callable
        ``angle_fn(t_s) -> (N,)`` true rocker angle, rad.
    strain_noise : float
        RMS strain noise (m/m) added before the bridge.
    pot_noise_v : float
        RMS potentiometer noise, V.
    seed : int
        Noise seed; block ``k`` draws from ``default_rng([seed, k])``, so a dropped block
        does not change the noise of the others.
    bridge_range_v_per_v : float
        Bridge input range per volt of excitation (NI 9237: 25 mV/V).
    timebase_hz : float or None
        If given, the device can only run at ``timebase_hz / n`` (n = 1, 2, ...); the rate
        actually used is the nearest such rate (read it back from ``sample_rate_hz``).
    clock : Clock
        Wall clock used for pacing when ``realtime``.
    realtime : bool
        Deliver blocks no sooner than the hardware would.
    buffer_s : float
        Device buffer length: in real time, a reader further behind than this loses
        samples (an ``overrun`` event).
    faults : DaqFaults
    """

    backend = "fake"

    def __init__(
        self,
        gauges: GaugeConfig,
        potentiometer: PotentiometerConfig,
        daq: DaqConfig,
        *,
        strain_fn: StrainFn,
        angle_fn: AngleFn,
        strain_noise: float = 0.0,
        pot_noise_v: float = 0.0,
        seed: int = 0,
        bridge_range_v_per_v: float = 0.025,
        timebase_hz: float | None = None,
        clock: Clock | None = None,
        realtime: bool = False,
        buffer_s: float = 1.0,
        faults: DaqFaults | None = None,
    ) -> None:
        if not callable(strain_fn):
            raise TypeError("strain_fn must be callable: t_s (N,) -> strain (N, 4)")
        if not callable(angle_fn):
            raise TypeError("angle_fn must be callable: t_s (N,) -> angle (N,) rad")
        for name, v in (("strain_noise", strain_noise), ("pot_noise_v", pot_noise_v)):
            if not np.isfinite(v) or v < 0:
                raise DaqInputError(f"{name} must be a non-negative number, got {v!r}")
        if not bridge_range_v_per_v > 0:
            raise DaqInputError(
                f"bridge_range_v_per_v must be positive, got {bridge_range_v_per_v}"
            )
        if not buffer_s > 0:
            raise DaqInputError(f"buffer_s must be positive, got {buffer_s!r}")
        self.gauges = gauges
        self.potentiometer = potentiometer
        self.daq = daq
        self._strain_fn = strain_fn
        self._angle_fn = angle_fn
        self.strain_noise = float(strain_noise)
        self.pot_noise_v = float(pot_noise_v)
        self.seed = int(seed)
        self.realtime = bool(realtime)
        self.buffer_s = float(buffer_s)
        self.faults = faults or DaqFaults()
        self._clock: Clock = clock or MonotonicClock()
        rate = daq.acquisition_rate_hz
        if timebase_hz is not None:
            rate = timebase_hz / max(1, round(timebase_hz / rate))
        self._rate_hz = float(rate)
        self.block_size = max(1, round(daq.block_duration_s * self._rate_hz))
        bridge_range = bridge_range_v_per_v * gauges.excitation_v
        self.range_v = np.array([daq.pot_range_v] + [bridge_range] * N_GAUGES)
        self.lsb_v = 2.0 * self.range_v / 2.0**daq.adc_bits
        self._started = False
        self._start_wall_ns = 0
        self._next_block = 0
        self._t0_ns = 0

    @property
    def sample_rate_hz(self) -> float:
        return self._rate_hz

    def describe(self) -> dict[str, object]:
        return {
            "backend": self.backend,
            "device": type(self).__name__,
            "requested_rate_hz": self.daq.acquisition_rate_hz,
            "sample_rate_hz": self._rate_hz,
            "block_size": self.block_size,
            "channels": ["potentiometer", "gauge1", "gauge2", "gauge3", "gauge4"],
            "input_range_v": self.range_v.tolist(),
            "adc_bits": self.daq.adc_bits,
            "bridge": self.gauges.bridge,
            "realtime": self.realtime,
        }

    def start(self, first_sample_ns: int = 0) -> None:
        """Start; the first sample is at run-clock time ``first_sample_ns`` (the
        callables are evaluated at run-clock times)."""
        self._started = True
        self._t0_ns = int(first_sample_ns)
        self._next_block = 0
        self._start_wall_ns = self._clock.now_ns()

    def stop(self) -> None:
        self._started = False

    def __enter__(self) -> FakeStrainDaq:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def read_block(self, timeout_s: float) -> RawBlock:
        """The next block of ``block_size`` samples (see the class notes for faults)."""
        if not self._started:
            raise DeviceError("FakeStrainDaq: read_block before start()")
        k = self._next_block
        events: list[Event] = []
        block_s = self.block_size / self._rate_hz
        if self.faults.timeout_at_block is not None and k >= self.faults.timeout_at_block:
            if self.realtime:
                self._clock.sleep_s(timeout_s)
            raise DeviceTimeoutError("FakeStrainDaq", timeout_s)
        if self.realtime:
            lag_s = (self._clock.now_ns() - self._start_wall_ns) * 1e-9 - (k + 1) * block_s
            if lag_s > self.buffer_s:
                lost = int((lag_s - self.buffer_s) / block_s) + 1
                t = sample_times_ns(k * self.block_size, 1, self._rate_hz)[0] + self._t0_ns
                events.append(self._overrun(t, lost * self.block_size, "reader fell behind"))
                k += lost
            elif lag_s < 0:
                if -lag_s > timeout_s:
                    self._clock.sleep_s(timeout_s)
                    raise DeviceTimeoutError("FakeStrainDaq", timeout_s)
                self._clock.sleep_s(-lag_s)
        while k in self.faults.drop_blocks or k in self.faults.overflow_blocks:
            if k in self.faults.overflow_blocks:
                t = sample_times_ns(k * self.block_size, 1, self._rate_hz)[0] + self._t0_ns
                events.append(self._overrun(t, self.block_size, "buffer overflow"))
            k += 1
        self._next_block = k + 1
        return self._make_block(k, tuple(events))

    def _overrun(self, t_ns: int, n_lost: int, why: str) -> Event:
        return Event(int(t_ns), "warning", "overrun", f"{why}: {n_lost} samples lost")

    def _make_block(self, k: int, events: tuple[Event, ...]) -> RawBlock:
        n = self.block_size
        seq0 = k * n
        t_ns = sample_times_ns(seq0, n, self._rate_hz) + np.int64(self._t0_ns)
        t_s = np.arange(seq0, seq0 + n, dtype=np.float64) / self._rate_hz + self._t0_ns * 1e-9
        strain = np.asarray(self._strain_fn(t_s), dtype=np.float64)
        angle = np.asarray(self._angle_fn(t_s), dtype=np.float64)
        if strain.shape != (n, N_GAUGES):
            raise ValueError(f"strain_fn must return shape ({n}, 4), got {strain.shape}")
        if angle.shape != (n,):
            raise ValueError(f"angle_fn must return shape ({n},), got {angle.shape}")
        rng = np.random.default_rng([self.seed, k])
        if self.strain_noise:
            strain = strain + rng.normal(0.0, self.strain_noise, strain.shape)
        pot_v = pot_volts_from_angle(angle, self.potentiometer)
        if self.pot_noise_v:
            pot_v = pot_v + rng.normal(0.0, self.pot_noise_v, n)
        volts = np.empty((n, 1 + N_GAUGES))
        volts[:, 0] = pot_v
        volts[:, 1:] = bridge_volts_from_strain(
            strain,
            bridge=self.gauges.bridge,
            gauge_factor=self.gauges.gauge_factor,
            excitation_v=self.gauges.excitation_v,
        )
        q = np.rint(volts / self.lsb_v) * self.lsb_v
        lo, hi = -self.range_v, self.range_v - self.lsb_v
        over = (volts < lo) | (volts > hi) | ~np.isfinite(volts)
        q = np.clip(np.nan_to_num(q, nan=0.0), lo, hi)
        clipped = tuple(int(c) for c in np.flatnonzero(over.any(axis=0)))
        return RawBlock(t_ns, q, seq0, clipped, events)


class FakeCamera:
    """A fake camera: renders frames on demand, stamps them on a drifting clock.

    The camera's own clock reads ``c = (1 + drift) t + offset`` at true (DAQ) time ``t``.
    Frame ``k`` starts exposing when ``c = (k + 0.5) / frame_rate_hz``; it is stamped at
    mid-exposure on the camera clock plus Gaussian jitter (that is ``Frame.t_ns``), while
    ``render_fn`` gets the TRUE exposure start, so the processing has a real clock offset
    to find. In real time a frame is delivered ``latency_s`` after its exposure ends; a
    reader more than a frame period late loses frames (a jump in ``sequence``).

    Parameters
    ----------
    render_fn : callable
        ``render_fn(t_exposure_start_s, exposure_s) -> bytes``: the encoded image.
    width_px, height_px : int
    frame_rate_hz, exposure_s, latency_s : float
    encoding : str
        ``"jpeg"`` or ``"png"``: what ``render_fn`` returns.
    clock_drift_ppm, clock_offset_s, clock_jitter_s : float
        Camera clock against the DAQ clock.
    seed : int
    clock : Clock
    realtime : bool
    faults : CameraFaults
    render_workers : int
        0 renders each frame when it is read. ``n > 0`` renders up to ``2 n`` frames ahead
        in ``n`` worker threads (their exposure times are known in advance), so a slow
        renderer can keep real time; ``render_fn`` must then be thread-safe.
    """

    backend = "fake"

    def __init__(
        self,
        *,
        render_fn: RenderFn,
        width_px: int,
        height_px: int,
        frame_rate_hz: float,
        encoding: str = "jpeg",
        exposure_s: float = 0.002,
        latency_s: float = 0.0,
        clock_drift_ppm: float = 0.0,
        clock_offset_s: float = 0.0,
        clock_jitter_s: float = 0.0,
        seed: int = 0,
        clock: Clock | None = None,
        realtime: bool = False,
        faults: CameraFaults | None = None,
        render_workers: int = 0,
    ) -> None:
        if not callable(render_fn):
            raise TypeError("render_fn must be callable: (t_start_s, exposure_s) -> bytes")
        if not isinstance(render_workers, int) or render_workers < 0:
            raise DaqInputError(f"render_workers must be an integer >= 0, got {render_workers!r}")
        if encoding not in ("jpeg", "png"):
            raise DaqInputError(f"encoding must be 'jpeg' or 'png', got {encoding!r}")
        if not frame_rate_hz > 0:
            raise DaqInputError(f"frame_rate_hz must be positive, got {frame_rate_hz!r}")
        if not 0 < exposure_s < 1.0 / frame_rate_hz:
            raise DaqInputError(f"exposure_s must be within (0, frame period), got {exposure_s!r}")
        for name, v in (("latency_s", latency_s), ("clock_jitter_s", clock_jitter_s)):
            if not np.isfinite(v) or v < 0:
                raise DaqInputError(f"{name} must be a non-negative number, got {v!r}")
        if width_px <= 0 or height_px <= 0:
            raise DaqInputError(
                f"width_px and height_px must be positive, got {width_px}x{height_px}"
            )
        self._render_fn = render_fn
        self.width_px = int(width_px)
        self.height_px = int(height_px)
        self.frame_rate_hz = float(frame_rate_hz)
        self.encoding = encoding
        self.exposure_s = float(exposure_s)
        self.latency_s = float(latency_s)
        self.clock_drift_ppm = float(clock_drift_ppm)
        self.clock_offset_s = float(clock_offset_s)
        self.clock_jitter_s = float(clock_jitter_s)
        self.seed = int(seed)
        self.realtime = bool(realtime)
        self.faults = faults or CameraFaults()
        self._clock: Clock = clock or MonotonicClock()
        self.render_workers = render_workers
        self._pool: ThreadPoolExecutor | None = None
        self._ahead: dict[int, Future[bytes]] = {}
        self._started = False
        self._start_wall_ns = 0
        self._next = 0

    def describe(self) -> dict[str, object]:
        return {
            "backend": self.backend,
            "device": type(self).__name__,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "frame_rate_hz": self.frame_rate_hz,
            "encoding": self.encoding,
            "exposure_s": self.exposure_s,
            "latency_s": self.latency_s,
            "realtime": self.realtime,
        }

    def true_exposure_start_s(self, k: int) -> float:
        """True (DAQ-clock) exposure start of frame ``k``, s."""
        c = (k + 0.5) / self.frame_rate_hz
        return (c - self.clock_offset_s) / (1.0 + self.clock_drift_ppm * 1e-6)

    def stamp_ns(self, k: int) -> int:
        """``Frame.t_ns`` of frame ``k``: camera-clock mid-exposure plus jitter."""
        c_mid = (k + 0.5) / self.frame_rate_hz + 0.5 * self.exposure_s
        if self.clock_jitter_s:
            c_mid += float(np.random.default_rng([self.seed, k]).normal(0, self.clock_jitter_s))
        return max(0, round(c_mid * 1e9))

    def _available_s(self, k: int) -> float:
        return self.true_exposure_start_s(k) + self.exposure_s + self.latency_s

    def start(self) -> None:
        self._started = True
        self._next = 0
        if self.render_workers and self._pool is None:
            self._pool = ThreadPoolExecutor(self.render_workers, "fake-camera-render")
        self._start_wall_ns = self._clock.now_ns()

    def stop(self) -> None:
        self._started = False
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
        self._ahead.clear()

    def _render_ahead(self, k: int) -> None:
        assert self._pool is not None
        for old in [j for j in self._ahead if j < k]:
            self._ahead.pop(old).cancel()
        for j in range(k, k + 2 * self.render_workers):
            if j not in self._ahead:
                t = self.true_exposure_start_s(j)
                self._ahead[j] = self._pool.submit(self._render_fn, t, self.exposure_s)

    def _render(self, k: int) -> bytes:
        if self._pool is None:
            return self._render_fn(self.true_exposure_start_s(k), self.exposure_s)
        self._render_ahead(k)
        return self._ahead.pop(k).result()

    def __enter__(self) -> FakeCamera:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def read_frame(self, timeout_s: float) -> Frame | None:
        """The next frame (never ``None``: a camera does not run out)."""
        if not self._started:
            raise DeviceError("FakeCamera: read_frame before start()")
        k = self._next
        while k in self.faults.drop_frames:
            k += 1
        if self.faults.timeout_at_frame is not None and k >= self.faults.timeout_at_frame:
            if self.realtime:
                self._clock.sleep_s(timeout_s)
            raise DeviceTimeoutError("FakeCamera", timeout_s)
        if self.realtime:
            now_s = (self._clock.now_ns() - self._start_wall_ns) * 1e-9
            period = 1.0 / self.frame_rate_hz
            if now_s > self._available_s(k) + period:
                # the camera's buffer holds one frame: everything older is overwritten
                while self._available_s(k + 1) <= now_s:
                    k += 1
            if self._pool is not None:
                self._render_ahead(k)  # render while waiting for the exposure
            wait = self._available_s(k) - now_s
            if wait > timeout_s:
                self._clock.sleep_s(timeout_s)
                raise DeviceTimeoutError("FakeCamera", timeout_s)
            self._clock.sleep_s(wait)
        self._next = k + 1
        data = self._render(k)
        if not isinstance(data, bytes | bytearray):
            raise TypeError(f"render_fn must return encoded bytes, got {type(data).__name__}")
        return Frame(self.stamp_ns(k), k, bytes(data), self.encoding, self.width_px, self.height_px)
