"""Reading what an unfinished or damaged MCAP file holds (no ROS imports).

A recorder that is killed leaves an MCAP file without its summary and footer, maybe ending in
the middle of a record; a file copied partly, or damaged, has the same problem. rosbags
refuses such files (it seeks to the footer first). :class:`McapSalvage` instead streams the
records from the start — schemas, channels, messages, chunks (uncompressed, lz4 or zstd) —
and stops at the first record that is cut off or malformed, keeping everything before it.
The messages of an uncompressed chunk cut off by the end of the file are kept up to the last
complete one.

Record layout (https://mcap.dev/spec): magic ``\\x89MCAP0\\r\\n``, then records of
``opcode u8, length u64, body``; little-endian integers; strings as ``u32 length + UTF-8``.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable, Iterator

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_DATA_END = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F
BINARY_SCHEMA_ENCODINGS = frozenset({"protobuf", "flatbuffer"})
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_MSG_HEAD = struct.Struct("<HIQQ")        # channel id, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")      # start, end, uncompressed size, uncompressed crc


class McapDamaged(ValueError):
    """Nothing could be read from the file (the message says why)."""


@dataclass(frozen=True)
class SalvagedSchema:
    id: int
    name: str          # message type, e.g. sensor_msgs/msg/Image
    encoding: str      # ros2msg | ros2idl
    data: str          # the message definition text ("" for binary schema encodings)


@dataclass(frozen=True)
class SalvagedChannel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass
class ScanResult:
    """What a pass over the file found."""

    schemas: dict[int, SalvagedSchema] = field(default_factory=dict)
    channels: dict[int, SalvagedChannel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None
    complete: bool = False          # the data section ended with a DataEnd or Footer record
    stop_reason: str | None = None  # why reading stopped early (None: it did not)
    good_bytes: int = 0             # offset of the end of the last complete record


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    if pos + n > len(buf):
        raise ValueError("string runs past the end of its record")
    return bytes(buf[pos:pos + n]).decode("utf-8"), pos + n


def _parse_schema(body: memoryview) -> SalvagedSchema:
    (sid,) = _U16.unpack_from(body, 0)
    name, pos = _string(body, 2)
    encoding, pos = _string(body, pos)
    (n,) = _U32.unpack_from(body, pos)
    raw = bytes(body[pos + 4:pos + 4 + n])
    # a binary schema (a protobuf descriptor set, as DepthAI writes) is no text definition
    data = "" if encoding in BINARY_SCHEMA_ENCODINGS else raw.decode("utf-8")
    return SalvagedSchema(sid, name, encoding, data)


def _parse_channel(body: memoryview) -> SalvagedChannel:
    cid, schema_id = struct.unpack_from("<HH", body, 0)
    topic, pos = _string(body, 4)
    encoding, pos = _string(body, pos)
    (n,) = _U32.unpack_from(body, pos)
    pos += 4
    end = pos + n
    meta: dict[str, str] = {}
    while pos < end:
        key, pos = _string(body, pos)
        value, pos = _string(body, pos)
        meta[key] = value
    return SalvagedChannel(cid, schema_id, topic, encoding, meta)


def _decompressor(name: str) -> Callable[[bytes], bytes]:
    if name == "":
        return lambda b: b
    if name == "lz4":
        from lz4.frame import decompress
        return decompress
    if name == "zstd":
        try:
            from compression import zstd  # Python >= 3.14
        except ImportError:
            from backports import zstd
        return zstd.decompress
    raise ValueError(f"unsupported chunk compression {name!r}")


class McapSalvage:
    """Stream the readable part of an MCAP file (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.scan = self._scan()

    # -- public -----------------------------------------------------------------------------
    def messages(self, channel_ids: set[int] | None = None, start_ns: int | None = None,
                 ) -> Iterator[tuple[int, int, memoryview]]:
        """(channel id, log time ns, serialised message) in file order."""
        for op, body in self._records(ScanResult()):
            if op != OP_MESSAGE or len(body) < _MSG_HEAD.size:
                continue
            cid, _seq, log_time, _pub = _MSG_HEAD.unpack_from(body, 0)
            if (channel_ids is None or cid in channel_ids) and (start_ns is None or log_time >= start_ns):
                yield cid, log_time, body[_MSG_HEAD.size:]

    # -- internals --------------------------------------------------------------------------
    def _scan(self) -> ScanResult:
        res = ScanResult()
        for op, body in self._records(res):
            try:
                if op == OP_SCHEMA:
                    s = _parse_schema(body)
                    res.schemas[s.id] = s
                elif op == OP_CHANNEL:
                    c = _parse_channel(body)
                    res.channels[c.id] = c
                elif op == OP_MESSAGE:
                    cid, _seq, log_time, _pub = _MSG_HEAD.unpack_from(body, 0)
                    res.counts[cid] = res.counts.get(cid, 0) + 1
                    res.start_ns = log_time if res.start_ns is None else min(res.start_ns, log_time)
                    res.end_ns = log_time if res.end_ns is None else max(res.end_ns, log_time)
            except (struct.error, ValueError, UnicodeDecodeError) as exc:
                res.stop_reason = f"malformed record (opcode {op:#04x}): {exc}"
                break
        return res

    def _records(self, res: ScanResult) -> Iterator[tuple[int, memoryview]]:
        """Top-level records with chunks expanded into their inner records."""
        try:
            f = open(self.path, "rb")
        except OSError as exc:
            raise McapDamaged(f"cannot open {self.path}: {exc.strerror}") from None
        with f:
            size = self.path.stat().st_size
            if f.read(len(MAGIC)) != MAGIC:
                raise McapDamaged(f"{self.path} is not an MCAP file (bad magic bytes)")
            pos = len(MAGIC)
            res.good_bytes = pos
            while True:
                head = f.read(9)
                if not head:
                    res.stop_reason = f"file ends at byte {pos} without a footer (recording not closed)"
                    return
                if len(head) < 9:
                    res.stop_reason = f"record header cut off at byte {pos}"
                    return
                op, length = head[0], _U64.unpack_from(head, 1)[0]
                if op == 0 or 0x0F < op < 0x80:  # 0x80-0xFF are private records
                    res.stop_reason = f"invalid record opcode {op:#04x} at byte {pos}"
                    return
                if op in (OP_DATA_END, OP_FOOTER):
                    res.complete = True
                    return
                available = size - pos - 9
                if length > available:
                    if op == OP_CHUNK:
                        yield from self._partial_chunk(f, available, pos, res)
                    else:
                        res.stop_reason = f"record cut off at byte {pos} ({available} of {length} bytes present)"
                    return
                body = memoryview(f.read(length))
                if op == OP_CHUNK:
                    try:
                        records = self._chunk_records(body, complete=True)
                    except (struct.error, ValueError) as exc:
                        res.stop_reason = f"damaged chunk at byte {pos}: {exc}"
                        return
                    inner_ok = yield from self._inner(records, pos, res)
                    if not inner_ok:
                        res.stop_reason = f"damaged records inside the chunk at byte {pos}"
                        return
                elif op != OP_HEADER:
                    yield op, body
                pos += 9 + length
                res.good_bytes = pos

    def _partial_chunk(self, f: BinaryIO, available: int, pos: int, res: ScanResult
                       ) -> Iterator[tuple[int, memoryview]]:
        body = memoryview(f.read(available))
        try:
            records = self._chunk_records(body, complete=False)
        except (struct.error, ValueError) as exc:
            res.stop_reason = f"last chunk at byte {pos} cut off and unreadable ({exc})"
            return
        yield from self._inner(records, pos, res)
        res.stop_reason = f"last chunk at byte {pos} cut off; kept its complete messages"

    @staticmethod
    def _chunk_records(body: memoryview, complete: bool) -> memoryview:
        _start, _end, usize, _crc = _CHUNK_HEAD.unpack_from(body, 0)
        compression, pos = _string(body, _CHUNK_HEAD.size)
        (n,) = _U64.unpack_from(body, pos)
        pos += 8
        data = body[pos:pos + n]
        if len(data) < n:
            if complete or compression != "":
                raise ValueError(f"{compression or 'uncompressed'} chunk data cut off")
            return data
        if compression == "":
            return data
        out = _decompressor(compression)(bytes(data))
        if len(out) != usize:
            raise ValueError(f"chunk decompressed to {len(out)} bytes, expected {usize}")
        return memoryview(out)

    @staticmethod
    def _inner(records: memoryview, chunk_pos: int, res: ScanResult):
        """Records inside a chunk; returns False when the chunk was damaged."""
        pos, n = 0, len(records)
        while pos < n:
            if pos + 9 > n:
                return pos == n
            op, length = records[pos], _U64.unpack_from(records, pos + 1)[0]
            if pos + 9 + length > n:
                return False
            yield op, records[pos + 9:pos + 9 + length]
            pos += 9 + length
        return True
