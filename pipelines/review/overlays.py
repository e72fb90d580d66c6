"""Streams a processed run to Rerun: frames with overlays, series, Fig. 11, events.

Computes every overlay first (pixels from the measurement and the simulation), then
hands them to ``pipelines.review.viewer.RunViewer`` — the only module that talks to Rerun.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from daq.imageinfo import image_encoding
from daq.log import LogError, iter_frames
from pipelines.process.frames import MeasuredFrame
from pipelines.process.run import Processed
from pipelines.review.display import DIFFERENCE_GAIN
from pipelines.review.previews import PREVIEW_MODES, RegionPreviews, region_note, whole_preview
from pipelines.review.viewer import FrameOverlay, RunViewer
from vision import FrameMeasurement, VisionError
from vision.codec import preview

FloatArray = NDArray[np.float64]


def beam_points_plane(
    clamp_m: FloatArray,
    hub_angle_rad: float,
    stations_m: FloatArray,
    lateral_m: FloatArray,
    longitudinal_m: FloatArray,
) -> FloatArray:
    """Plane points (S, 2) of a beam shape given in the hub frame from the clamp."""
    axis = np.array([np.cos(hub_angle_rad), np.sin(hub_angle_rad)])
    normal = np.array([-axis[1], axis[0]])  # toward increasing hub angle
    along = (stations_m + longitudinal_m)[:, None] * axis[None, :]
    return np.asarray(clamp_m[None, :] + along + lateral_m[:, None] * normal[None, :], float)


def magnified_difference(
    centreline_m: FloatArray,
    clamp_m: FloatArray,
    hub_angle_rad: float,
    sim_shape: tuple[FloatArray, FloatArray, FloatArray],
    gain: float,
) -> FloatArray:
    """Plane points (K, 2): the simulated beam plus ``gain`` times the measured centre
    line's lateral offset from it, at the centre line's points.

    A 0.2 mm difference is a tenth of a pixel on the bench's framing; twenty times it is
    visible. Points outside the simulated beam's span are dropped.
    """
    stations, lat, lon = sim_shape
    axis = np.array([np.cos(hub_angle_rad), np.sin(hub_angle_rad)])
    normal = np.array([-axis[1], axis[0]])
    rel = np.asarray(centreline_m, float) - clamp_m[None, :]
    along, across = rel @ axis, rel @ normal
    sim_along = stations + lon
    inside = (along >= sim_along[0]) & (along <= sim_along[-1])
    along, across = along[inside], across[inside]
    # a cubic through the stations: a straight line between them would itself differ from
    # the simulated shape by tens of micrometres, magnified like a real difference
    sim_across = not_a_knot_cubic(sim_along, lat, along)
    shown = sim_across + gain * (across - sim_across)
    return np.asarray(clamp_m[None, :] + np.outer(along, axis) + np.outer(shown, normal), float)


def not_a_knot_cubic(x: FloatArray, y: FloatArray, at: FloatArray) -> FloatArray:
    """The not-a-knot cubic spline through (``x``, ``y``) (``x`` increasing) at ``at``:
    scipy's ``CubicSpline(x, y)(at)`` to rounding, without its per-call checks (a
    frame's overlay built one, 0.2 ms, on each of a bench minute's 900 frames, in the
    serial step after them). Its slopes from the same equations (continuity of the
    second derivative inside, of the third at the second and last-but-one points),
    solved densely: the simulation's 21 stations."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = x.size
    if n < 4:  # scipy's own cases: a line, a parabola through three points
        return np.asarray(CubicSpline(x, y)(at), float)
    h = np.diff(x)
    d = np.diff(y) / h
    a = np.zeros((n, n))
    b = np.empty(n)
    i = np.arange(1, n - 1)
    a[i, i - 1] = h[1:]
    a[i, i] = 2.0 * (h[:-1] + h[1:])
    a[i, i + 1] = h[:-1]
    b[1:-1] = 3.0 * (h[1:] * d[:-1] + h[:-1] * d[1:])
    a[0, 0], a[0, 1] = h[1], h[0] + h[1]
    b[0] = ((h[0] + 2.0 * (h[0] + h[1])) * h[1] * d[0] + h[0] ** 2 * d[1]) / (h[0] + h[1])
    a[-1, -1], a[-1, -2] = h[-2], h[-1] + h[-2]
    b[-1] = (h[-1] ** 2 * d[-2] + (2.0 * (h[-2] + h[-1]) + h[-1]) * h[-2] * d[-1]) / (h[-2] + h[-1])
    m = np.linalg.solve(a, b)
    q = np.asarray(at, float)
    k = np.clip(np.searchsorted(x, q, side="right") - 1, 0, n - 2)
    t = q - x[k]
    hk = h[k]
    c2 = (3.0 * d[k] - 2.0 * m[k] - m[k + 1]) / hk
    c3 = (m[k] + m[k + 1] - 2.0 * d[k]) / hk**2
    return np.asarray(y[k] + t * (m[k] + t * (c2 + t * c3)), float)


def frame_overlay(
    m: FrameMeasurement,
    to_px: Callable[[FloatArray], FloatArray],
    sim_shape: tuple[FloatArray, FloatArray, FloatArray] | None,
    beam_length_m: float,
    *,
    scale: float = 1.0,
) -> FrameOverlay:
    """Overlay of one frame: what was measured, the rigid beam, the simulated shape and
    the measured - simulated difference magnified :data:`DIFFERENCE_GAIN` times.

    ``scale`` maps the measurement's pixels onto the displayed image's (a preview at
    1/``reduction`` of the size: pixel centres map as ``(p + 0.5) * scale - 0.5``).
    """
    if not m.ok:
        return FrameOverlay(ok=False, reason=m.reason)

    def shown(px: FloatArray) -> FloatArray:
        return np.asarray((np.asarray(px, float) + 0.5) * scale - 0.5, float)

    clamp = np.asarray(m.clamp_plane_m, float)
    axis = np.array([np.cos(m.hub_angle_rad), np.sin(m.hub_angle_rad)])
    rigid = to_px(np.stack([clamp, clamp + beam_length_m * axis]))
    sim_px = difference_px = None
    if sim_shape is not None:
        stations, lat, lon = sim_shape
        sim_px = shown(to_px(beam_points_plane(clamp, m.hub_angle_rad, stations, lat, lon)))
        diff = magnified_difference(
            m.centreline_plane_m, clamp, m.hub_angle_rad, sim_shape, DIFFERENCE_GAIN
        )
        if diff.shape[0] >= 2:
            difference_px = shown(to_px(diff))
    tip_px = to_px(np.asarray(m.tip_plane_m, float)[None, :])[0]
    return FrameOverlay(
        centreline_px=shown(m.centreline_px),
        hub_line_px=shown(m.hub_line_px),
        rigid_line_px=shown(rigid),
        sim_beam_px=sim_px,
        difference_px=difference_px,
        difference_gain=DIFFERENCE_GAIN,
        tip_px=shown(tip_px),
        ok=True,
        reason="",
    )


def displayed_frame(data: bytes, encoding: str, reduction: int) -> tuple[bytes, str, float]:
    """The frame as the recording shows it: as logged (``reduction`` 1) or a JPEG preview
    at 1/``reduction`` of its size (:func:`vision.codec.preview`); with the pixel scale."""
    if reduction == 1:
        return data, encoding, 1.0
    return preview(data, reduction), "jpeg", 1.0 / reduction


# Previews made ahead are kept in memory up to this many bytes (a bench minute at 1/2 size
# is about 90 MB); the frames past it are reduced while the recording is written.
PREVIEW_BUDGET_BYTES = 256 * 1024 * 1024
# frames sent to Rerun per call: 16 frames at 1/2 size are a chunk of about Rerun's own
# chunk size (1 MiB); a few hundred per chunk made the recording's close wait several
# times longer, one per call spent more CPU in Python (900 frames under load: 1.5-2.0 s
# CPU at 16 per call, 2.4 s one by one, 3.0 s at 256)
_FRAMES_PER_BATCH = 16
# whole previews are made this many at a time (each frame alone, the decode and encode
# outside the GIL): those left when the frames are measured use both cores, not one
_WHOLE_THREADS = 2
# the measured frames' bytes (given with their measurements) are held for the previews
# up to this many bytes; the frames past it are read from the log again
HELD_BYTES = 64 * 1024 * 1024


class FramePreviews:
    """The log's frames as the recording shows them (:class:`RegionPreviews`), made in a
    thread while the frames are measured, so the ``.rrd`` step after them only logs.

    Start it before ``process_run`` and give ``process_run`` its :meth:`feed` as
    ``on_measured``: most frames show only the measured region as that frame's
    (``mode="region"``), so the thread follows the measurements, made from the bytes the
    run read (given with them; up to :data:`HELD_BYTES` held, a frame given without its
    bytes or past them is read from the log again); ``mode="whole"`` makes
    every frame whole, ahead of them, :data:`_WHOLE_THREADS` at a time (each depends on
    its frame alone), so those left when the frames are measured do not leave a core
    idle. :func:`stream_processed` takes what it made (the decodes and the JPEG encodes
    run outside the GIL). Up to :data:`PREVIEW_BUDGET_BYTES` are kept; a failure (a frame
    that does not decode) is not raised here: that frame and the rest are made again, in
    order, where they always were.
    """

    def __init__(self, log_path: Path, reduction: int, mode: str = "whole") -> None:
        if mode not in PREVIEW_MODES:
            raise ValueError(f"mode must be one of {PREVIEW_MODES}, got {mode!r}")
        self.log_path = Path(log_path)
        self.reduction = int(reduction)
        self.mode = mode
        self.composer = (
            RegionPreviews(self.reduction, whole=mode == "whole")
            if self.reduction in (2, 4)
            else None
        )
        self._made: dict[int, tuple[bytes, str, float]] = {}
        self.wall_s = 0.0  # how long the thread took
        self.cpu_s = 0.0  # and the CPU time it used (its helper threads' too)
        self._helpers_cpu_s: list[float] = []
        self._stop = threading.Event()
        # (t_ns, sequence, measurement, bytes or None) of the frames fed, in that order
        self._measured: deque[tuple[int, int, FrameMeasurement, bytes | None]] = deque()
        self._fed: set[int] = set()
        self._held = 0  # bytes of the frames fed and not yet made
        self._fed_all = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="frame-previews", daemon=True)

    def start(self) -> FramePreviews:
        self._thread.start()
        return self

    def feed(self, frames: Iterable[MeasuredFrame]) -> None:
        """Measured frames, in the log's order, in any number at a time
        (``process_run``'s ``on_measured``); a frame given again is ignored."""
        if self.mode == "whole":
            return
        with self._cond:
            for f in frames:
                if f.sequence in self._fed:
                    continue
                self._fed.add(f.sequence)
                data = f.data
                if data is not None and self._held + len(data) > HELD_BYTES:
                    data = None  # read from the log again
                self._held += len(data) if data is not None else 0
                self._measured.append((f.t_ns, f.sequence, f.measurement, data))
            self._cond.notify_all()

    def _next_measured(self) -> tuple[int, int, FrameMeasurement, bytes | None] | None:
        """The next frame fed (t_ns, sequence, measurement, bytes or None), or None when
        no more will be."""
        with self._cond:
            while not self._measured:
                if self._fed_all or self._stop.is_set():
                    return None
                self._cond.wait(timeout=0.5)
            fed = self._measured.popleft()
            self._held -= len(fed[3]) if fed[3] is not None else 0
            return fed

    def _run(self) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            self._make()
        finally:
            self.wall_s = time.perf_counter() - t0
            self.cpu_s = time.thread_time() - c0 + sum(self._helpers_cpu_s)

    def _make(self) -> None:
        if self.composer is None:
            return
        if self.mode == "whole":
            self._make_whole(self.composer)
            return
        size = 0
        logged: Iterator[Any] | None = None  # the log, opened at the first frame fed bare
        try:
            while not (self._stop.is_set() or size > PREVIEW_BUDGET_BYTES):
                fed = self._next_measured()
                if fed is None:
                    return
                t_ns, sequence, m, data = fed
                if data is not None:
                    encoding = image_encoding(data) or ""  # as the log's reader tells it
                else:
                    if logged is None:
                        logged = iter_frames(self.log_path, start_ns=t_ns)
                    frame = next((f for f in logged if f.sequence == sequence), None)
                    if frame is None:
                        return  # not in the log from there on: made in stream_processed
                    data, encoding = frame.data, frame.encoding
                shown = self.composer.show(data, encoding, m)
                self._made[sequence] = shown
                size += len(shown[0])
        except (VisionError, LogError, OSError, ValueError):
            return  # the frames left are reduced in stream_processed, which reports it

    def _make_whole(self, composer: RegionPreviews) -> None:
        """:meth:`_make` of whole previews: the log read here, the frames made
        :data:`_WHOLE_THREADS` at a time, kept in the log's order (the same as one by
        one: up to the budget, up to the first that fails)."""
        size = 0
        pending: deque[tuple[int, Future[tuple[bytes, str, float]]]] = deque()

        def made(data: bytes) -> tuple[bytes, str, float]:
            c0 = time.thread_time()
            try:
                return whole_preview(data, composer.reduction)
            finally:
                self._helpers_cpu_s.append(time.thread_time() - c0)

        def keep() -> bool:  # the oldest made frame kept; False: no more are
            nonlocal size
            sequence, done = pending.popleft()
            if self._stop.is_set() or size > PREVIEW_BUDGET_BYTES:
                return False
            shown = done.result()
            self._made[sequence] = shown
            composer.whole_frames += 1
            size += len(shown[0])
            return True

        pool = ThreadPoolExecutor(_WHOLE_THREADS, thread_name_prefix="frame-previews")
        try:
            for frame in iter_frames(self.log_path):
                if self._stop.is_set() or size > PREVIEW_BUDGET_BYTES:
                    return
                try:
                    pending.append((frame.sequence, pool.submit(made, frame.data)))
                except RuntimeError:  # the interpreter is exiting (never stopped): no more
                    return
                if len(pending) > 2 * _WHOLE_THREADS and not keep():
                    return
            while pending:
                if not keep():
                    return
        except (VisionError, LogError, OSError, ValueError):
            return  # the frames left are reduced in stream_processed, which reports it
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def _finish(self) -> None:
        with self._cond:
            self._fed_all = True
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join()

    def stop(self) -> None:
        """Stop making previews (the run failed, or they were used); safe to repeat."""
        self._stop.set()
        self._finish()

    def take(self, frames: Iterable[MeasuredFrame] = ()) -> dict[int, tuple[bytes, str, float]]:
        """Wait for the thread (if started), given the run's measured ``frames`` (those
        not fed already); the previews it made, by frame sequence."""
        self.feed(frames)
        self._finish()
        return self._made


def stream_processed(
    processed: Processed,
    log_path: Path,
    viewer: RunViewer,
    *,
    frame_reduction: int = 2,
    previews: FramePreviews | None = None,
    frame_previews: str = "whole",
) -> None:
    """Log a processed run: results series, every frame with its overlays, events.

    Frames go in at 1/``frame_reduction`` of their size (2 by default: a 20 s run's
    recording loads in seconds; 1 keeps the logged frames as they are), made by
    :class:`~pipelines.review.previews.RegionPreviews` (``frame_previews`` "region": whole
    once a second, the measured region alone between; "whole": every frame whole), taken
    from ``previews`` where it made them that way (:class:`FramePreviews`), and sent to
    Rerun as columns, 16 frames per call.
    """
    if frame_previews not in PREVIEW_MODES:
        raise ValueError(f"frame_previews must be one of {PREVIEW_MODES}, got {frame_previews!r}")
    ds = processed.results
    region = frame_reduction > 1 and frame_previews == "region"
    viewer.log_results(ds, summary_note=region_note(frame_reduction) if region else "")
    sim = processed.sim
    lat = CubicSpline(sim.time_s, sim.station_lateral_m, axis=0)
    lon = CubicSpline(sim.time_s, sim.station_longitudinal_m, axis=0)
    t0_ns = int(ds.attrs.get("t_zero_ns", 0))
    frame_t = ds["frame_time"].values
    # the simulated shape at every frame's time within the simulation's, at once
    within = np.isfinite(frame_t) & (sim.time_s[0] <= frame_t) & (frame_t <= sim.time_s[-1])
    shapes = None
    if within.any():
        shapes = np.asarray(lat(frame_t[within])), np.asarray(lon(frame_t[within]))
    shape_row = np.cumsum(within) - 1
    by_seq = {f.sequence: (i, f) for i, f in enumerate(processed.frames)}
    length = processed.calibration.beam_length_m
    made: dict[int, tuple[bytes, str, float]] = {}
    composer = None
    if (
        previews is not None
        and previews.reduction == frame_reduction
        and previews.mode == frame_previews
    ):
        made = previews.take(processed.frames)
        composer = previews.composer  # continues where the thread stopped
    elif previews is not None:
        previews.stop()
    if composer is None and frame_reduction > 1:
        composer = RegionPreviews(frame_reduction, whole=frame_previews == "whole")
    times: list[float] = []
    images: list[bytes] = []
    encodings: list[str] = []
    overlays: list[FrameOverlay | None] = []

    def send() -> None:
        if times:
            viewer.log_frames(times, images, encodings, overlays)
            for column in (times, images, encodings, overlays):
                column.clear()

    for sequence, frame in _measured_in_log_order(log_path, processed.frames, made):
        hit = by_seq.get(sequence)
        if hit is None:
            continue
        i, measured = hit
        t = float(frame_t[i])
        shape = None
        if within[i] and shapes is not None:
            k = shape_row[i]
            shape = (sim.stations_m, shapes[0][k], shapes[1][k])
        shown = made.pop(sequence, None)
        if shown is None:
            assert frame is not None  # read from the log wherever no preview was made
            if composer is None:
                shown = displayed_frame(frame.data, frame.encoding, frame_reduction)
            else:
                shown = composer.show(frame.data, frame.encoding, measured.measurement)
        data, encoding, scale = shown
        overlay = frame_overlay(
            measured.measurement, processed.calibration.to_px, shape, length, scale=scale
        )
        times.append(t)
        images.append(data)
        encodings.append(encoding)
        overlays.append(overlay)
        if len(times) >= _FRAMES_PER_BATCH:
            send()
    send()
    viewer.log_events(processed.events, t0_ns=t0_ns)


def _measured_in_log_order(
    log_path: Path, frames: list[MeasuredFrame], made: dict[int, tuple[bytes, str, float]]
) -> Iterator[tuple[int, Any]]:
    """(sequence, the logged frame or None) of the log's frames in its order, the log
    read only where it is needed: not at all while ``made`` holds a preview of each
    measured frame (they were measured from this log, in its order), from the start
    again at the first without one (the previews thread stops at a frame and makes no
    later one), then every frame not given yet, as the log has them. A log whose frames
    repeat a sequence number is read whole, as before."""
    seqs = [f.sequence for f in frames]
    given: set[int] = set()
    if len(set(seqs)) == len(seqs):
        for seq in seqs:
            if seq not in made:
                break
            given.add(seq)
            yield seq, None
        else:
            return
    for f in iter_frames(log_path):
        if f.sequence not in given:
            yield f.sequence, f
