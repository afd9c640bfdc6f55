"""Recover the messages of an interrupted MCAP bag (``fall-predictor repair-bag``).

A writer killed mid-run (SIGKILL, power loss) leaves an MCAP file without its summary and
footer, maybe with a torn last record, and a bag directory without ``metadata.yaml``: no
reader opens it. :func:`scan_mcap` walks the records from the start of the file (MCAP's
record framing: opcode, length, content) and yields every schema, channel and complete
message, including those inside chunks (zstd chunks are checked against their content
checksum; the complete records at the start of a torn last chunk are recovered from the part
of it on disk). :func:`repair_bag` writes what was found as a valid bag (same topics, types,
log times and serialized bytes) in place of the damaged one and keeps the damaged file next to
it as ``<name>.mcap.damaged``.

What cannot be recovered: messages the writer still held in memory (rosbags keeps up to 1 MiB,
its open chunk, before writing it) and a message cut by the end of the file. Records after a
damaged one are not searched for (the framing has no resynchronisation marker).
"""
from __future__ import annotations

import os
import shutil
import struct
import sys
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

from rosbags.typesys.store import Typestore

from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.bagio import BagError, deserialize_cdr, recorded_typestore

if sys.version_info >= (3, 14):
    from compression import zstd
else:
    from backports import zstd

#: The MCAP magic bytes, at the start and the end of a complete file.
MCAP_MAGIC = b'\x89MCAP0\r\n'
#: Suffix of the damaged file kept next to the repaired bag.
BACKUP_SUFFIX = '.damaged'

_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_DATA_END = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F
_LAST_OPCODE = 0x10                     # opcodes 0x01..0x10 exist in MCAP 0; anything else is damage


@dataclass(frozen=True, slots=True)
class McapSchema:
    id: int
    name: str                           #: message type, e.g. std_msgs/msg/Float64MultiArray
    encoding: str
    data: bytes


@dataclass(frozen=True, slots=True)
class McapChannel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str


@dataclass(frozen=True, slots=True)
class McapMessage:
    channel_id: int
    log_time_ns: int
    data: bytes
    from_torn_chunk: bool               #: found in a chunk cut by the end of the file


McapRecord = Union[McapSchema, McapChannel, McapMessage]


@dataclass(slots=True)
class ScanResult:
    """Where the scan of a file stopped and why (filled in while :func:`scan_mcap` runs)."""

    file_bytes: int = 0
    complete_bytes: int = 0             #: bytes up to the end of the last complete record
    complete: bool = False              #: the file ends with a footer and the closing magic
    stop_reason: str = ''
    chunks_dropped: int = 0             #: chunks whose content failed its checksum or is unknown


class _Cut(Exception):
    """A record runs past the end of its buffer."""


def _u16(buf: memoryview, pos: int) -> int:
    if pos + 2 > len(buf):
        raise _Cut
    return struct.unpack_from('<H', buf, pos)[0]


def _u32(buf: memoryview, pos: int) -> int:
    if pos + 4 > len(buf):
        raise _Cut
    return struct.unpack_from('<I', buf, pos)[0]


def _u64(buf: memoryview, pos: int) -> int:
    if pos + 8 > len(buf):
        raise _Cut
    return struct.unpack_from('<Q', buf, pos)[0]


def _bytes(buf: memoryview, pos: int) -> tuple[bytes, int]:
    """A length-prefixed byte string (u32 length) at ``pos``, and the position after it."""
    n = _u32(buf, pos)
    if pos + 4 + n > len(buf):
        raise _Cut
    return bytes(buf[pos + 4:pos + 4 + n]), pos + 4 + n


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    raw, pos = _bytes(buf, pos)
    return raw.decode('utf-8'), pos


def _parse(op: int, content: memoryview, torn: bool) -> Optional[McapRecord]:
    """A schema, channel or message record's content, else None."""
    if op == _OP_SCHEMA:
        schema_id = _u16(content, 0)
        name, pos = _string(content, 2)
        encoding, pos = _string(content, pos)
        data, _ = _bytes(content, pos)
        return McapSchema(schema_id, name, encoding, data)
    if op == _OP_CHANNEL:
        channel_id, schema_id = _u16(content, 0), _u16(content, 2)
        topic, pos = _string(content, 4)
        encoding, _ = _string(content, pos)
        return McapChannel(channel_id, schema_id, topic, encoding)
    if op == _OP_MESSAGE:
        if len(content) < 22:
            raise _Cut
        return McapMessage(_u16(content, 0), _u64(content, 6), bytes(content[22:]), torn)
    return None


def _records(buf: memoryview, torn: bool) -> Iterator[McapRecord]:
    """The schema, channel and message records of a chunk's (possibly cut) content."""
    pos = 0
    while pos + 9 <= len(buf):
        op, length = buf[pos], _u64(buf, pos + 1)
        end = pos + 9 + length
        if end > len(buf) or not 0 < op <= _LAST_OPCODE:
            return
        try:
            record = _parse(op, buf[pos + 9:end], torn)
        except (_Cut, UnicodeDecodeError):
            return
        if record is not None:
            yield record
        pos = end


def _chunk_content(content: memoryview, whole: bool) -> Optional[memoryview]:
    """The uncompressed records of a chunk record (``whole``: complete, else cut by the end of
    the file); None if its compression is unknown or its content fails a checksum."""
    try:
        uncompressed_size, crc = _u64(content, 16), _u32(content, 24)
        compression, pos = _string(content, 28)
        size = _u64(content, pos)
    except (_Cut, UnicodeDecodeError):
        return None
    data = content[pos + 8:pos + 8 + size]
    try:
        if compression == '':
            out = bytes(data)
        elif compression == 'zstd' and whole:
            out = zstd.decompress(data)         # verifies the frame's content checksum
        elif compression == 'zstd':
            out = zstd.ZstdDecompressor().decompress(data)      # the blocks on disk
        else:
            return None
    except zstd.ZstdError:
        return None
    if whole and (len(out) != uncompressed_size or (crc and zlib.crc32(out) != crc)):
        return None
    return memoryview(out)


def scan_mcap(buf: Union[bytes, memoryview], result: ScanResult) -> Iterator[McapRecord]:
    """Every schema, channel and complete message in the MCAP bytes ``buf``, in file order.

    ``result`` receives the byte counts and the reason the scan stopped. Raises BagError if
    ``buf`` does not start with the MCAP magic.
    """
    view = memoryview(buf)
    result.file_bytes = len(view)
    if bytes(view[:8]) != MCAP_MAGIC:
        raise BagError('not an MCAP file (no MCAP magic at its start)')
    pos = result.complete_bytes = 8
    while True:
        if pos == len(view):
            result.stop_reason = 'end of file without footer (writer interrupted)'
            return
        if pos + 9 > len(view):
            result.stop_reason = 'torn record header at the end of the file'
            return
        op, length = view[pos], struct.unpack_from('<Q', view, pos + 1)[0]
        if not 0 < op <= _LAST_OPCODE:
            result.stop_reason = f'unknown record opcode {op:#04x} at byte {pos} (damaged file)'
            return
        end = pos + 9 + length
        content = view[pos + 9:min(end, len(view))]
        if end > len(view):
            if op == _OP_CHUNK:
                records = _chunk_content(content, whole=False)
                if records is not None:
                    yield from _records(records, torn=True)
            result.stop_reason = f'record (opcode {op:#04x}) at byte {pos} cut by the end of the file'
            return
        if op == _OP_CHUNK:
            records = _chunk_content(content, whole=True)
            if records is None:
                result.chunks_dropped += 1
            else:
                yield from _records(records, torn=False)
        elif op == _OP_FOOTER:
            result.complete_bytes = end
            result.complete = bytes(view[end:end + 8]) == MCAP_MAGIC
            result.stop_reason = 'footer' if result.complete else 'footer without closing magic'
            return
        elif op != _OP_DATA_END:
            try:
                record = _parse(op, content, torn=False)
            except (_Cut, UnicodeDecodeError):
                result.stop_reason = f'malformed record (opcode {op:#04x}) at byte {pos}'
                return
            if record is not None:
                yield record
        pos = result.complete_bytes = end


@dataclass(slots=True)
class RepairReport:
    """What :func:`repair_bag` did to one bag."""

    bag: str
    status: str                         #: 'repaired' or 'intact' (nothing done)
    backup: Optional[str] = None        #: the damaged MCAP file, kept
    messages: dict[str, int] = field(default_factory=dict)      #: recovered per topic
    from_torn_chunk: int = 0            #: of which found in a chunk cut by the end of the file
    undecodable: dict[str, int] = field(default_factory=dict)   #: complete but dropped per topic
    file_bytes: int = 0
    bytes_dropped: int = 0              #: file bytes after the last complete record
    chunks_dropped: int = 0
    stop_reason: str = ''


def _mcap_file(bag: Path) -> Path:
    files = [p for p in bag.glob('*.mcap')]
    if len(files) != 1:
        raise BagError(f'{bag}: expected one .mcap file, found {len(files)}')
    return files[0]


def needs_repair(bag: Path) -> bool:
    """True if the bag directory lacks ``metadata.yaml`` or its MCAP file lacks the closing magic."""
    if not (bag / 'metadata.yaml').exists():
        return True
    mcap = _mcap_file(bag)
    with mcap.open('rb') as f:
        size = f.seek(0, os.SEEK_END)
        if size < 16:
            return True
        f.seek(size - 8)
        return f.read(8) != MCAP_MAGIC


def _schema_typestore(schema: Optional[McapSchema]) -> Optional[Typestore]:
    """The type store that decodes a channel of ``schema``: built from its recorded ros2msg
    definition (:func:`~fall_predictor.data.bagio.recorded_typestore`); the package's own for a
    schema in another encoding; None for a missing or unparsable one."""
    if schema is None:
        return None
    try:
        definition = schema.data.decode() if schema.encoding == 'ros2msg' else ''
        return recorded_typestore(schema.name, definition)
    except (BagError, UnicodeDecodeError):
        return None


def _write_recovered(source: Path, target: Path, report: RepairReport, result: ScanResult) -> None:
    schemas: dict[int, McapSchema] = {}
    channels: dict[int, tuple[str, str, Optional[Typestore]]] = {}
    data = source.read_bytes()           # parts are bounded; a whole file is read at once
    with BagWriter(target) as writer:
        for record in scan_mcap(data, result):
            if isinstance(record, McapSchema):
                schemas[record.id] = record
            elif isinstance(record, McapChannel):
                schema = schemas.get(record.schema_id)
                channels[record.id] = (record.topic, schema.name if schema else '',
                                       _schema_typestore(schema))
            else:
                topic, msg_type, store = channels.get(record.channel_id, ('', '', None))
                try:
                    if store is None:
                        raise BagError(f'no usable schema for channel {record.channel_id}')
                    deserialize_cdr(record.data, msg_type, store)
                except Exception:           # unknown channel or type, or damaged bytes
                    name = topic or f'channel {record.channel_id}'
                    report.undecodable[name] = report.undecodable.get(name, 0) + 1
                    continue
                # Written with the definition it was recorded with, so that it reads as before.
                writer.write_raw(topic, msg_type, record.log_time_ns, record.data, store=store)
                report.messages[topic] = report.messages.get(topic, 0) + 1
                report.from_torn_chunk += record.from_torn_chunk


def repair_bag(bag: Union[str, os.PathLike[str]]) -> RepairReport:
    """Rewrite the interrupted bag directory ``bag`` as a valid bag holding every complete
    message of its MCAP file; the damaged file is kept as ``<bag>/<name>.mcap.damaged``.

    A bag that has ``metadata.yaml`` and a complete MCAP file is left alone (status 'intact').
    Raises BagError if ``bag`` holds no single MCAP file or the file is not MCAP. Crash-safe:
    the damaged directory is first renamed to ``.<name>.damaged`` next to it, so an interrupted
    repair loses nothing.
    """
    bag = Path(bag)
    if bag.is_file() and bag.suffix == '.mcap':
        bag = bag.parent
    mcap = _mcap_file(bag)
    report = RepairReport(bag=str(bag), status='intact')
    if not needs_repair(bag):
        return report
    with mcap.open('rb') as f:
        if f.read(8) != MCAP_MAGIC:
            raise BagError(f'{mcap}: not an MCAP file (no MCAP magic at its start)')
    moved = bag.with_name(f'.{bag.name}{BACKUP_SUFFIX}')
    if moved.exists():
        raise BagError(f'{moved} exists (an earlier repair was interrupted): move it away first')
    os.replace(bag, moved)
    result = ScanResult()
    try:
        _write_recovered(moved / mcap.name, bag, report, result)
    except BaseException:
        shutil.rmtree(bag, ignore_errors=True)
        os.replace(moved, bag)
        raise
    backup = bag / f'{bag.name}.mcap{BACKUP_SUFFIX}'
    os.replace(moved / mcap.name, backup)
    shutil.rmtree(moved)
    report.status = 'repaired'
    report.backup = str(backup)
    report.file_bytes = result.file_bytes
    report.bytes_dropped = result.file_bytes - result.complete_bytes
    report.chunks_dropped = result.chunks_dropped
    report.stop_reason = result.stop_reason
    return report


def bags_under(path: Union[str, os.PathLike[str]]) -> list[Path]:
    """The bag directories at or below ``path`` (a bag, a ``.mcap`` file, a split recording,
    or a directory of recordings): every directory holding a ``.mcap`` file, sorted."""
    root = Path(path)
    if not root.exists():
        raise BagError(f'{root}: does not exist')
    if root.is_file():
        if root.suffix != '.mcap':
            raise BagError(f'{root}: not a bag directory or .mcap file')
        return [root.parent]
    bags = sorted({p.parent for p in root.rglob('*.mcap')
                   if not any(part.startswith('.') for part in p.relative_to(root).parts)})
    if not bags:
        raise BagError(f'{root}: no .mcap file found')
    return bags


__all__ = ['MCAP_MAGIC', 'McapChannel', 'McapMessage', 'McapSchema', 'RepairReport', 'ScanResult',
           'bags_under', 'needs_repair', 'repair_bag', 'scan_mcap']
