"""The live view of a capture: what is being recorded, in Rerun, while it is recorded.

:class:`LiveView` is the capture's monitor (:class:`pipelines.acquire.capture.CaptureMonitor`):
the capture hands it each sample block, frame and event right after the log has it, and it
only queues them. A thread of its own sends them to a :class:`~pipelines.review.viewer.RunViewer`
in the ``live`` layout: rocker angle and strains at the full rate, events, and camera frames at a
reduced rate and size, each shown frame measured (the registration object is looked for until it
is found, then the hub angle and tip deflection of every shown frame are plotted, with the
measured centre line drawn on it). When the view falls behind, it drops what it has not shown
(frames first); the log never waits for it.
"""

from __future__ import annotations

import logging
import queue
import threading
from dataclasses import dataclass

import numpy as np

from daq.records import Event, Frame, SampleBlock
from pipelines.review.overlays import displayed_frame, frame_overlay
from pipelines.review.viewer import RunViewer
from pipelines.rig import Rig
from vision import Calibration, Measurer, calibration_from_registration, decode

log = logging.getLogger(__name__)

_STOP = object()


@dataclass
class LiveStats:
    """What the view showed and what it dropped (the log has everything)."""

    sample_blocks: int = 0
    frames_shown: int = 0
    frames_skipped: int = 0  # not due at the view's frame rate
    frames_measured: int = 0
    dropped: int = 0  # the view's queue was full


class LiveView:
    """A capture monitor that streams to ``viewer`` from a thread of its own.

    Parameters
    ----------
    viewer : an open :class:`RunViewer` (``layout="live"``).
    rig : the bench (registration object, camera intrinsics, beam length).
    frame_rate_hz : frames shown per second at most (the rest are skipped).
    frame_reduction : shown frames at 1/N size (2 or 4; 1 = as recorded).
    camera_info : the log's ``/camera/info`` (intrinsics for the registration), or None.
    queue_size : records waiting for the view before it drops what comes.
    """

    def __init__(
        self,
        viewer: RunViewer,
        rig: Rig,
        *,
        frame_rate_hz: float = 3.0,
        frame_reduction: int = 4,
        camera_info: dict[str, object] | None = None,
        queue_size: int = 256,
    ) -> None:
        if not frame_rate_hz > 0:
            raise ValueError(f"frame_rate_hz must be positive, got {frame_rate_hz!r}")
        self.viewer = viewer
        self.rig = rig
        self.frame_period_ns = round(1e9 / frame_rate_hz)
        self._slack_ns = round(0.5e9 / rig.camera.frame_rate_hz)
        self.frame_reduction = frame_reduction
        self.stats = LiveStats()
        self._camera_info = camera_info
        self._queue: queue.Queue[object] = queue.Queue(maxsize=queue_size)
        self._next_frame_ns: int | None = None
        self._calibration: Calibration | None = None
        self._measurer: Measurer | None = None
        self._thread = threading.Thread(target=self._run, name="live-view", daemon=True)
        self._thread.start()

    # -- the capture's side: never blocks ------------------------------------------------

    def _offer(self, item: object) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.stats.dropped += 1

    def samples(self, block: SampleBlock) -> None:
        self._offer(block)

    def frame(self, frame: Frame) -> None:
        # Frames are shown on a grid of the view's period; a frame within half a camera
        # period of its slot takes it (frame times jitter about their nominal spacing).
        due = self._next_frame_ns
        if due is not None and frame.t_ns < due - self._slack_ns:
            self.stats.frames_skipped += 1
            return
        due = frame.t_ns if due is None else due
        while due <= frame.t_ns + self._slack_ns:
            due += self.frame_period_ns
        self._next_frame_ns = due
        if self._queue.qsize() > self._queue.maxsize // 2:
            self.stats.dropped += 1  # frames give way first, so samples keep flowing
            return
        self._offer(frame)

    def event(self, event: Event) -> None:
        self._offer(event)

    def close(self, timeout_s: float = 30.0) -> LiveStats:
        """Show what is queued, stop the thread and return the statistics."""
        self._queue.put(_STOP)
        self._thread.join(timeout=timeout_s)
        return self.stats

    # -- the view's thread ------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            try:
                if isinstance(item, SampleBlock):
                    self.viewer.log_samples(item.t_ns * 1e-9, item.rocker_angle_rad, item.strain)
                    self.stats.sample_blocks += 1
                elif isinstance(item, Frame):
                    self._show(item)
                elif isinstance(item, Event):
                    self.viewer.log_events([item])
            except Exception:  # the view must never end the capture: say so once, go on
                log.exception("live view: could not show a %s", type(item).__name__)

    def _calibrate(self, image: np.ndarray) -> None:
        info = self._camera_info or {}
        k = info.get("K")
        d = info.get("D")
        try:
            self._calibration = calibration_from_registration(
                image,
                self.rig.registration,
                np.asarray(k, float).reshape(3, 3) if k is not None else None,
                np.asarray(d, float) if d is not None else None,
                beam_length_m=self.rig.beam.length_m,
                beam_width_m=self.rig.beam.width_m,
            )
        except ValueError as exc:
            if self.stats.frames_shown == 0:
                self.viewer.log_events(
                    [Event(0, "warning", "live_view", f"registration object not found yet: {exc}")]
                )
            return
        self._measurer = Measurer(self._calibration)

    def _show(self, frame: Frame) -> None:
        t_s = frame.t_ns * 1e-9
        data, encoding, scale = displayed_frame(frame.data, frame.encoding, self.frame_reduction)
        overlay = None
        if self._measurer is None:
            self._calibrate(decode(frame.data))
        if self._measurer is not None and self._calibration is not None:
            m = self._measurer.measure(decode(frame.data))
            self.stats.frames_measured += 1
            overlay = frame_overlay(
                m, self._calibration.to_px, None, self.rig.beam.length_m, scale=scale
            )
            self.viewer.log_tip_deflection(
                [t_s], [m.tip_lateral_m if m.ok else np.nan], np.zeros(0), np.zeros(0)
            )
        self.viewer.log_frame(t_s, data, encoding, overlay, frame_index=frame.sequence)
        self.stats.frames_shown += 1
