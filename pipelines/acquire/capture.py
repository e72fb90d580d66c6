"""The capture loop: DAQ + camera on one run clock into a crash-safe MCAP log.

Run-clock zero is the log's first sample: the DAQ starts a pre-roll earlier (the
anti-alias filter's settling, see :func:`preroll`), so the log holds ``duration x 400``
samples from t = 0. The main thread reads DAQ blocks, filters and decimates them to the
400 Hz stream and writes them; a worker thread reads the camera
into a queue. Frames are written once the DAQ stream has reached their time, so the
file stays nearly in log-time order. Every loss is an event in the log: sample gaps,
overruns, dropped or late frames, clipping, device errors. Ctrl-C finishes the file;
a write failure leaves what was flushed recoverable.
"""

from __future__ import annotations

import logging
import math
import os
import queue
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol

from daq.antialias import AntiAliasDesign, design_antialias
from daq.errors import DaqError, DeviceTimeoutError
from daq.log import LogWriter
from daq.protocols import Camera, StrainDaq
from daq.records import Event, Frame, SampleBlock, sample_times_ns
from daq.stream import SampleStream
from pipelines import __version__
from pipelines.errors import BeambenchError
from pipelines.rig import Rig

log = logging.getLogger(__name__)

ProgressFn = Callable[[float, float], None]  # (captured_s, duration_s)
CHANNEL_NAMES = ("potentiometer", "gauge 1", "gauge 2", "gauge 3", "gauge 4")


@dataclass(frozen=True)
class CaptureSummary:
    """What a capture recorded and lost (counts of messages written to the log)."""

    out_path: Path
    run_id: str
    duration_s: float
    samples: int
    frames: int
    events: int
    dropped_samples: int
    dropped_frames: int
    overruns: int
    clipping_events: int
    device_errors: int
    acquisition_rate_hz: float
    wall_time_s: float
    cpu_time_s: float
    flushes: int
    interrupted: bool
    log_bytes: int


class _Counters:
    def __init__(self) -> None:
        self.dropped_samples = 0
        self.overruns = 0
        self.clipping = 0
        self.device_errors = 0
        self.frames = 0


class _CameraReader(threading.Thread):
    """Reads frames until one starts at or after ``end_ns``; puts ``Frame``, ``Event``
    or ``None`` (end) on ``out``. In real time a full queue drops the frame (an event)."""

    def __init__(self, camera: Camera, end_ns: int, realtime: bool, period_s: float) -> None:
        super().__init__(name="camera-reader", daemon=True)
        self.camera = camera
        self.end_ns = end_ns
        self.realtime = realtime
        self.period_s = period_s
        self.timeout_s = max(1.0, 3.0 * period_s)
        self.out: queue.Queue[Frame | Event | None] = queue.Queue(maxsize=32)
        self.stop_flag = threading.Event()
        self.failure: BaseException | None = None
        self.now_ns = 0  # latest DAQ time, set by the main loop (for event times)
        self.next_sequence = 0
        self.dropped_frames = 0
        self.device_errors = 0

    def _put(self, item: Frame | Event | None) -> None:
        if self.realtime and isinstance(item, Frame):
            try:
                self.out.put_nowait(item)
            except queue.Full:
                self.dropped_frames += 1
                self._put(
                    Event(
                        item.t_ns,
                        "warning",
                        "dropped_frames",
                        f"frame {item.sequence} not written in time (writer busy)",
                    )
                )
            return
        while not self.stop_flag.is_set():
            try:
                self.out.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def _check_sequence(self, frame: Frame) -> None:
        missing = frame.sequence - self.next_sequence
        if frame.t_ns >= self.end_ns and missing > 0:
            # the frame that ends the run: count only the skipped frames due before the end
            before_end = (self.end_ns - frame.t_ns) / (self.period_s * 1e9) + missing
            missing = max(0, min(missing, math.ceil(before_end)))
        if missing > 0:
            self.dropped_frames += missing
            self._put(
                Event(
                    min(frame.t_ns, self.end_ns),
                    "warning",
                    "dropped_frames",
                    f"{missing} frames missing before frame {frame.sequence}",
                )
            )
        self.next_sequence = frame.sequence + 1

    def run(self) -> None:
        timeouts = 0
        try:
            while not self.stop_flag.is_set():
                try:
                    frame = self.camera.read_frame(self.timeout_s)
                except DeviceTimeoutError as exc:
                    timeouts += 1
                    self.device_errors += 1
                    self._put(Event(self.now_ns, "error", "device_error", f"camera: {exc}"))
                    if timeouts >= 3:
                        break
                    continue
                except DaqError as exc:
                    self.device_errors += 1
                    self._put(Event(self.now_ns, "error", "device_error", f"camera: {exc}"))
                    break
                timeouts = 0
                if frame is None:
                    break
                self._check_sequence(frame)
                if frame.t_ns >= self.end_ns:
                    break
                self._put(frame)
        except BaseException as exc:  # handed to the main thread, which re-raises it
            self.failure = exc
        finally:
            self._put(None)


def preroll(design: AntiAliasDesign) -> tuple[int, int]:
    """``(preroll_ns, first_output_sequence)``: how long before the run clock's zero the
    acquisition starts, and the decimator's sequence number of the output sample at 0.

    The filter withholds its outputs for ``design.settle_s()`` after a (re)start; the
    first it emits is the acquisition sample ``n0``, the first settled one on the
    decimation grid, stamped ``t(n0) - group delay``. Starting the acquisition at
    ``-(t(n0) - group delay)`` puts that sample at exactly t = 0 (integer ns), and every
    later output on the 400 Hz grid from there.
    """
    d = design.decimation
    settle_n = math.ceil(design.settle_s() * design.acquisition_rate_hz)
    n0 = -(-settle_n // d) * d
    t0_ns = int(sample_times_ns(n0, 1, design.acquisition_rate_hz)[0])
    return t0_ns - design.group_delay_ns, n0 // d


def _first_output_sequence(design: AntiAliasDesign, preroll_ns: int) -> int:
    """The decimator's sequence number of the first output at or after t = 0 when the
    acquisition starts ``preroll_ns`` before zero (the real rate may differ from the
    requested one the pre-roll was computed for)."""
    d = design.decimation
    settle_n = math.ceil(design.settle_s() * design.acquisition_rate_hz)
    n = -(-settle_n // d) * d
    while (
        int(sample_times_ns(n, 1, design.acquisition_rate_hz)[0])
        - preroll_ns
        - design.group_delay_ns
        < 0
    ):
        n += d
    return n // d


def _event(t_ns: int, level: str, name: str, message: str) -> Event:
    return Event(max(0, int(t_ns)), level, name, message)


class CaptureMonitor(Protocol):
    """What watches a capture (the live view): it is handed every record right after the
    log has it, and must return at once (queue it, or drop it); the log never waits."""

    def samples(self, block: SampleBlock) -> None: ...
    def frame(self, frame: Frame) -> None: ...
    def event(self, event: Event) -> None: ...


class _Recorder:
    """The log writer, and the monitor that sees what was written once it was."""

    def __init__(self, writer: LogWriter, monitor: CaptureMonitor | None) -> None:
        self.writer = writer
        self.monitor = monitor

    def write_samples(self, block: SampleBlock) -> None:
        self.writer.write_samples(block)
        if self.monitor is not None and len(block):
            self.monitor.samples(block)

    def write_frame(self, frame: Frame) -> None:
        self.writer.write_frame(frame)
        if self.monitor is not None:
            self.monitor.frame(frame)

    def write_event(self, event: Event) -> None:
        self.writer.write_event(event)
        if self.monitor is not None:
            self.monitor.event(event)

    @property
    def last_log_time_ns(self) -> int | None:
        return self.writer.last_log_time_ns

    @property
    def last_flushed_log_time_ns(self) -> int | None:
        return self.writer.last_flushed_log_time_ns

    def flush(self) -> None:
        self.writer.flush()

    def maybe_flush(self) -> None:
        self.writer.maybe_flush()


def _check_out_path(out: Path) -> None:
    if out.exists():
        raise BeambenchError(f"{out}: already exists; choose another --out (never overwritten)")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise BeambenchError(f"{out}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise BeambenchError(f"{out}: the folder {parent} is not writable")


def _run_info(
    rig: Rig,
    daq_device: StrainDaq,
    camera_device: Camera | None,
    design: AntiAliasDesign,
    duration_s: float,
    realtime: bool,
    start_utc: datetime,
    preroll_ns: int,
) -> dict[str, Any]:
    cam = camera_device.describe() if camera_device is not None else None
    return {
        "run_id": uuid.uuid4().hex,
        "start_utc": start_utc.isoformat(timespec="microseconds").replace("+00:00", "Z"),
        "software_version": __version__,
        "backend_daq": daq_device.backend,
        "backend_camera": camera_device.backend if camera_device is not None else "none",
        "daq_device": daq_device.describe(),
        "camera_device": cam,
        "acquisition_rate_hz": float(daq_device.sample_rate_hz),
        "output_rate_hz": rig.daq.output_rate_hz,
        "camera_frame_rate_hz": cam.get("frame_rate_hz") if cam else None,
        "filter": design.describe(),
        "duration_requested_s": float(duration_s),
        "realtime": bool(realtime),
        "rig_source": rig.source,
        "preroll_s": preroll_ns * 1e-9,
        "run_clock": "int64 ns since the log's first sample; the DAQ started preroll_s "
        "earlier so the anti-alias filter had settled by then; sample times have the "
        "anti-alias group delay removed; frames are stamped at mid-exposure by the camera",
    }


def capture_run(
    rig: Rig,
    daq_device: StrainDaq,
    camera_device: Camera | None,
    out_path: str | os.PathLike[str],
    duration_s: float,
    *,
    realtime: bool,
    camera_info: dict[str, Any] | None = None,
    progress: ProgressFn | None = None,
    monitor: CaptureMonitor | None = None,
) -> CaptureSummary:
    """Record ``duration_s`` of run time from the devices into a new MCAP log.

    Parameters
    ----------
    rig : Rig
        Gauges, potentiometer and DAQ settings (filter spec, flush interval).
    daq_device : StrainDaq
        Not yet started; started and stopped here.
    camera_device : Camera or None
        Not yet started; ``None`` records the DAQ only.
    out_path : path
        New log file (an existing file is refused, never overwritten).
    duration_s : float
        Run time to record, s (the run clock, not the wall clock).
    realtime : bool
        Recorded in the metadata; in real time a frame that cannot be queued is dropped
        (an event) instead of waited for.
    camera_info : dict, optional
        ``foxglove.CameraCalibration`` content for ``/camera/info``.
    progress : callable, optional
        ``progress(captured_s, duration_s)`` after each DAQ block.
    monitor : CaptureMonitor, optional
        Sees every sample block, frame and event after the log has written it (the live
        view); it must not block.

    Raises
    ------
    BeambenchError
        Existing or unwritable output, a device error, or a failed write (the flushed
        part of the log is then recoverable with ``beambench recover``).
    KeyboardInterrupt
        Re-raised after the log is finished cleanly.
    """
    if not (isinstance(duration_s, int | float) and duration_s > 0 and duration_s < 1e6):
        raise BeambenchError(f"--duration must be a positive number of seconds, got {duration_s!r}")
    out = Path(out_path)
    _check_out_path(out)
    wall0 = time.monotonic()
    cpu0 = time.process_time()
    end_ns = round(duration_s * 1e9)
    c = _Counters()
    interrupted = False
    writer: LogWriter | None = None
    reader: _CameraReader | None = None
    try:
        design, start_utc, preroll_ns = _start_devices(rig, daq_device, camera_device)
        info = _run_info(
            rig, daq_device, camera_device, design, duration_s, realtime, start_utc, preroll_ns
        )
        try:
            writer = LogWriter(
                out,
                rig_json=rig.to_json(),
                run_info=info,
                camera_info=camera_info,
                flush_interval_s=rig.daq.flush_interval_s,
            )
        except OSError as exc:
            raise BeambenchError(f"{out}: cannot write: {exc.strerror or exc}") from None
        rec = _Recorder(writer, monitor)
        rec.write_event(_event(0, "info", "start", f"run {info['run_id']} started"))
        if camera_device is not None:
            fps = camera_device.describe().get("frame_rate_hz")
            period = 1.0 / fps if isinstance(fps, int | float) and fps > 0 else 1.0
            reader = _CameraReader(camera_device, end_ns, realtime, period)
            reader.start()
        try:
            first_seq = _first_output_sequence(design, preroll_ns)
            _loop(
                rig,
                daq_device,
                reader,
                rec,
                design,
                first_seq,
                end_ns,
                duration_s,
                c,
                progress,
                realtime=realtime,
            )
            rec.write_event(_event(end_ns, "info", "stop", "run finished"))
        except KeyboardInterrupt:
            interrupted = True
            writer.write_event(
                _event(_last_time(writer), "warning", "stop", "interrupted (Ctrl-C)")
            )
            raise
        except DaqError as exc:
            c.device_errors += 1
            writer.write_event(_event(_last_time(writer), "error", "device_error", f"DAQ: {exc}"))
            writer.write_event(
                _event(_last_time(writer), "error", "stop", "stopped by a device error")
            )
            raise BeambenchError(f"DAQ: {exc} (the log up to the failure is in {out})") from None
    except OSError as exc:
        if writer is None:
            raise BeambenchError(f"{out}: cannot write: {exc.strerror or exc}") from None
        _close_after_failure(writer)
        writer = None
        raise BeambenchError(
            f"{out}: writing the log failed ({exc.strerror or exc}); what was flushed before "
            f"can be restored with 'beambench recover {out} --out FIXED.mcap'"
        ) from None
    finally:
        if reader is not None:
            reader.stop_flag.set()
        for device in (camera_device, daq_device):
            if device is not None:
                try:
                    device.stop()
                except DaqError as exc:
                    log.warning("stopping %s failed: %s", device.backend, exc)
        if reader is not None:
            reader.join(timeout=5.0)
        if writer is not None:
            try:
                writer.close()
            except OSError as exc:
                raise BeambenchError(
                    f"{out}: finishing the log failed ({exc.strerror or exc}); what was "
                    f"flushed can be restored with 'beambench recover {out} --out FIXED.mcap'"
                ) from None
    assert writer is not None
    if reader is not None and reader.failure is not None:
        raise reader.failure
    return CaptureSummary(
        out_path=out,
        run_id=str(info["run_id"]),
        duration_s=duration_s,
        samples=writer.counts["/daq/samples"],
        frames=writer.counts["/camera/image"],
        events=writer.counts["/events"],
        dropped_samples=c.dropped_samples,
        dropped_frames=reader.dropped_frames if reader is not None else 0,
        overruns=c.overruns,
        clipping_events=c.clipping,
        device_errors=c.device_errors + (reader.device_errors if reader is not None else 0),
        acquisition_rate_hz=float(daq_device.sample_rate_hz),
        wall_time_s=time.monotonic() - wall0,
        cpu_time_s=time.process_time() - cpu0,
        flushes=writer.flush_count,
        interrupted=interrupted,
        log_bytes=out.stat().st_size,
    )


def _start_devices(
    rig: Rig, daq_device: StrainDaq, camera_device: Camera | None
) -> tuple[AntiAliasDesign, datetime, int]:
    """Start the DAQ a pre-roll before run-clock zero (computed at the requested rate),
    design the filter at its real rate, start the camera. Returns the design, the start
    time and the pre-roll (ns). Device problems become ``BeambenchError``."""
    try:
        preroll_ns, _ = preroll(design_antialias(rig.daq, rig.daq.acquisition_rate_hz))
    except ValueError as exc:
        raise BeambenchError(f"DAQ: {exc}") from None
    try:
        daq_device.start(first_sample_ns=-preroll_ns)
    except DaqError as exc:
        raise BeambenchError(f"DAQ: {exc}") from None
    start_utc = datetime.now(UTC)
    try:
        design = design_antialias(rig.daq, daq_device.sample_rate_hz)
    except ValueError as exc:
        raise BeambenchError(f"DAQ: {exc}") from None
    if camera_device is not None:
        try:
            camera_device.start()
        except DaqError as exc:
            raise BeambenchError(f"camera: {exc}") from None
    return design, start_utc, preroll_ns


def _last_time(writer: LogWriter) -> int:
    return writer.last_log_time_ns or 0


def _close_after_failure(writer: LogWriter) -> None:
    try:
        writer.close()
    except OSError as exc:  # the disk is still full: the flushed part stays recoverable
        log.info("%s: could not finish the log: %s", writer.path, exc)


def _loop(
    rig: Rig,
    daq_device: StrainDaq,
    reader: _CameraReader | None,
    writer: _Recorder,
    design: AntiAliasDesign,
    first_seq: int,
    end_ns: int,
    duration_s: float,
    c: _Counters,
    progress: ProgressFn | None,
    *,
    realtime: bool,
) -> None:
    """Read, filter and write until the stream has reached ``end_ns``: the acquisition
    runs a group delay past it, since each output is stamped a group delay before the
    input it comes from. Output sequences are renumbered from ``first_seq`` (the sample
    at t = 0) to 0."""
    stream = SampleStream(design, rig.gauges, rig.potentiometer)
    settle_ms = design.settle_s() * 1e3
    stop_ns = end_ns + design.group_delay_ns
    # In real time, flush by the data, not only by the wall clock: once what was written
    # since the last flush spans the flush interval. Blocks arrive one block duration
    # apart, so a wall-clock test alone (elapsed >= interval) skips a flush whenever a
    # block comes a little early. Faster than real time (a synthetic capture) the wall
    # clock decides, or a 60 s run written in 3 s would fsync 600 times.
    flush_ns = round(rig.daq.flush_interval_s * 1e9) if realtime else None
    timeout_s = max(1.0, 5.0 * rig.daq.block_duration_s)
    expected_seq = 0
    pending: list[Frame] = []
    camera_done = reader is None
    rate = daq_device.sample_rate_hz
    clipped_before: tuple[int, ...] = ()
    while True:
        block = daq_device.read_block(timeout_s)
        if len(block) == 0:
            continue
        t_first, t_last = int(block.t_ns[0]), int(block.t_ns[-1])
        for ev in block.events:
            if ev.name == "overrun":
                c.overruns += 1
            writer.write_event(ev)
        gap = block.first_sequence - expected_seq
        if gap > 0:
            c.dropped_samples += gap
            writer.write_event(
                _event(
                    t_first,
                    "warning",
                    "dropped_samples",
                    f"{gap} samples at {rate:g} Hz missing before sample {block.first_sequence}; "
                    f"the filter restarts on the new data and withholds its {settle_ms:.1f} ms "
                    "of settling",
                )
            )
        expected_seq = block.first_sequence + len(block)
        if block.clipped_channels and block.clipped_channels != clipped_before:
            # one event when clipping starts or moves to other channels, not every block
            c.clipping += 1
            names = ", ".join(CHANNEL_NAMES[i] for i in block.clipped_channels)
            writer.write_event(
                _event(t_first, "warning", "clipping", f"ADC range reached on {names}")
            )
        clipped_before = block.clipped_channels
        out = stream.process(block)
        samples = SampleBlock(
            out.t_ns,
            out.rocker_angle_rad,
            out.strain,
            out.raw_volts,
            out.first_sequence - first_seq,
        )
        keep = int((samples.t_ns < end_ns).sum())
        writer.write_samples(samples.slice(0, keep) if keep < len(samples) else samples)
        if reader is not None:
            reader.now_ns = t_last
            camera_done = _drain(reader, writer, pending, t_last, c, wait=False) or camera_done
        last, done = writer.last_log_time_ns, writer.last_flushed_log_time_ns
        if flush_ns is not None and last is not None and (done is None or last - done >= flush_ns):
            writer.flush()
        else:
            writer.maybe_flush()
        if progress is not None:
            progress(max(0.0, min(duration_s, (t_last + 1e9 / rate) * 1e-9)), duration_s)
        if t_last + 1e9 / rate >= stop_ns:
            break
    if reader is not None and not camera_done:
        # In real time the camera has 10 s to hand over its last frames; a fake camera
        # that renders slower than real time is waited for (it always finishes).
        deadline = time.monotonic() + (10.0 if reader.realtime else math.inf)
        while not _drain(reader, writer, pending, end_ns, c, wait=True):
            if time.monotonic() > deadline:
                writer.write_event(
                    _event(
                        end_ns,
                        "warning",
                        "dropped_frames",
                        "camera did not deliver its last frames in time",
                    )
                )
                break
    for frame in pending:
        _write_frame(writer, frame, c)


def _drain(
    reader: _CameraReader,
    writer: _Recorder,
    pending: list[Frame],
    upto_ns: int,
    c: _Counters,
    *,
    wait: bool,
) -> bool:
    """Move queued camera items to the log; frames later than ``upto_ns`` wait in
    ``pending``. Returns True once the camera reader has finished."""
    done = False
    while not (pending and pending[-1].t_ns > upto_ns):  # ahead of the DAQ: let it queue
        try:
            item = reader.out.get(timeout=0.1) if wait else reader.out.get_nowait()
        except queue.Empty:
            break
        if item is None:
            done = True
            break
        if isinstance(item, Event):
            writer.write_event(item)
        else:
            pending.append(item)
    while pending and pending[0].t_ns <= upto_ns:
        _write_frame(writer, pending.pop(0), c)
    return done


def _write_frame(writer: _Recorder, frame: Frame, c: _Counters) -> None:
    writer.write_frame(frame)
    c.frames += 1
