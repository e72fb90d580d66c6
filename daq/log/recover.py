"""Salvaging a log whose writer died: every flushed chunk becomes a finished file."""

from __future__ import annotations

import logging
import os
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import EndOfFile
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from daq.errors import LogError
from daq.log.format import PROFILE, TOPIC_SAMPLES
from daq.log.reader import DAMAGED_DATA_ERRORS, read_run, scan_log

log = logging.getLogger(__name__)

# a truncated record, or damage past which the stream cannot be followed
_END_OF_DATA: tuple[type[BaseException], ...] = (EndOfFile, *DAMAGED_DATA_ERRORS)


@dataclass(frozen=True)
class RecoverySummary:
    """What :func:`recover_log` restored.

    ``complete`` is True when the input already had its footer (nothing was lost);
    ``truncated`` when it ended mid-record; ``bad_chunks`` counts chunks that were cut
    off or failed their CRC (their messages are lost: they were never fully flushed).
    """

    out_path: Path
    messages: int
    messages_by_topic: dict[str, int] = field(default_factory=dict)
    chunks: int = 0
    bad_chunks: int = 0
    metadata: tuple[str, ...] = ()
    complete: bool = False
    truncated: bool = False
    first_log_time_ns: int | None = None
    last_log_time_ns: int | None = None
    bytes_in: int = 0


def recover_log(
    broken_path: str | os.PathLike[str], out_path: str | os.PathLike[str]
) -> RecoverySummary:
    """Copy every intact record of ``broken_path`` into a new, finished ``out_path``.

    Reads the file front to back (no index needed), keeps the header, metadata, schemas,
    channels and every message of every chunk that is complete and passes its CRC, and
    stops at the first truncated record. ``out_path`` must not exist; it is written to a
    temporary file first and read back with the verifying reader (``read_run`` and
    ``scan_log``), so a failure never leaves a half-written or unreadable output.

    Raises
    ------
    LogError
        The input is missing, not MCAP, or not a beambench log; nothing usable could be
        restored (no message, no ``/daq/samples``, or what was restored fails
        verification, e.g. a message whose contents were damaged before they were
        written); or the data-section CRC shows damage outside the chunks.
    FileExistsError
        ``out_path`` exists.
    """
    src = Path(broken_path)
    dst = Path(out_path)
    if dst.exists():
        raise FileExistsError(f"{dst}: already exists; choose another --out")
    try:
        size = src.stat().st_size
        f = open(src, "rb")
    except FileNotFoundError:
        raise LogError(str(src), "no such file", suggest_recover=False) from None
    except OSError as exc:
        raise LogError(str(src), f"cannot open: {exc.strerror}", suggest_recover=False) from None

    header: Header | None = None
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    metadata: list[Metadata] = []
    messages: list[Message] = []
    chunks = bad_chunks = 0
    complete = truncated = False
    with f:
        reader = StreamReader(f, emit_chunks=True, validate_crcs=True, record_size_limit=size + 1)
        try:
            for record in reader.records:
                if isinstance(record, Header):
                    header = record
                elif isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Metadata):
                    metadata.append(record)
                elif isinstance(record, Chunk):
                    chunks += 1
                    try:
                        inner = breakup_chunk(record, validate_crc=True)
                    except DAMAGED_DATA_ERRORS as exc:
                        bad_chunks += 1
                        log.warning("%s: chunk %d unreadable (%s): skipped", src, chunks, exc)
                        continue
                    for r in inner:
                        if isinstance(r, Schema):
                            schemas[r.id] = r
                        elif isinstance(r, Channel):
                            channels[r.id] = r
                        elif isinstance(r, Message):
                            messages.append(r)
                elif isinstance(record, Message):
                    messages.append(record)
                elif isinstance(record, DataEnd | Footer):
                    complete = True
                    break
        except CRCValidationError as exc:
            if not isinstance(exc.record, DataEnd):
                truncated = True
            elif not bad_chunks:
                # every chunk passed its own CRC, so the damage is in a record that has
                # no CRC of its own (metadata, schema, channel): copying would launder it
                raise LogError(
                    str(src),
                    "damaged: the data-section CRC fails but every chunk passes its own, so "
                    "a metadata, schema or channel record changed; recover cannot tell which",
                    suggest_recover=False,
                ) from None
            else:  # the unreadable chunks explain it; their messages are dropped
                complete = True
        except _END_OF_DATA as exc:
            if header is None:
                raise LogError(
                    str(src), f"not an MCAP file ({exc})", suggest_recover=False
                ) from None
            truncated = True
    if header is None:
        raise LogError(str(src), "not an MCAP file (no header)", suggest_recover=False)
    if header.profile != PROFILE:
        raise LogError(
            str(src),
            f"not a beambench log (MCAP profile {header.profile!r})",
            suggest_recover=False,
        )

    topic_counts: Counter[str] = Counter()
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dst.name}.", suffix=".partial", dir=dst.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as out:
            writer = Writer(
                out,
                chunk_size=4 * 1024 * 1024,
                compression=CompressionType.ZSTD,
                enable_data_crcs=True,
            )
            writer.start(profile=header.profile, library=header.library)
            schema_ids = {
                sid: writer.register_schema(s.name, s.encoding, s.data)
                for sid, s in sorted(schemas.items())
            }
            channel_ids = {}
            for cid, c in sorted(channels.items()):
                channel_ids[cid] = writer.register_channel(
                    c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), c.metadata
                )
            for m in metadata:
                writer.add_metadata(m.name, dict(m.metadata))
            kept = 0
            for msg in messages:
                if msg.channel_id not in channel_ids:
                    continue  # its channel record was lost with a bad chunk
                writer.add_message(
                    channel_ids[msg.channel_id],
                    msg.log_time,
                    msg.data,
                    msg.publish_time,
                    msg.sequence,
                )
                topic_counts[channels[msg.channel_id].topic] += 1
                kept += 1
            writer.finish()
            out.flush()
            os.fsync(out.fileno())
        _check_usable(src, tmp, kept, topic_counts, chunks, bad_chunks)
        if dst.exists():
            raise FileExistsError(f"{dst}: already exists; choose another --out")
        os.replace(tmp, dst)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    times = [m.log_time for m in messages if m.channel_id in channel_ids]
    return RecoverySummary(
        out_path=dst,
        messages=kept,
        messages_by_topic=dict(topic_counts),
        chunks=chunks,
        bad_chunks=bad_chunks,
        metadata=tuple(m.name for m in metadata),
        complete=complete,
        truncated=truncated,
        first_log_time_ns=min(times) if times else None,
        last_log_time_ns=max(times) if times else None,
        bytes_in=size,
    )


def _check_usable(
    src: Path,
    restored: Path,
    kept: int,
    topic_counts: Counter[str],
    chunks: int,
    bad_chunks: int,
) -> None:
    """Refuse an output that holds nothing usable or does not read back verified."""
    lost = f"{chunks} chunk(s) read, {bad_chunks} unreadable"
    if kept == 0:
        raise LogError(
            str(src),
            f"nothing to recover: no message survived ({lost}; the writer died before "
            "its first flush, or the data is damaged)",
            suggest_recover=False,
        )
    if topic_counts[TOPIC_SAMPLES] == 0:
        found = ", ".join(f"{n} on {t}" for t, n in sorted(topic_counts.items()))
        raise LogError(
            str(src),
            f"nothing usable to recover: no /daq/samples message survived (only {found}; {lost})",
            suggest_recover=False,
        )
    try:
        read_run(restored, require_samples=True)
        scan_log(restored)
    except LogError as exc:
        raise LogError(
            str(src),
            f"the restored log does not read back: {exc.problem}",
            suggest_recover=False,
        ) from None
