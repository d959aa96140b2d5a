"""The records of an MCAP file, read with bounded memory.

``dms record play``, ``dms record info`` and ``dms sim replay`` read files that may come
from anywhere. mcap's own reader inflates a whole chunk at the size its header claims:
a 10 KB file holding one zstd chunk of a 300 MB message takes about 1 GB. Here each
bound is checked before the memory is taken, and a record over it ends the reading
with :class:`TooLarge`, one line naming the limit and what to do:

- a record as stored (a compressed chunk, an attachment): :data:`MAX_RECORD_BYTES`;
- a chunk inflated: :data:`MAX_CHUNK_BYTES`, by what its header claims and by what it
  really inflates to (read in steps, never past the bound);
- a message: :data:`MAX_MESSAGE_BYTES`.

``dms record`` writes 16 KiB chunks of messages of a few kilobytes, far below them.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import IO

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import RecordLengthLimitExceeded
from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE
from mcap.records import (
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    Footer,
    McapRecord,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)
from mcap.stream_reader import MAGIC_SIZE, StreamReader
from mcap.summary import Summary

from sim.errors import RecordingError

MIB = 1024 * 1024
MAX_RECORD_BYTES = 64 * MIB
"""The largest record read as stored: a chunk before it is inflated, an attachment."""
MAX_CHUNK_BYTES = 64 * MIB
"""The largest chunk once inflated."""
MAX_MESSAGE_BYTES = 16 * MIB
"""The largest message."""
STEP_BYTES = 1 * MIB
"""How much of a chunk is inflated at a time, so that inflating never passes the bound."""
MESSAGE_HEADER_BYTES = 22
"""A message record's fields before its data: channel id, sequence, two times."""

REWRITE = (
    "dms record writes 16 KiB chunks: this file is damaged or comes from another recorder; "
    "rewrite it with smaller chunks (mcap compress --chunk-size 1048576 FILE -o OUT) "
    "or without the topic that holds it (mcap filter)"
)


class TooLarge(RecordingError):
    """A record over one of this module's bounds: the file is not read further."""


def _size(count: int) -> str:
    return f"{count / MIB:.1f} MiB" if count >= MIB else f"{count} bytes"


def mcap_records(stream: IO[bytes], name: str, skip_magic: bool = False) -> Iterator[McapRecord]:
    """The records of the MCAP ``stream`` (named ``name`` in refusals) in file order,
    a chunk's records in its place. mcap's errors (a truncated or corrupt file) pass
    through; a record over a bound raises :class:`TooLarge`. ``skip_magic``: ``stream``
    is at a record, not at the file's start."""
    reader = StreamReader(
        stream, skip_magic=skip_magic, emit_chunks=True, record_size_limit=MAX_RECORD_BYTES
    )
    records = reader.records
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except RecordLengthLimitExceeded as error:
            raise TooLarge(
                f"{name}: {error}: over the {_size(MAX_RECORD_BYTES)} a record may take; {REWRITE}"
            ) from None
        if isinstance(record, Chunk):
            yield from _chunk_records(record, name)
        elif isinstance(record, Message):
            _check_message(len(record.data), record.channel_id, name)
            yield record
        else:
            yield record


def _check_message(size: int, channel_id: int, name: str) -> None:
    if size > MAX_MESSAGE_BYTES:
        raise TooLarge(
            f"{name}: a message of {_size(size)} (channel {channel_id}) is over the "
            f"{_size(MAX_MESSAGE_BYTES)} a message may take; {REWRITE}"
        )


def _chunk_records(chunk: Chunk, name: str) -> Iterator[McapRecord]:
    """The schemas, channels and messages of one chunk; other records are skipped."""
    data = inflate(chunk, name)
    stream = ReadDataStream(io.BytesIO(data))
    while stream.count < len(data):
        opcode = stream.read1()
        length = stream.read8()
        if opcode == Opcode.MESSAGE:
            _check_message(max(0, length - MESSAGE_HEADER_BYTES), -1, name)
            yield Message.read(stream, length)
        elif opcode == Opcode.CHANNEL:
            yield Channel.read(stream)
        elif opcode == Opcode.SCHEMA:
            yield Schema.read(stream)
        else:
            stream.read(length)


def check_chunk_size(size: int, name: str, said: str = "") -> None:
    """TooLarge when a chunk of ``size`` bytes inflated is over :data:`MAX_CHUNK_BYTES`."""
    if size > MAX_CHUNK_BYTES:
        raise TooLarge(
            f"{name}: a chunk of {said}{_size(size)} inflated is over the "
            f"{_size(MAX_CHUNK_BYTES)} a chunk may hold; {REWRITE}"
        )


def inflate(chunk: Chunk, name: str) -> bytes:
    """The chunk's records, inflated in steps and never past :data:`MAX_CHUNK_BYTES`."""
    check_chunk_size(chunk.uncompressed_size, name)
    if chunk.compression == "":
        return bytes(chunk.data)
    if chunk.compression == "zstd":
        # The window is the memory zstd takes besides the output: no larger than a chunk.
        decompressor = zstandard.ZstdDecompressor(max_window_size=MAX_CHUNK_BYTES)
        reader = decompressor.stream_reader(io.BytesIO(chunk.data), read_across_frames=True)
    elif chunk.compression == "lz4":
        import lz4.frame

        reader = lz4.frame.LZ4FrameFile(io.BytesIO(chunk.data), mode="rb")
    else:
        raise RecordingError(
            f"{name}: a chunk compressed with {chunk.compression!r}, which is neither zstd "
            "nor lz4: it cannot be read"
        )
    out = bytearray()
    with reader:
        while True:
            try:
                step = reader.read(min(STEP_BYTES, MAX_CHUNK_BYTES + 1 - len(out)))
            except (zstandard.ZstdError, RuntimeError, OSError, EOFError) as error:
                raise RecordingError(f"{name}: a chunk cannot be inflated: {error}") from None
            if not step:
                return bytes(out)
            out += step
            check_chunk_size(len(out), name, said="more than ")


def read_summary(stream: IO[bytes], name: str) -> tuple[Summary | None, dict[str, dict[str, str]]]:
    """The summary section of a complete file and its metadata records, by name; (None,
    {}) for a file without one. mcap's own seeking reader would read them with its
    unbounded reader, and read the whole file through it when there is no summary."""
    stream.seek(-(FOOTER_SIZE + MAGIC_SIZE), io.SEEK_END)
    footer = next(mcap_records(stream, name, skip_magic=True), None)
    if not isinstance(footer, Footer) or footer.summary_start == 0:
        return None, {}
    stream.seek(footer.summary_start, io.SEEK_SET)
    summary = Summary()
    for record in mcap_records(stream, name, skip_magic=True):
        if isinstance(record, Statistics):
            summary.statistics = record
        elif isinstance(record, Schema):
            summary.schemas[record.id] = record
        elif isinstance(record, Channel):
            summary.channels[record.id] = record
        elif isinstance(record, AttachmentIndex):
            summary.attachment_indexes.append(record)
        elif isinstance(record, ChunkIndex):
            summary.chunk_indexes.append(record)
        elif isinstance(record, MetadataIndex):
            summary.metadata_indexes.append(record)
    metadata: dict[str, dict[str, str]] = {}
    for index in summary.metadata_indexes:
        stream.seek(index.offset, io.SEEK_SET)
        found = next(mcap_records(stream, name, skip_magic=True), None)
        if isinstance(found, Metadata):
            metadata.setdefault(found.name, dict(found.metadata))
    return summary, metadata
