"""Record-by-record reading of an MCAP file that survives cuts and corrupt bytes.

Every MCAP record is framed as opcode (1 byte), content length (uint64 LE),
content. This reader takes each record's content as one block and parses it
on its own, so a record whose inner fields lie (a length that runs past its
block, bytes that do not decompress, a chunk whose CRC fails) is lost alone:

- a chunk whose framing holds but whose content is bad (CRC mismatch, zstd
  error, a malformed record inside) is skipped, and the message indexes the
  writer put after it say which channels lost how many messages;
- where the framing itself is broken (an unknown opcode, a length past the
  end of the file, a block that does not parse), reading resumes at the
  next chunk that decompresses and passes its CRC; what lay between is
  lost, with its log-time range taken from the good chunks on either side;
- a file that simply ends inside a record (a cut) keeps everything before.

The mcap library's stream reader skips records with unknown opcodes, reads
a chunk's data length from inside the chunk even if it runs past the record,
and stops for good at the first exception; a few corrupt bytes in the middle
of an hour's log lost everything after them.
"""

from __future__ import annotations

import mmap
import struct
from io import BytesIO

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (Attachment, AttachmentIndex, Channel, Chunk, ChunkIndex, DataEnd, Footer, Header,
                          Message, MessageIndex, Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
from mcap.stream_reader import breakup_chunk

__all__ = ["MAGIC", "scan_records"]

MAGIC = b"\x89MCAP0\r\n"
_READERS = {
    Opcode.HEADER: Header.read, Opcode.FOOTER: Footer.read, Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read, Opcode.MESSAGE_INDEX: MessageIndex.read,
    Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.ATTACHMENT: Attachment.read,
    Opcode.ATTACHMENT_INDEX: AttachmentIndex.read, Opcode.STATISTICS: Statistics.read,
    Opcode.METADATA: Metadata.read, Opcode.METADATA_INDEX: MetadataIndex.read,
    Opcode.SUMMARY_OFFSET: SummaryOffset.read, Opcode.DATA_END: DataEnd.read,
}
# Opcodes 0x80 and up are the user's own (the MCAP spec): skipped, not corruption.
_USER_OPCODES = 0x80
_COMPRESSIONS = (b"", b"zstd", b"lz4")


class Corrupt(Exception):
    """A record whose framing or content is not MCAP."""


def _parse(opcode, content):
    if opcode in _READERS or opcode == Opcode.MESSAGE:
        stream = ReadDataStream(BytesIO(content))
        try:
            record = (Message.read(stream, len(content)) if opcode == Opcode.MESSAGE
                      else _READERS[opcode](stream))
        except Exception as exc:  # noqa: BLE001 - any parse failure is corruption of this block
            raise Corrupt(f"opcode 0x{opcode:02x}: {type(exc).__name__}") from None
        if stream.count > len(content):
            raise Corrupt(f"opcode 0x{opcode:02x}: fields run past the record")
    elif opcode >= _USER_OPCODES:
        return None
    else:
        raise Corrupt(f"unknown opcode 0x{opcode:02x}")
    if isinstance(record, Chunk) and stream.count != len(content):
        raise Corrupt("chunk data length disagrees with the record length")
    return record


def _chunk_at(buf, p, size):
    """The chunk framed at byte ``p`` if it is a whole, decompressible chunk that passes its CRC."""
    if p + 9 + 36 > size or buf[p] != Opcode.CHUNK:
        return None
    (length,) = struct.unpack_from("<Q", buf, p + 1)
    q = p + 9
    if q + length > size:
        return None
    start_ns, end_ns, _, _, clen = struct.unpack_from("<QQQII", buf, q)
    if start_ns > end_ns or clen > 4 or q + 32 + clen + 8 > size:
        return None
    if bytes(buf[q + 32: q + 32 + clen]) not in _COMPRESSIONS:
        return None
    (dlen,) = struct.unpack_from("<Q", buf, q + 32 + clen)
    if 32 + clen + 8 + dlen != length:
        return None
    try:
        chunk = _parse(Opcode.CHUNK, bytes(buf[q: q + length]))
        return chunk, breakup_chunk(chunk, validate_crc=True)
    except Exception:  # noqa: BLE001 - not a chunk after all
        return None


def _resync(buf, start, size):
    """(byte, chunk, its records) of the first good chunk at or after ``start``, or None."""
    p = buf.find(bytes([Opcode.CHUNK]), start)
    while p != -1:
        found = _chunk_at(buf, p, size)
        if found is not None:
            return (p, *found)
        p = buf.find(bytes([Opcode.CHUNK]), p + 1)
    return None


def scan_records(fh, size, on_record, report):
    """Read every record of an open MCAP file from after its magic bytes.

    Parameters
    ----------
    fh : binary file
        Positioned anywhere; read through a memory map.
    size : int
        The file's size (bytes).
    on_record : callable
        ``on_record(record)`` for each record read, chunks' inner records
        included, in file order (the chunk itself is not passed).
    report : dict
        Filled in: ``bytes_recovered`` (the end of the last good record),
        ``complete`` (footer and closing magic read), ``data_complete``
        (DataEnd read), ``chunks`` (good ones), ``error`` (why reading ended
        early, or None) and ``lost_chunks``: one dict per damaged stretch,
        ``from_byte``, ``to_byte``, ``first_log_time_ns``,
        ``last_log_time_ns`` (None where unknown), ``messages_by_channel_id``
        ({channel id: messages}, from the message indexes after the chunk,
        None where not known) and ``reason``.
    """
    report.setdefault("lost_chunks", [])
    if size <= len(MAGIC):
        return
    with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        _scan(buf, size, on_record, report)


def _scan(buf, size, on_record, report):
    lost = report["lost_chunks"]
    pos = len(MAGIC)
    last_end_ns = None  # log time of the last good chunk's end: bounds a lost stretch
    indexed = None  # the lost chunk the following message indexes describe
    while pos < size:
        if pos + 9 > size:
            report["error"] = f"file ends at byte {size} inside a record"
            return
        opcode = buf[pos]
        (length,) = struct.unpack_from("<Q", buf, pos + 1)
        end = pos + 9 + length
        try:
            if end > size:  # a cut, or a corrupt length: told apart by what follows
                raise Corrupt(f"record at byte {pos} runs {end - size} bytes past the end of the file")
            record = _parse(opcode, bytes(buf[pos + 9: end]))
        except Corrupt as exc:
            found = _resync(buf, pos + 1, size)
            if found is None:
                cut = end > size and opcode in _READERS
                report["error"] = (f"file ends at byte {size} inside a record" if cut
                                   else f"unreadable record after byte {pos}: {exc}")
                return
            p, chunk, inner = found
            lost.append({"from_byte": pos, "to_byte": p, "first_log_time_ns": last_end_ns,
                         "last_log_time_ns": chunk.message_start_time, "messages_by_channel_id": None,
                         "reason": str(exc)})
            indexed = None
            pos = p + 9 + struct.unpack_from("<Q", buf, p + 1)[0]
            _take_chunk(chunk, inner, on_record, report)
            last_end_ns = chunk.message_end_time
            report["bytes_recovered"] = pos
            continue
        if isinstance(record, Chunk):
            try:
                inner = breakup_chunk(record, validate_crc=True)
            except Exception as exc:  # noqa: BLE001 - framing held, content did not
                first = (str(exc).splitlines() or [""])[0]
                indexed = {"from_byte": pos, "to_byte": end, "first_log_time_ns": record.message_start_time,
                           "last_log_time_ns": record.message_end_time, "messages_by_channel_id": {},
                           "reason": f"{type(exc).__name__} {first}".strip()}
                lost.append(indexed)
                pos = end
                continue
            _take_chunk(record, inner, on_record, report)
            last_end_ns = record.message_end_time
            indexed = None
        elif isinstance(record, MessageIndex):
            if indexed is not None:
                counts = indexed["messages_by_channel_id"]
                counts[record.channel_id] = counts.get(record.channel_id, 0) + len(record.records)
        elif record is not None:
            indexed = None
            on_record(record)
        pos = end
        report["bytes_recovered"] = pos
        if isinstance(record, DataEnd):
            report["data_complete"] = True
        if isinstance(record, Footer):
            report["complete"] = bytes(buf[pos: pos + len(MAGIC)]) == MAGIC
            if report["complete"]:
                report["bytes_recovered"] = pos + len(MAGIC)
            else:
                report["error"] = "the closing magic bytes are missing"
            return
    report["error"] = report["error"] or f"file ends at byte {size} without a footer"


def _take_chunk(chunk, inner, on_record, report):
    for rec in inner:
        on_record(rec)
    report["chunks"] += 1
