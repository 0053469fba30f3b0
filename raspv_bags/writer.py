"""Writing ROS 2 bags that survive their writer being killed (no ROS imports).

:class:`BagWriter` wraps rosbags' writer (mcap or sqlite3) and adds :meth:`BagWriter.flush`:
everything written before a flush is on disk in a form :class:`raspv_bags.reader.BagReader`
can read back even if the process then dies without closing the bag (SIGKILL, power loss of
the process, OOM killer):

- mcap: the pending chunk is closed and the file buffer flushed, so the file is a sequence of
  complete chunk records; only the summary and footer (written by :meth:`close`) are missing.
- sqlite3: the open transaction is committed.

``flush_interval_s`` makes :meth:`write` flush by itself, so a killed recording loses at most
that much. :meth:`close` writes the index, the footer and ``metadata.yaml``.

``compression`` (MCAP only): each chunk compressed losslessly with ``zstd`` (level 1) or ``lz4``,
as the MCAP format provides and the RealSense SDK's own bags do (LZ4 chunks) — every MCAP reader
(rosbags, ``ros2 bag``, Foxglove, :mod:`raspv_bags.mcap_salvage`) decompresses it; nothing in the
messages changes. Measured on the demo's camera streams: colour ~9×, depth and labels > 100×
(docs/bags.md#recording).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from raspv_bags.message_types import normalise_type, typestore


def chunk_compressor(name: str) -> Callable[[bytes], bytes]:
    """The function that compresses an MCAP chunk for ``name`` (one of :data:`COMPRESSIONS`
    but "none")."""
    if name == "zstd":
        try:
            from compression import zstd          # Python >= 3.14
        except ImportError:
            from backports import zstd            # rosbags' own dependency before 3.14
        return lambda data: zstd.compress(data, level=ZSTD_LEVEL)
    if name == "lz4":
        from lz4.frame import compress            # rosbags' dependency (it reads lz4 chunks)
        return compress
    raise ValueError(f"unknown chunk compression {name!r}; use one of {', '.join(COMPRESSIONS)}")

STORAGES = ("mcap", "sqlite3")
COMPRESSIONS = ("zstd", "lz4", "none")     # of MCAP chunks
ZSTD_LEVEL = 1          # the fastest: ~9× on the demo's colour at ~5 ms per 465×366 frame, level 3 ~10× at ~13 ms


class BagWriteError(RuntimeError):
    """A bag that cannot be created or written (the message says why)."""


@dataclass(frozen=True)
class QosSpec:
    """The QoS a topic was offered with, in plain terms (stored in the bag per topic)."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def to_rosbags(self) -> Qos:
        zero = QosTime(0, 0)
        return Qos(QosHistory.KEEP_LAST, int(self.depth),
                   QosReliability.RELIABLE if self.reliable else QosReliability.BEST_EFFORT,
                   QosDurability.TRANSIENT_LOCAL if self.transient_local else QosDurability.VOLATILE,
                   zero, zero, QosLiveliness.AUTOMATIC, zero, False)

    @classmethod
    def from_rosbags(cls, qos: Qos) -> "QosSpec":
        return cls(reliable=qos.reliability != QosReliability.BEST_EFFORT,
                   transient_local=qos.durability == QosDurability.TRANSIENT_LOCAL,
                   depth=max(1, int(qos.depth or 1)))


class _FlushableMcap(McapWriter):
    def flush(self) -> None:
        if self.chunk.bio.tell():
            self.close_chunk()
        self.bio.flush()


class _FlushableSqlite3(Sqlite3Writer):
    def flush(self) -> None:
        self.conn.commit()


class _Writer(Writer):
    STORAGE_PLUGINS = {StoragePlugin.SQLITE3: _FlushableSqlite3, StoragePlugin.MCAP: _FlushableMcap}


class BagWriter:
    """A ROS 2 bag (directory) being written. Timestamps are integer nanoseconds."""

    def __init__(self, path: str | Path, storage: str = "mcap", flush_interval_s: float | None = 0.5,
                 compression: str = "none") -> None:
        if storage not in STORAGES:
            raise BagWriteError(f"unknown storage {storage!r}; use one of {', '.join(STORAGES)}")
        if compression not in COMPRESSIONS:
            raise BagWriteError(f"unknown compression {compression!r}; use one of {', '.join(COMPRESSIONS)}")
        if compression != "none" and storage != "mcap":
            raise BagWriteError(f"{compression} compression is for MCAP bags (chunks); {storage} bags are written "
                                "uncompressed: use --compression none or mcap storage")
        self.path = Path(path)
        if self.path.exists():
            raise BagWriteError(f"{self.path} exists already; choose a new output directory")
        if not self.path.parent.is_dir():
            raise BagWriteError(f"{self.path.parent} is not a directory")
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        self.storage = storage
        self._writer = _Writer(self.path, version=9, storage_plugin=plugin)
        try:
            self._writer.open()
        except (OSError, WriterError) as exc:
            raise BagWriteError(f"cannot create bag {self.path}: {exc}") from None
        self.compression = compression
        if compression != "none":         # before the first chunk closes (rosbags' own STORAGE mode is zstd level 3)
            self._writer.storage.compression = compression
            self._writer.storage.compressor = chunk_compressor(compression)
        self._connections: dict[str, object] = {}
        self.counts: dict[str, int] = {}
        self.types: dict[str, str] = {}
        self.bytes_written = 0            # serialised message bytes handed in (before compression)
        self.flush_interval_s = flush_interval_s
        self._last_flush = time.monotonic()
        self.closed = False

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[QosSpec] = (),
                  msgdef: str | None = None, type_hash: str | None = None) -> None:
        """Declare a topic. ``msgdef``/``type_hash`` (rosbag2 text and RIHS01 hash) are needed
        only for types the typestore does not know."""
        msgtype = normalise_type(msgtype)
        if topic in self._connections:
            if self.types[topic] != msgtype:
                raise BagWriteError(f"topic {topic} already recorded as {self.types[topic]}, not {msgtype}")
            return
        store = typestore()
        offered = [q.to_rosbags() for q in qos]
        try:
            if msgtype in store.fielddefs:
                conn = self._writer.add_connection(topic, msgtype, typestore=store, offered_qos_profiles=offered)
            elif msgdef is not None:
                conn = self._writer.add_connection(topic, msgtype, msgdef=msgdef, rihs01=type_hash or "RIHS01_" + "0" * 64,
                                                   offered_qos_profiles=offered)
            else:
                raise BagWriteError(f"message type {msgtype} of {topic} is unknown and has no definition")
        except WriterError as exc:
            raise BagWriteError(f"cannot add topic {topic} ({msgtype}): {exc}") from None
        self._connections[topic] = conn
        self.counts[topic] = 0
        self.types[topic] = msgtype

    def set_custom_data(self, key: str, value: str) -> None:
        """A key/value pair of text in ``metadata.yaml``'s ``custom_data`` (rosbag2 metadata
        version 6+), written at :meth:`close`."""
        self._writer.set_custom_data(key, value)

    def write(self, topic: str, timestamp_ns: int, data: bytes | memoryview) -> None:
        """Append one serialised (CDR) message of a declared topic."""
        conn = self._connections.get(topic)
        if conn is None:
            raise BagWriteError(f"topic {topic} was not added to the bag")
        self._writer.write(conn, int(timestamp_ns), data)
        self.counts[topic] += 1
        self.bytes_written += len(data)
        if self.flush_interval_s is not None and time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()

    @property
    def file_bytes(self) -> int:
        """Bytes in the bag's files so far (compressed chunks; the pending chunk not yet)."""
        return sum(p.stat().st_size for p in self.path.iterdir() if p.is_file())

    def flush(self) -> None:
        """Make everything written so far readable after a crash."""
        if not self.closed and self._writer.storage is not None:
            self._writer.storage.flush()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Write the index, footer and ``metadata.yaml``: the bag is complete."""
        if self.closed:
            return
        self.closed = True
        self._writer.close()

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
