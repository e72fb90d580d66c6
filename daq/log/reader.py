"""Reading a run log back into the records the drivers produced."""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
import zstandard
from google.protobuf.message import DecodeError
from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, get_chunk_data_stream
from mcap.summary import Summary

from daq.errors import DaqInputError, LogError
from daq.log.format import (
    PROFILE,
    TOPIC_CAMERA_INFO,
    TOPIC_EVENTS,
    TOPIC_IMAGE,
    TOPIC_SAMPLES,
    TOPICS,
    BadMessageError,
    decode_camera_info,
    decode_event,
    decode_image,
    decode_metadata,
    decode_rig_record,
    decode_sample,
    decode_written_samples,
)
from daq.records import Event, Frame, SampleBlock

# what damaged bytes can raise when mcap and the message decoders parse them: lz4
# reports a bad chunk as RuntimeError; a garbage length gives OverflowError, or
# MemoryError when a chunk claims a huge uncompressed size
DAMAGED_DATA_ERRORS: tuple[type[BaseException], ...] = (
    McapError,
    EndOfFile,
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

_MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER = 0x02
_OP_CHUNK = 0x06
_OP_METADATA = 0x0C
_OP_DATA_END = 0x0F
_FOOTER_SIZE = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, offset start, CRC
_DATA_END_SIZE = 1 + 8 + 4
_CRC_BLOCK = 256 * 1024


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
        The ``rig`` metadata record's ``json`` entry (``Rig.to_json()``); "" when the
        record has none (another recorder's flat entries) or the log has no record.
    rig_record : dict or None
        The ``rig`` metadata record's entries as written (strings), None when the log has
        no ``rig`` record: what another recorder wrote is interpreted by the rig loader.
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
    rig_record: dict[str, str] | None = None


def _open(
    path: str | os.PathLike[str], *, verify_data: bool = True
) -> tuple[IO[bytes], SeekingReader, Summary]:
    """Open a log and verify what can be verified before reading messages: the magic,
    the header's profile, the footer, the summary section's CRC and (``verify_data``) the
    data section's CRC, which covers every byte before the summary (header, metadata,
    chunks, indexes). Chunk CRCs are checked as the chunks are read."""
    p = Path(path)
    try:
        f = open(p, "rb")
    except FileNotFoundError:
        raise LogError(str(p), "no such file", suggest_recover=False) from None
    except IsADirectoryError:
        raise LogError(str(p), "is a folder, not a log", suggest_recover=False) from None
    except OSError as exc:
        raise LogError(str(p), f"cannot open: {exc.strerror}", suggest_recover=False) from None
    try:
        size = os.fstat(f.fileno()).st_size
        try:
            reader = SeekingReader(f, validate_crcs=True, record_size_limit=max(size, 1))
            header = reader.get_header()
        except READ_ERRORS as exc:
            raise LogError(str(p), f"not an MCAP file ({exc})", suggest_recover=False) from None
        if header.profile != PROFILE:
            if verify_data:  # a damaged header is damage, not another kind of file
                data_end = _check_footer(p, f, size)
                _check_data_section(p, f, data_end)
            raise LogError(
                str(p),
                f"not a beambench log (MCAP profile {header.profile!r}, expected {PROFILE!r})",
                suggest_recover=False,
            )
        data_end = _check_footer(p, f, size)
        try:
            summary = reader.get_summary()
        except READ_ERRORS as exc:
            raise LogError(str(p), f"truncated or corrupt log: no valid summary ({exc})") from None
        if summary is None:
            raise LogError(str(p), "log has no summary (the writer did not finish)")
        if verify_data:
            _check_data_section(p, f, data_end)
    except BaseException:
        f.close()
        raise
    return f, reader, summary


def opens_as_log(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` opens as a beambench log: the magic, the profile, the footer and
    the summary (its CRC), without the data section's CRC (milliseconds, where reading
    the log takes a second a bench minute). For a caller that starts work ahead of the
    read (``process`` starts its frame workers): a file refused here is refused by
    :func:`read_run` at once, with its reason, and nothing need be started for it."""
    try:
        f, _, _ = _open(path, verify_data=False)
    except LogError:
        return False
    f.close()
    return True


def _check_footer(p: Path, f: IO[bytes], size: int) -> int:
    """Check the footer and the summary CRC; return where the data section's DataEnd
    record ends (the summary's start, or the footer's when there is no summary).
    A missing footer or a damaged summary is what ``beambench recover`` mends: it reads
    the data front to back and writes a new summary."""
    tail_size = _FOOTER_SIZE + len(_MAGIC)
    if size < len(_MAGIC) + tail_size:
        raise LogError(str(p), f"truncated log: {size} bytes, too short to hold a footer")
    footer_pos = size - tail_size
    f.seek(footer_pos)
    tail = f.read(tail_size)
    opcode, length, summary_start, _, summary_crc = struct.unpack("<BQQQI", tail[:_FOOTER_SIZE])
    if tail[_FOOTER_SIZE:] != _MAGIC or opcode != _OP_FOOTER or length != _FOOTER_SIZE - 9:
        raise LogError(str(p), "truncated or unfinished log: it does not end with a footer")
    if summary_start == 0:
        return footer_pos
    if not len(_MAGIC) < summary_start <= footer_pos:
        raise LogError(
            str(p), f"damaged footer at byte {footer_pos}: summary start {summary_start}"
        )
    if summary_crc != 0:
        f.seek(summary_start)
        crc = _crc(f, footer_pos + _FOOTER_SIZE - 4 - summary_start)
        if crc != summary_crc:
            raise LogError(
                str(p),
                f"damaged at bytes {summary_start}-{footer_pos + _FOOTER_SIZE}: the summary "
                "section fails its CRC",
            )
    return summary_start


def _crc(f: IO[bytes], n: int, crc: int = 0) -> int:
    """The CRC-32 of the next ``n`` bytes of ``f`` (fewer at its end), read into one
    buffer small enough to stay in the CPU's cache while the CRC reads it back (fresh
    16 MB blocks cost a fifth more for the data section)."""
    buf = memoryview(bytearray(max(0, min(n, _CRC_BLOCK))))
    while n > 0:
        got = f.readinto(buf[: min(n, _CRC_BLOCK)])  # type: ignore[attr-defined]
        if not got:
            break
        crc = zlib.crc32(buf[:got], crc)
        n -= got
    return crc


def _check_data_section(p: Path, f: IO[bytes], data_end: int) -> None:
    """Check the data-section CRC (stored in the DataEnd record just before
    ``data_end``; 0 means the writer did not compute one). Raises the located damage."""
    pos = data_end - _DATA_END_SIZE
    f.seek(max(pos, 0))
    record = f.read(_DATA_END_SIZE)
    if (
        pos < len(_MAGIC)
        or len(record) != _DATA_END_SIZE
        or record[0] != _OP_DATA_END
        or struct.unpack("<Q", record[1:9])[0] != 4
    ):
        # another writer's DataEnd (longer record), or damage: walk the records to it
        pos, stored = _find_data_end(p, f, data_end)
    else:
        (stored,) = struct.unpack("<I", record[9:])
    if stored == 0:
        return
    f.seek(0)
    if _crc(f, pos) != stored:
        raise _located_damage(p, f, pos, f"bytes 0-{pos} fail the data-section CRC")


def _find_data_end(p: Path, f: IO[bytes], end: int) -> tuple[int, int]:
    for offset, opcode, _ in _walk(p, f, end):
        if opcode == _OP_DATA_END:
            f.seek(offset + 9)
            (crc,) = struct.unpack("<I", f.read(4))
            return offset, crc
    raise LogError(str(p), f"damaged: no DataEnd record before byte {end}")


def _walk(p: Path, f: IO[bytes], end: int) -> Iterator[tuple[int, int, int]]:
    """(offset, opcode, length) of each record from the header to ``end``; a record
    running past ``end`` is damage at its offset."""
    offset = len(_MAGIC)
    while offset < end:
        f.seek(offset)
        head = f.read(9)
        if len(head) < 9:
            raise LogError(str(p), f"damaged at byte {offset}: a record is cut off")
        opcode, length = struct.unpack("<BQ", head)
        if offset + 9 + length > end:
            raise LogError(
                str(p),
                f"damaged at byte {offset}: a record (opcode 0x{opcode:02x}) claims "
                f"{length} bytes, past the end of the data section at byte {end}",
                suggest_recover=False,
            )
        yield offset, opcode, length
        offset += 9 + length


def _located_damage(p: Path, f: IO[bytes], end: int, fallback: str) -> LogError:
    """The first record before ``end`` that is damaged (a chunk failing its CRC or not
    decompressing, a metadata record that does not parse), as a LogError naming its
    byte offset; ``fallback`` when none can be found. ``beambench recover`` is not
    suggested: it cannot mend damaged contents."""
    try:
        for offset, opcode, length in _walk(p, f, end):
            if opcode == _OP_DATA_END:
                break
            if opcode not in (_OP_CHUNK, _OP_METADATA):
                continue
            f.seek(offset + 9)
            stream = ReadDataStream(io.BytesIO(f.read(length)))
            name = "?"
            try:
                if opcode == _OP_CHUNK:
                    get_chunk_data_stream(Chunk.read(stream), validate_crc=True)
                else:
                    meta = Metadata.read(stream)
                    name = meta.name
                    if meta.name == "run":
                        decode_metadata(dict(meta.metadata))
                    elif meta.name == "rig":
                        decode_rig_record(dict(meta.metadata))
            except DAMAGED_DATA_ERRORS as exc:
                what = "a chunk" if opcode == _OP_CHUNK else "corrupt metadata record"
                if isinstance(exc, CRCValidationError):
                    problem = f"{what} fails its CRC"
                elif opcode == _OP_METADATA:
                    problem = f"{what} '{name}' ({exc})"
                else:
                    problem = f"{what} cannot be read ({type(exc).__name__}: {exc})"
                return LogError(
                    str(p), f"damaged at byte {offset}: {problem}", suggest_recover=False
                )
    except LogError as exc:
        return exc
    return LogError(
        str(p),
        f"damaged: {fallback}; no chunk or metadata record does, so a header, schema, "
        "channel or index record changed",
        suggest_recover=False,
    )


def _messages(
    path: Path,
    f: IO[bytes],
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
        end = os.fstat(f.fileno()).st_size
        raise _located_damage(
            path, f, end, f"corrupt log data ({type(exc).__name__}: {exc})"
        ) from None


def _bad(p: Path, topic: str, message: Message, problem: str) -> LogError:
    return LogError(
        str(p),
        f"bad {topic} message (sequence {message.sequence}, log time {message.log_time} ns): "
        f"{problem}",
        suggest_recover=False,
    )


def _decode_sample(p: Path, message: Message) -> list[float]:
    try:
        t_ns, values = decode_sample(message.data)
    except BadMessageError as exc:
        raise _bad(p, TOPIC_SAMPLES, message, str(exc)) from None
    if t_ns != message.log_time:
        raise _bad(p, TOPIC_SAMPLES, message, f"its timestamp {t_ns} ns is not its log time")
    return values


def _decode_samples(p: Path, messages: list[Message]) -> np.ndarray:
    """The values (n, 10) of ``/daq/samples`` messages, each checked as
    :func:`_decode_sample` checks it, raising the first bad one's error: those in the
    writer's own form are read together (``decode_written_samples``), the others (and any
    whose time is not its log time) one by one, in order."""
    t_ns, values, ok = decode_written_samples([m.data for m in messages])
    if ok.any():
        # a log time beyond 2**63 ns matches no payload time: uint64 holds every log time
        log_times = np.fromiter((m.log_time for m in messages), np.uint64, len(messages))
        ok &= t_ns.astype(np.uint64) == log_times
    for i in np.flatnonzero(~ok).tolist():
        values[i] = _decode_sample(p, messages[i])
    return values


def _decode_frame(p: Path, message: Message) -> Frame:
    try:
        t_ns, data, kind, width, height = decode_image(message.data)
    except BadMessageError as exc:
        raise _bad(p, TOPIC_IMAGE, message, str(exc)) from None
    if t_ns != message.log_time:
        raise _bad(p, TOPIC_IMAGE, message, f"its timestamp {t_ns} ns is not its log time")
    return Frame(message.log_time, message.sequence, data, kind, width, height)


def _decode_other(p: Path, topic: str, message: Message) -> Any:
    try:
        if topic == TOPIC_EVENTS:
            return decode_event(message.data)
        return decode_camera_info(message.data)
    except (BadMessageError, ValueError) as exc:
        raise _bad(p, topic, message, str(exc)) from None


def _check_order(
    p: Path, topic: str, times: np.ndarray, seqs: np.ndarray, *, time_advances: bool
) -> np.ndarray:
    """The sequence order of a topic's messages, checked: no sequence number twice
    and (``time_advances``) log times strictly increasing with the sequence."""
    order = np.argsort(seqs, kind="stable")
    s = seqs[order]
    t = times[order]
    dup = np.flatnonzero(np.diff(s) == 0)
    if dup.size:
        k = int(dup[0]) + 1
        raise LogError(
            str(p),
            f"bad {topic} message (sequence {s[k]}, log time {t[k]} ns): sequence {s[k]} "
            f"appears twice (also at log time {t[k - 1]} ns)",
            suggest_recover=False,
        )
    if time_advances:
        back = np.flatnonzero(np.diff(t) <= 0)
        if back.size:
            k = int(back[0]) + 1
            raise LogError(
                str(p),
                f"bad {topic} message (sequence {s[k]}, log time {t[k]} ns): time does not "
                f"advance (sequence {s[k - 1]} is at {t[k - 1]} ns)",
                suggest_recover=False,
            )
    return order


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
    require_samples: bool = False,
) -> RunLog:
    """Read samples, events and metadata of a run log (frames are not loaded), verified
    as they are read: the file's CRCs (summary, data section, each chunk) and every
    message against its schema (``daq.log.format``), samples numbered without a repeat
    and advancing in time.

    Parameters
    ----------
    path : str or Path
    topics : iterable of str, optional
        Restrict to these topics (``/daq/samples``, ``/events``, ``/camera/info``;
        ``/camera/image`` is accepted and ignored here). Default: all.
    start_ns, end_ns : int, optional
        Half-open log-time window ``[start_ns, end_ns)`` on the run clock, ns.
    require_samples : bool
        A log without ``/daq/samples`` messages (in the window), or whose rocker angle
        or a gauge is null in every sample, is an error.

    Raises
    ------
    LogError
        Missing, truncated, damaged (naming the byte offset), a message that breaks its
        schema (naming topic, sequence and log time), not a beambench log, or no samples
        when ``require_samples``.
    """
    want = [t for t in _check_topics(topics) if t != TOPIC_IMAGE]
    p = Path(path)
    f, reader, summary = _open(p)
    with f:
        try:
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except READ_ERRORS as exc:
            raise LogError(str(p), f"corrupt metadata ({exc})") from None
        if "run" not in meta:
            raise LogError(
                str(p),
                "log lacks the 'run' metadata record (not written by beambench "
                "capture, or cut off before its first flush)",
                suggest_recover=False,
            )
        run_info = _metadata(p, "run", meta["run"], decode_metadata)
        # another recorder may store the rig as flat entries, or not at all: the rig
        # loader reads what it can (design.md, "Logs from other recorders")
        rig_record = meta.get("rig")
        rig_json = "" if rig_record is None else _metadata(p, "rig", rig_record, decode_rig_record)
        image_ids = [c.id for c in summary.channels.values() if c.topic == TOPIC_IMAGE]
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        frame_count = sum(counts.get(i, 0) for i in image_ids)
        sample_messages: list[Message] = []
        events: list[tuple[int, Event]] = []
        camera_info = None
        failure: Exception | None = None
        if want:
            # file order, sorted below: much faster than the reader's merge for 400 Hz
            messages = _messages(p, f, reader, want, start_ns, end_ns, ordered=False)
            try:
                for _, channel, message in messages:
                    if channel.topic == TOPIC_SAMPLES:
                        sample_messages.append(message)  # decoded together, below
                    elif channel.topic == TOPIC_EVENTS:
                        events.append((message.sequence, _decode_other(p, TOPIC_EVENTS, message)))
                    elif channel.topic == TOPIC_CAMERA_INFO:
                        camera_info = _decode_other(p, TOPIC_CAMERA_INFO, message)
            except Exception as exc:  # raised below, after the samples read before it
                failure = exc
    # a bad sample read before the failure (a bad event, a damaged record, anything the
    # reading raised) is the first error, as when each was decoded as it came
    values = _decode_samples(p, sample_messages)
    if failure is not None:
        raise failure
    t = _times_ns(p, TOPIC_SAMPLES, [m.log_time for m in sample_messages])
    s = np.asarray([m.sequence for m in sample_messages], dtype=np.int64)
    order = _check_order(p, TOPIC_SAMPLES, t, s, time_advances=True)
    if len(order) and np.any(np.diff(order) != 1):
        values = values[order]
        t, s = t[order], s[order]
    ev_seqs = np.asarray([q for q, _ in events], dtype=np.int64)
    ev_times = np.asarray([e.t_ns for _, e in events], dtype=np.int64)
    _check_order(p, TOPIC_EVENTS, ev_times, ev_seqs, time_advances=False)
    ordered_events = [e for _, e in events]
    ordered_events.sort(key=lambda e: e.t_ns)  # stable: same-time events keep file order
    if require_samples and not len(t):
        raise LogError(
            str(p),
            "no /daq/samples messages: the DAQ stream (rocker angle and strains) is missing"
            + (" in the time window" if start_ns is not None or end_ns is not None else ""),
            suggest_recover=False,
        )
    samples = _samples_block(t, values, s)
    if require_samples:
        _require_values(p, samples)
    return RunLog(
        path=p,
        samples=samples,
        events=ordered_events,
        rig_json=rig_json,
        run_info=run_info,
        camera_info=camera_info,
        frame_count=int(frame_count),
        sample_sequences=s,
        rig_record=rig_record,
    )


def _require_values(p: Path, samples: SampleBlock) -> None:
    """Each channel holds at least one number (null is the writer's missing value: a
    channel that is null throughout was never measured)."""
    channels = [("rocker angle", samples.rocker_angle_rad)] + [
        (f"gauge {g + 1} strain", samples.strain[:, g]) for g in range(samples.strain.shape[1])
    ]
    for name, values in channels:
        if not np.isfinite(values).any():
            raise LogError(
                str(p),
                f"/daq/samples: the {name} is null in all {len(values)} samples (never measured)",
                suggest_recover=False,
            )


def _metadata(p: Path, name: str, values: dict[str, str], decode: Any) -> Any:
    try:
        return decode(values)
    except BadMessageError as exc:
        raise LogError(
            str(p), f"corrupt metadata record '{name}': {exc}", suggest_recover=False
        ) from None


def _times_ns(path: Path, topic: str, times: list[int]) -> np.ndarray:
    try:
        return np.asarray(times, dtype=np.int64)
    except OverflowError:  # MCAP times are unsigned 64-bit: a damaged one can exceed int64
        raise LogError(
            str(path),
            f"bad {topic} message: a log time beyond 2**63 ns",
            suggest_recover=False,
        ) from None


def _samples_block(t: np.ndarray, values: np.ndarray, seqs: np.ndarray) -> SampleBlock:
    if not len(t):
        return SampleBlock.empty()
    return SampleBlock(t, values[:, 0], values[:, 1:5], values[:, 5:10], int(seqs[0]))


def iter_frames(
    path: str | os.PathLike[str],
    *,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> Iterator[Frame]:
    """Yield the ``/camera/image`` frames lazily, in log-time order, verified: the
    summary's and each chunk's CRC, each message a ``foxglove.CompressedImage`` holding
    a JPEG or PNG of a plausible size, frame counters and times advancing.

    ``Frame.sequence`` is the message sequence (the camera's frame counter); width and
    height come from the image header. Raises ``LogError`` for a damaged log or the
    first bad frame (naming its sequence and log time).
    """
    p = Path(path)
    f, reader, _ = _open(p, verify_data=False)  # the frames' chunks carry their own CRCs
    with f:
        last: Message | None = None
        for _, _, message in _messages(p, f, reader, [TOPIC_IMAGE], start_ns, end_ns):
            frame = _decode_frame(p, message)
            if last is not None:
                if message.sequence == last.sequence:
                    problem = f"sequence {message.sequence} appears twice"
                elif message.sequence < last.sequence:
                    problem = f"the frame counter runs backwards (from {last.sequence})"
                elif message.log_time == last.log_time:
                    problem = f"the same log time as frame {last.sequence}"
                else:
                    problem = ""
                if problem:
                    raise _bad(p, TOPIC_IMAGE, message, problem)
            last = message
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
    metadata names and size (for ``beambench info``). Every message of beambench's topics
    is verified as :func:`read_run` and :func:`iter_frames` do; other channels' messages
    are counted as they are. Raises ``LogError``."""
    p = Path(path)
    f, reader, summary = _open(p)
    with f:
        per: dict[int, tuple[list[int], list[int]]] = {cid: ([], []) for cid in summary.channels}
        # every channel is counted; another recorder's own channels (not beambench's
        # topics) are counted without decoding: their schemas are theirs
        every = sorted({c.topic for c in summary.channels.values()} | set(TOPICS))
        for _, channel, message in _messages(p, f, reader, every, None, None, ordered=False):
            if channel.topic == TOPIC_SAMPLES:
                _decode_sample(p, message)
            elif channel.topic == TOPIC_IMAGE:
                _decode_frame(p, message)
            elif channel.topic in TOPICS:
                _decode_other(p, channel.topic, message)
            t, s = per[channel.id]
            t.append(message.log_time)
            s.append(message.sequence)
        try:
            header = reader.get_header()
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except READ_ERRORS as exc:
            raise LogError(str(p), f"corrupt metadata ({exc})") from None
    if "run" in metadata:
        _metadata(p, "run", metadata["run"], decode_metadata)
    if "rig" in metadata:
        _metadata(p, "rig", metadata["rig"], decode_rig_record)
    stats = {}
    for cid, channel in summary.channels.items():
        schema = summary.schemas.get(channel.schema_id)
        t, s = per[cid]
        times = _times_ns(p, channel.topic, t)
        seqs = np.asarray(s, dtype=np.int64)
        if channel.topic in TOPICS:
            _check_order(p, channel.topic, times, seqs, time_advances=channel.topic != TOPIC_EVENTS)
        stats[channel.topic] = ChannelStats(
            channel.topic,
            schema.name if schema else "",
            channel.message_encoding,
            times,
            seqs,
        )
    info = {
        "profile": header.profile,
        "library": header.library,
        "metadata": metadata,
        "size_bytes": p.stat().st_size,
        "chunks": len(summary.chunk_indexes),
    }
    return stats, info
