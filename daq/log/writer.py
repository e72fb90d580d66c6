"""Writing a run log: a chunked, compressed MCAP file that is safe to kill.

Every ``flush_interval_s`` (at most 1 s) the writer ends the chunk in progress and hands
it with its message indexes to the operating system, so ``recover_log`` can restore every
message written before the last flush if the process dies; it fsyncs at least once a
second (at the flush that ends a second since the last fsync), so a crash of the machine
itself loses at most about a second. A killed process loses nothing the kernel has: at
the rig's 0.1 s flush an fsync at every flush cost a tenth of the capture's CPU and
bought nothing against a kill (issue #19).
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
from pathlib import Path
from types import TracebackType
from typing import Any

from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.Log_pb2 import Log

from daq.errors import DaqInputError
from daq.log.format import (
    FORMAT_VERSION,
    PROFILE,
    SAMPLE_SCHEMA_BYTES,
    SAMPLE_SCHEMA_NAME,
    TOPIC_CAMERA_INFO,
    TOPIC_EVENTS,
    TOPIC_IMAGE,
    TOPIC_SAMPLES,
    check_camera_info,
    encode_camera_info,
    encode_event,
    encode_image_parts,
    encode_metadata,
    encode_samples,
    protobuf_schema,
    software_version,
    utc_zero_ns,
)
from daq.log.mcap_out import ChunkBuffer, McapOut
from daq.records import Event, Frame, SampleBlock

log = logging.getLogger(__name__)

# Chunks end at each flush (about once a second) or at this size, whichever comes first.
_CHUNK_SIZE = 8 * 1024 * 1024
# Frames are kept out of the chunks that hold samples and events (up to this many frames
# per chunk), so reading samples never decompresses images.
_FRAMES_PER_CHUNK = 8
# Longest time between fsyncs (design.md: the writer flushes at least once a second).
_SYNC_INTERVAL_S = 1.0


class LogWriter:
    """Write one run to an MCAP file (``shared/design.md``, "Run log (MCAP), version 1").

    Parameters
    ----------
    path : str or Path
        New file; an existing file is never overwritten (``FileExistsError``).
    rig_json : str
        ``Rig.to_json()``, stored as the ``rig`` metadata record.
    run_info : dict
        The ``run`` metadata record (run id, start_utc, versions, backends, rates...).
    camera_info : dict or None
        ``foxglove.CameraCalibration`` content (width, height, K (9), D,
        distortion_model) when intrinsics are known; written once on ``/camera/info``.
    flush_interval_s : float
        Longest time between flushes (0 < s <= 1).
    compression : str
        ``"zstd"``, ``"lz4"`` or ``"none"``.

    Use as a context manager, or call :meth:`close` in a ``finally``.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        rig_json: str,
        run_info: dict[str, Any],
        camera_info: dict[str, Any] | None = None,
        flush_interval_s: float = 1.0,
        compression: str = "zstd",
    ) -> None:
        if not 0 < flush_interval_s <= 1.0:
            raise DaqInputError(f"flush_interval_s must be in (0, 1] s, got {flush_interval_s!r}")
        try:
            rig = json.loads(rig_json)
        except (TypeError, json.JSONDecodeError) as exc:
            raise DaqInputError(f"rig_json must be a JSON object: {exc}") from None
        if not isinstance(rig, dict):
            raise DaqInputError("rig_json must be a JSON object")
        if not isinstance(run_info, dict):
            raise TypeError(f"run_info must be a dict, got {type(run_info).__name__}")
        cam = check_camera_info(camera_info) if camera_info is not None else None
        modes = {"zstd": "zstd", "lz4": "lz4", "none": ""}
        if compression not in modes:
            raise DaqInputError(f"compression must be one of {sorted(modes)}, got {compression!r}")
        self.path = Path(path)
        self.flush_interval_s = float(flush_interval_s)
        self._file = open(self.path, "xb")
        self._closed = False
        self._utc_zero_ns: int | None = None
        self.counts = {TOPIC_SAMPLES: 0, TOPIC_IMAGE: 0, TOPIC_CAMERA_INFO: 0, TOPIC_EVENTS: 0}
        self.flush_count = 0
        self.bytes_at_last_flush = 0
        self.sync_count = 0
        self._last_sync = -math.inf
        self.last_flushed_log_time_ns: int | None = None
        self._max_log_time_ns: int | None = None
        self._event_sequence = 0
        self._compression = modes[compression]
        # samples and events go to one chunk, frames (held) to chunks of their own
        self._chunk = ChunkBuffer()
        self._frames: list[Frame] = []
        try:
            # the data section's CRC is always written: the metadata has no other check
            self._mcap = McapOut(
                self._file, profile=PROFILE, library=f"beambench {software_version()}"
            )
            self._channels = self._register_channels()
            meta_rig = {"json": rig_json, **{k: json.dumps(v) for k, v in rig.items()}}
            self._mcap.metadata("rig", meta_rig)
            run = {"log_format_version": FORMAT_VERSION, **run_info}
            self._utc_zero_ns = utc_zero_ns(run_info)
            self._mcap.metadata("run", encode_metadata(run))
            if cam is not None:
                self._add(TOPIC_CAMERA_INFO, 0, encode_camera_info(cam), 0)
            self.flush()
        except BaseException:
            self._file.close()
            raise
        self._last_flush = time.monotonic()

    def _register_channels(self) -> dict[str, int]:
        ids = {}
        sid = self._mcap.schema(SAMPLE_SCHEMA_NAME, "jsonschema", SAMPLE_SCHEMA_BYTES)
        ids[TOPIC_SAMPLES] = self._mcap.channel(TOPIC_SAMPLES, "json", sid)
        for topic, cls in (
            (TOPIC_IMAGE, CompressedImage),
            (TOPIC_CAMERA_INFO, CameraCalibration),
            (TOPIC_EVENTS, Log),
        ):
            name, data = protobuf_schema(cls)
            sid = self._mcap.schema(name, "protobuf", data)
            ids[topic] = self._mcap.channel(topic, "protobuf", sid)
        return ids

    def _add(self, topic: str, t_ns: int, data: bytes, sequence: int) -> None:
        self._chunk.add(self._channels[topic], sequence, t_ns, time.time_ns(), (data,))
        self.counts[topic] += 1
        if self._max_log_time_ns is None or t_ns > self._max_log_time_ns:
            self._max_log_time_ns = t_ns

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"{self.path}: the log writer is closed")

    def write_samples(self, block: SampleBlock) -> None:
        """One ``/daq/samples`` message per sample; ``sequence`` = output-sample index."""
        self._check_open()
        if not isinstance(block, SampleBlock):
            raise TypeError(f"block must be a SampleBlock, got {type(block).__name__}")
        if len(block) == 0:
            return
        if int(block.t_ns[0]) < 0:
            raise ValueError("block.t_ns must be >= 0 (MCAP log times are unsigned)")
        messages = encode_samples(
            block.t_ns, block.rocker_angle_rad, block.strain, block.raw_volts, self._utc_zero_ns
        )
        self._chunk.add_many(
            self._channels[TOPIC_SAMPLES],
            block.first_sequence,
            block.t_ns.tolist(),
            time.time_ns(),
            messages,
        )
        if self._chunk.size >= _CHUNK_SIZE:
            self._end_chunk()
        self.counts[TOPIC_SAMPLES] += len(block)
        last = int(block.t_ns[-1])
        if self._max_log_time_ns is None or last > self._max_log_time_ns:
            self._max_log_time_ns = last
        self.maybe_flush()

    def write_frame(self, frame: Frame) -> None:
        """One ``/camera/image`` message (``foxglove.CompressedImage``)."""
        self._check_open()
        if not isinstance(frame, Frame):
            raise TypeError(f"frame must be a Frame, got {type(frame).__name__}")
        if frame.t_ns < 0:
            raise ValueError(f"frame.t_ns must be >= 0, got {frame.t_ns}")
        self._frames.append(frame)
        if len(self._frames) >= _FRAMES_PER_CHUNK:
            self._write_frame_chunk()
        self.maybe_flush()

    def _end_chunk(self) -> None:
        """Write the chunk of samples and events, with the log's compression."""
        self._mcap.write_chunk(self._chunk, self._compression)
        self._chunk = ChunkBuffer()

    def _write_frame_chunk(self) -> None:
        """End the chunk of samples and events, then write the held frames as a chunk.

        JPEG and PNG are compressed already: zstd gains ~2.5 % of their size and cost 0.6 %
        of a core at 15 frames/s, so the frame chunks are written uncompressed (MCAP's
        chunk records name their compression one by one; every reader handles ""), and
        the images go to the file without a copy."""
        if not self._frames:
            return
        self._end_chunk()
        chunk = ChunkBuffer()
        channel = self._channels[TOPIC_IMAGE]
        now = time.time_ns()
        for frame in self._frames:
            parts = encode_image_parts(frame.t_ns, frame.data, frame.encoding)
            chunk.add(channel, frame.sequence, frame.t_ns, now, parts)
            self.counts[TOPIC_IMAGE] += 1
            if self._max_log_time_ns is None or frame.t_ns > self._max_log_time_ns:
                self._max_log_time_ns = frame.t_ns
        self._frames.clear()
        self._mcap.write_chunk(chunk, "")

    def write_event(self, event: Event) -> None:
        """One ``/events`` message (``foxglove.Log``); also logged with ``logging``."""
        self._check_open()
        if not isinstance(event, Event):
            raise TypeError(f"event must be an Event, got {type(event).__name__}")
        t = max(0, event.t_ns)
        self._add(TOPIC_EVENTS, t, encode_event(event), self._event_sequence)
        self._event_sequence += 1
        log.info("event %s (%s): %s", event.name, event.level, event.message)
        self.maybe_flush()

    def maybe_flush(self) -> bool:
        """Flush if ``flush_interval_s`` has passed since the last flush."""
        if time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()
            return True
        return False

    def flush(self) -> None:
        """End the chunk in progress, hand it and its indexes to the operating system
        (what a killed process keeps), and fsync if a second has passed since the last."""
        self._check_open()
        self._write_frame_chunk()
        self._end_chunk()
        self._file.flush()
        now = time.monotonic()
        # fsync once a second: flushes come every flush_interval_s, so waiting for the
        # one at least a second less an interval after the last keeps the gap <= 1 s
        if now - self._last_sync >= _SYNC_INTERVAL_S - self.flush_interval_s:
            os.fsync(self._file.fileno())
            self._last_sync = now
            self.sync_count += 1
        self._last_flush = now
        self.flush_count += 1
        self.bytes_at_last_flush = self._file.tell()
        self.last_flushed_log_time_ns = self._max_log_time_ns

    def close(self) -> None:
        """Write the summary and footer, fsync, close. Safe to call twice; the file is
        closed even when finishing fails (what was flushed stays recoverable)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._write_frame_chunk()
            self._end_chunk()
            self._mcap.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
            self.last_flushed_log_time_ns = self._max_log_time_ns
        finally:
            self._file.close()

    @property
    def last_log_time_ns(self) -> int | None:
        """Latest log time written so far (flushed or not), ns."""
        return self._max_log_time_ns

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
