"""A lean MCAP writer for the run log's hot path: messages by the block, frames unchopped.

``mcap.writer.Writer`` builds every message through several Python calls and copies each
byte about five times (message into the chunk builder, chunk out of it, chunk into the
record builder, record out of it, into the file); at 400 samples and 15 frames of 2048 x
1536 JPEG a second that was most of the capture's CPU (issue #19). This writer packs a
block's message headers with one ``struct`` call each, builds a chunk's message indexes
with numpy, and hands the chunk to the file as the list of its pieces, so a frame's bytes
are copied once (into the kernel) and read twice (the chunk's CRC and the data
section's). The rare records (header, schemas, channels, metadata, the summary) use the
``mcap`` library's own record classes. The file is what ``mcap``'s writer makes, except
that schemas and channels precede the chunks in the data section instead of opening the
first chunk (both are valid MCAP; the summary repeats them as before).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence
from itertools import accumulate
from typing import IO

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
_U32 = 0xFFFFFFFF
# opcode, record length, channel id, sequence, log time, publish time (then the data)
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE_FIXED = 2 + 4 + 8 + 8
# opcode, record length, start, end, uncompressed size, uncompressed CRC
_CHUNK_HEAD = struct.Struct("<BQQQQI")
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, record length, channel id, entries' bytes
COMPRESSIONS = ("", "zstd", "lz4")

Piece = bytes | bytearray | memoryview

# CRC-32 (zlib's) of a concatenation from the parts' CRCs, as zlib's crc32_combine does
# it (multiplication by x^(8 n) modulo the CRC polynomial), so a frame chunk's bytes are
# read once for both the chunk's CRC and the data section's.
_POLY = 0xEDB88320


def _multmodp(a: int, b: int) -> int:
    m = 1 << 31
    p = 0
    while True:
        if a & m:
            p ^= b
            if a & (m - 1) == 0:
                return p
        m >>= 1
        b = (b >> 1) ^ _POLY if b & 1 else b >> 1


def _x2n_table() -> list[int]:
    table = [1 << 30]  # x^1
    for _ in range(31):
        table.append(_multmodp(table[-1], table[-1]))
    return table


_X2N = _x2n_table()


def crc32_combine(crc1: int, crc2: int, len2: int) -> int:
    """``zlib.crc32(a + b)`` from ``crc1 = zlib.crc32(a)``, ``crc2 = zlib.crc32(b)`` and
    ``len2 = len(b)``."""
    p = 1 << 31  # x^0
    n, k = len2, 3  # x^(8 len2)
    while n:
        if n & 1:
            p = _multmodp(_X2N[k & 31], p)
        n >>= 1
        k += 1
    return _multmodp(p, crc1) ^ crc2


class ChunkBuffer:
    """The messages of one chunk, kept as the list of their bytes until it is written."""

    def __init__(self) -> None:
        self.pieces: list[Piece] = []
        self.size = 0
        self.count = 0
        self.start_ns = 0
        self.end_ns = 0
        # per channel: (log times, offsets in the chunk's records)
        self._times: dict[int, list[int]] = {}
        self._offsets: dict[int, list[int]] = {}

    def _span(self, first_ns: int, last_ns: int) -> None:
        if self.count == 0:
            self.start_ns, self.end_ns = first_ns, last_ns
        else:
            self.start_ns = min(self.start_ns, first_ns)
            self.end_ns = max(self.end_ns, last_ns)

    def add(
        self,
        channel: int,
        sequence: int,
        log_ns: int,
        publish_ns: int,
        data: Sequence[Piece],
    ) -> None:
        """One message whose data is the concatenation of ``data`` (not copied)."""
        n = sum(len(d) for d in data)
        self._times.setdefault(channel, []).append(log_ns)
        self._offsets.setdefault(channel, []).append(self.size)
        self.pieces.append(
            _MESSAGE_HEAD.pack(
                Opcode.MESSAGE, _MESSAGE_FIXED + n, channel, sequence & _U32, log_ns, publish_ns
            )
        )
        self.pieces.extend(data)
        self._span(log_ns, log_ns)
        self.size += 9 + _MESSAGE_FIXED + n
        self.count += 1

    def add_many(
        self,
        channel: int,
        first_sequence: int,
        log_ns: list[int],
        publish_ns: int,
        data: list[bytes],
    ) -> None:
        """Messages ``first_sequence, first_sequence + 1, ...`` of one channel, their log
        times non-decreasing, packed into one piece."""
        if not data:
            return
        pack = _MESSAGE_HEAD.pack
        op = Opcode.MESSAGE
        sizes = [9 + _MESSAGE_FIXED + len(d) for d in data]
        heads = [
            pack(op, size - 9, channel, seq & _U32, t, publish_ns)
            for size, seq, t in zip(
                sizes, range(first_sequence, first_sequence + len(data)), log_ns, strict=True
            )
        ]
        offsets = list(accumulate(sizes, initial=self.size))
        self._times.setdefault(channel, []).extend(log_ns)
        self._offsets.setdefault(channel, []).extend(offsets[:-1])
        self.pieces.append(b"".join([x for pair in zip(heads, data, strict=True) for x in pair]))
        self._span(log_ns[0], log_ns[-1])
        self.size = offsets[-1]
        self.count += len(data)

    def message_indexes(self) -> list[tuple[int, bytes]]:
        """(channel id, its Message Index record), channels in the order first written."""
        out = []
        for channel, times in self._times.items():
            entries = np.empty((len(times), 2), dtype="<u8")
            entries[:, 0] = times
            entries[:, 1] = self._offsets[channel]
            body = entries.tobytes()
            head = _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 2 + 4 + len(body), channel, len(body))
            out.append((channel, head + body))
        return out

    def channel_counts(self) -> dict[int, int]:
        return {c: len(t) for c, t in self._times.items()}


class McapOut:
    """Write one MCAP file: header, schemas and channels, metadata, chunks with their
    message indexes, then (``finish``) the data end, the summary and the footer.

    Every byte of the data section passes through :meth:`_put`, which keeps its CRC.
    ``output`` is a binary file opened for writing, positioned at 0.
    """

    def __init__(self, output: IO[bytes], *, profile: str, library: str) -> None:
        self._out = output
        self._pos = 0
        self._crc = 0
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}
        self._message_count = 0
        self._start_ns = 0
        self._end_ns = 0
        # level 1: on the JSON samples as small as the default level 3 and a quarter faster
        self._zstd = zstandard.ZstdCompressor(level=1)
        self._put(MAGIC)
        self._put_record(Header(profile=profile, library=library))

    @property
    def position(self) -> int:
        """Bytes written so far."""
        return self._pos

    def _put(self, *pieces: Piece) -> None:
        for p in pieces:
            self._crc = zlib.crc32(p, self._crc)
            self._out.write(p)
            self._pos += len(p)

    def _put_record(self, record: Header | Schema | Channel | Metadata | DataEnd) -> int:
        builder = RecordBuilder()
        record.write(builder)
        data = builder.end()
        self._put(data)
        return len(data)

    def schema(self, name: str, encoding: str, data: bytes) -> int:
        sid = len(self._schemas) + 1
        schema = Schema(id=sid, data=data, encoding=encoding, name=name)
        self._schemas.append(schema)
        self._put_record(schema)
        return sid

    def channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        cid = len(self._channels) + 1
        channel = Channel(
            id=cid, topic=topic, message_encoding=message_encoding, schema_id=schema_id, metadata={}
        )
        self._channels.append(channel)
        self._counts[cid] = 0
        self._put_record(channel)
        return cid

    def metadata(self, name: str, data: dict[str, str]) -> None:
        offset = self._pos
        length = self._put_record(Metadata(name=name, metadata=data))
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))

    def write_chunk(self, chunk: ChunkBuffer, compression: str) -> None:
        """Write ``chunk`` (nothing when it is empty) and its message indexes."""
        if chunk.count == 0:
            return
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression must be one of {COMPRESSIONS}, got {compression!r}")
        if compression:
            records = b"".join(chunk.pieces)
            crc = zlib.crc32(records)
            if compression == "zstd":
                body: list[Piece] = [self._zstd.compress(records)]
            else:
                import lz4.frame

                body = [lz4.frame.compress(records)]
        else:  # written piece by piece: no copy of the frames before the kernel's
            body = chunk.pieces
            crc = 0
            for p in body:
                crc = zlib.crc32(p, crc)
        body_size = sum(len(p) for p in body)
        name = compression.encode()
        length = 8 + 8 + 8 + 4 + 4 + len(name) + 8 + body_size
        head = _CHUNK_HEAD.pack(
            Opcode.CHUNK, length, chunk.start_ns, chunk.end_ns, chunk.size, crc
        ) + struct.pack(f"<I{len(name)}sQ", len(name), name, body_size)
        start = self._pos
        if compression:
            self._put(head, *body)
        else:
            self._crc = crc32_combine(zlib.crc32(head, self._crc), crc, body_size)
            for p in (head, *body):
                self._out.write(p)
                self._pos += len(p)
        index_start = self._pos
        offsets = {}
        for channel, record in chunk.message_indexes():
            offsets[channel] = self._pos
            self._put(record)
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=chunk.start_ns,
                message_end_time=chunk.end_ns,
                chunk_start_offset=start,
                chunk_length=index_start - start,
                message_index_offsets=offsets,
                message_index_length=self._pos - index_start,
                compression=compression,
                compressed_size=body_size,
                uncompressed_size=chunk.size,
            )
        )
        for channel, n in chunk.channel_counts().items():
            self._counts[channel] += n
        if self._message_count == 0:
            self._start_ns, self._end_ns = chunk.start_ns, chunk.end_ns
        else:
            self._start_ns = min(self._start_ns, chunk.start_ns)
            self._end_ns = max(self._end_ns, chunk.end_ns)
        self._message_count += chunk.count

    def finish(self) -> None:
        """Data end (with the data section's CRC), summary, summary offsets, footer."""
        self._put_record(DataEnd(data_section_crc=self._crc))
        summary_start = self._pos
        builder = RecordBuilder()
        offsets: list[SummaryOffset] = []

        def group(opcode: Opcode, records: Sequence[Schema | Channel | Statistics]) -> None:
            if not records:
                return
            begin = builder.count
            for r in records:
                r.write(builder)
            offsets.append(SummaryOffset(opcode, summary_start + begin, builder.count - begin))

        group(Opcode.SCHEMA, self._schemas)
        group(Opcode.CHANNEL, self._channels)
        stats = Statistics(
            attachment_count=0,
            channel_count=len(self._channels),
            channel_message_counts=dict(self._counts),
            chunk_count=len(self._chunk_indexes),
            message_count=self._message_count,
            message_end_time=self._end_ns,
            message_start_time=self._start_ns,
            metadata_count=len(self._metadata_indexes),
            schema_count=len(self._schemas),
        )
        group(Opcode.STATISTICS, [stats])
        for opcode, items in (
            (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        ):
            if items:
                begin = builder.count
                for item in items:
                    item.write(builder)
                offsets.append(SummaryOffset(opcode, summary_start + begin, builder.count - begin))
        offset_start = summary_start + builder.count
        for o in offsets:
            o.write(builder)
        summary = builder.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start, offset_start), crc
        )
        tail = RecordBuilder()
        Footer(
            summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc
        ).write(tail)
        self._out.write(summary)
        self._out.write(tail.end())
        self._out.write(MAGIC)
