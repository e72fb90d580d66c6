"""Reading a run log back into the records the drivers produced."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
import zstandard
from google.protobuf.message import DecodeError
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import CRCValidationError

from daq.errors import DaqInputError, LogError
from daq.imageinfo import image_size_px
from daq.log.format import (
    PROFILE,
    TOPIC_CAMERA_INFO,
    TOPIC_EVENTS,
    TOPIC_IMAGE,
    TOPIC_SAMPLES,
    TOPICS,
    decode_camera_info,
    decode_event,
    decode_image,
    decode_metadata,
    decode_sample,
)
from daq.records import Event, Frame, SampleBlock

# what damaged bytes can raise when mcap and the message decoders parse them: lz4
# reports a bad chunk as RuntimeError; a garbage length gives OverflowError, or
# MemoryError when a chunk claims a huge uncompressed size
DAMAGED_DATA_ERRORS: tuple[type[BaseException], ...] = (
    McapError,
    CRCValidationError,
    struct.error,
    zstandard.ZstdError,
    DecodeError,
    EOFError,
    KeyError,
    ValueError,
    UnicodeDecodeError,
    OverflowError,
    RuntimeError,
    MemoryError,
)
# reading through the index also seeks to offsets stored in the file: a garbage one
# fails the seek with OSError
READ_ERRORS: tuple[type[BaseException], ...] = (*DAMAGED_DATA_ERRORS, OSError)


@dataclass(frozen=True, eq=False)
class RunLog:
    """Everything in a run log except the images (see :func:`iter_frames`).

    Attributes
    ----------
    path : Path
    samples : SampleBlock
        All ``/daq/samples`` messages (in the time window), concatenated in time order.
        ``first_sequence`` is the first sample's sequence number.
    events : list of Event
    rig_json : str
        The ``rig`` metadata record (``Rig.to_json()``).
    run_info : dict
        The ``run`` metadata record.
    camera_info : dict or None
        ``/camera/info`` content (width, height, K, D, distortion_model).
    frame_count : int
        Number of ``/camera/image`` messages in the file.
    """

    path: Path
    samples: SampleBlock
    events: list[Event]
    rig_json: str
    run_info: dict[str, Any]
    camera_info: dict[str, Any] | None
    frame_count: int
    sample_sequences: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))


def _open(path: str | os.PathLike[str]) -> tuple[IO[bytes], SeekingReader]:
    p = Path(path)
    try:
        f = open(p, "rb")
    except FileNotFoundError:
        raise LogError(str(p), "no such file", suggest_recover=False) from None
    except OSError as exc:
        raise LogError(str(p), f"cannot open: {exc.strerror}", suggest_recover=False) from None
    try:
        reader = SeekingReader(f)
        header = reader.get_header()
    except READ_ERRORS as exc:
        f.close()
        raise LogError(str(p), f"not an MCAP file ({exc})", suggest_recover=False) from None
    except BaseException:
        f.close()
        raise
    if header.profile != PROFILE:
        f.close()
        raise LogError(
            str(p),
            f"not a beambench log (MCAP profile {header.profile!r}, expected {PROFILE!r})",
            suggest_recover=False,
        )
    try:
        summary = reader.get_summary()
    except READ_ERRORS as exc:
        f.close()
        raise LogError(str(p), f"truncated or corrupt log: no valid footer ({exc})") from None
    if summary is None:
        f.close()
        raise LogError(str(p), "log has no summary (the writer did not finish)")
    return f, reader


def _messages(
    path: Path,
    reader: SeekingReader,
    topics: Iterable[str],
    start_ns: int | None,
    end_ns: int | None,
    *,
    ordered: bool = True,
) -> Iterator[tuple[Schema | None, Channel, Message]]:
    try:
        yield from reader.iter_messages(
            topics=list(topics),
            starting_at=start_ns,
            ending_before=end_ns,
            log_time_order=ordered,
        )
    except READ_ERRORS as exc:
        raise LogError(str(path), f"corrupt log data ({type(exc).__name__}: {exc})") from None


def _check_topics(topics: Iterable[str] | None) -> list[str]:
    if topics is None:
        return list(TOPICS)
    if isinstance(topics, str):
        topics = [topics]
    topics = list(topics)
    unknown = sorted(set(topics) - set(TOPICS))
    if unknown:
        raise DaqInputError(f"topics: unknown topic {unknown[0]!r}; expected some of {TOPICS}")
    return topics


def read_run(
    path: str | os.PathLike[str],
    *,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> RunLog:
    """Read samples, events and metadata of a run log (frames are not loaded).

    Parameters
    ----------
    path : str or Path
    topics : iterable of str, optional
        Restrict to these topics (``/daq/samples``, ``/events``, ``/camera/info``;
        ``/camera/image`` is accepted and ignored here). Default: all.
    start_ns, end_ns : int, optional
        Half-open log-time window ``[start_ns, end_ns)`` on the run clock, ns.

    Raises
    ------
    LogError
        Missing, truncated, corrupt or not a beambench log.
    """
    want = [t for t in _check_topics(topics) if t != TOPIC_IMAGE]
    p = Path(path)
    f, reader = _open(p)
    with f:
        try:
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            summary = reader.get_summary()
        except READ_ERRORS as exc:
            raise LogError(str(p), f"corrupt metadata ({exc})") from None
        assert summary is not None
        if "rig" not in meta or "run" not in meta:
            raise LogError(
                str(p),
                "log lacks the 'rig' or 'run' metadata record (not written by beambench "
                "capture, or cut off before its first flush)",
                suggest_recover=False,
            )
        try:
            run_info = decode_metadata(meta["run"])
        except READ_ERRORS as exc:
            raise LogError(str(p), f"corrupt metadata ({exc})") from None
        image_ids = [c.id for c in summary.channels.values() if c.topic == TOPIC_IMAGE]
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        frame_count = sum(counts.get(i, 0) for i in image_ids)
        times: list[int] = []
        seqs: list[int] = []
        rows: list[list[Any]] = []
        events: list[Event] = []
        camera_info = None
        if want:
            # file order, sorted below: much faster than the reader's merge for 400 Hz
            for _, channel, message in _messages(p, reader, want, start_ns, end_ns, ordered=False):
                try:
                    if channel.topic == TOPIC_SAMPLES:
                        t, values = decode_sample(message.data)
                        times.append(t)
                        seqs.append(message.sequence)
                        rows.append(values)
                    elif channel.topic == TOPIC_EVENTS:
                        events.append(decode_event(message.data))
                    elif channel.topic == TOPIC_CAMERA_INFO:
                        camera_info = decode_camera_info(message.data)
                except READ_ERRORS as exc:
                    raise LogError(
                        str(p),
                        f"bad {channel.topic} message at log time {message.log_time} "
                        f"({type(exc).__name__}: {exc})",
                    ) from None
    order = np.argsort(_times_ns(p, TOPIC_SAMPLES, times), kind="stable")
    if len(order) and np.any(np.diff(order) != 1):
        times = [times[i] for i in order]
        rows = [rows[i] for i in order]
        seqs = [seqs[i] for i in order]
    events.sort(key=lambda e: e.t_ns)  # stable: same-time events keep their file order
    samples = _samples_block(times, rows, seqs)
    return RunLog(
        path=p,
        samples=samples,
        events=events,
        rig_json=meta["rig"].get("json", ""),
        run_info=run_info,
        camera_info=camera_info,
        frame_count=int(frame_count),
        sample_sequences=np.asarray(seqs, dtype=np.int64),
    )


def _times_ns(path: Path, topic: str, times: list[int]) -> np.ndarray:
    try:
        return np.asarray(times, dtype=np.int64)
    except OverflowError:  # MCAP times are unsigned 64-bit: a damaged one can exceed int64
        raise LogError(str(path), f"corrupt log data ({topic} time beyond 2**63 ns)") from None


def _samples_block(times: list[int], rows: list[list[Any]], seqs: list[int]) -> SampleBlock:
    if not times:
        return SampleBlock.empty()
    arr = np.array(rows, dtype=np.float64)  # None (JSON null) -> nan
    return SampleBlock(
        np.array(times, dtype=np.int64), arr[:, 0], arr[:, 1:5], arr[:, 5:10], seqs[0]
    )


def iter_frames(
    path: str | os.PathLike[str],
    *,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> Iterator[Frame]:
    """Yield the ``/camera/image`` frames lazily, in log-time order.

    ``Frame.sequence`` is the message sequence (the camera's frame counter); width and
    height come from the image header. Raises ``LogError`` for a damaged log.
    """
    p = Path(path)
    f, reader = _open(p)
    with f:
        for _, _, message in _messages(p, reader, [TOPIC_IMAGE], start_ns, end_ns):
            try:
                _, data, fmt = decode_image(message.data)
                width, height = image_size_px(data)
                frame = Frame(message.log_time, message.sequence, data, fmt, width, height)
            except READ_ERRORS as exc:
                raise LogError(
                    str(p), f"bad image at log time {message.log_time} ({exc})"
                ) from None
            yield frame


@dataclass(frozen=True)
class ChannelStats:
    """Per-topic index of a log: log times and sequence numbers of every message."""

    topic: str
    schema_name: str
    message_encoding: str
    log_time_ns: np.ndarray
    sequence: np.ndarray


def scan_log(path: str | os.PathLike[str]) -> tuple[dict[str, ChannelStats], dict[str, Any]]:
    """Log times and sequences of every message per topic, plus the file's header,
    metadata names and size (for ``beambench info``). Raises ``LogError``."""
    p = Path(path)
    f, reader = _open(p)
    with f:
        summary = reader.get_summary()
        assert summary is not None
        per: dict[int, tuple[list[int], list[int]]] = {cid: ([], []) for cid in summary.channels}
        for _, channel, message in _messages(p, reader, TOPICS, None, None, ordered=False):
            t, s = per[channel.id]
            t.append(message.log_time)
            s.append(message.sequence)
        try:
            header = reader.get_header()
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except READ_ERRORS as exc:
            raise LogError(str(p), f"corrupt metadata ({exc})") from None
    stats = {}
    for cid, channel in summary.channels.items():
        schema = summary.schemas.get(channel.schema_id)
        t, s = per[cid]
        stats[channel.topic] = ChannelStats(
            channel.topic,
            schema.name if schema else "",
            channel.message_encoding,
            _times_ns(p, channel.topic, t),
            np.asarray(s, dtype=np.int64),
        )
    info = {
        "profile": header.profile,
        "library": header.library,
        "metadata": metadata,
        "size_bytes": p.stat().st_size,
        "chunks": len(summary.chunk_indexes),
    }
    return stats, info
