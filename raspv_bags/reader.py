"""Reading ROS 2 bags, including unfinished and damaged ones (no ROS imports).

:class:`BagReader` opens a bag directory (``metadata.yaml`` + ``.mcap``/``.db3`` files) or a
single ``.mcap``/``.db3`` file and gives its topics and its messages as serialised bytes, in
time order. It uses what can be read and says what it could not (:attr:`BagReader.notes`):

- a complete bag: rosbags' reader;
- a bag whose recorder was killed (no ``metadata.yaml``, MCAP without footer): MCAP records are
  streamed up to the first damaged one (:mod:`raspv_bags.mcap_salvage`); an SQLite
  database's journal is rolled back and what was committed is read;
- a bag whose ``metadata.yaml`` or index is broken: its storage files are read directly;
- a message that stops the reader half-way: the messages before it are kept.

Only when nothing can be read does it raise :class:`BagError`, with a one-line reason.
Timestamps are integer nanoseconds (the receive time the recorder stored).
"""
from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.metadata import parse_qos

from raspv_bags.mcap_salvage import McapDamaged, McapSalvage
from raspv_bags.message_types import normalise_type, register_definition, typestore
from raspv_bags.writer import QosSpec

STORAGE_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}


class BagError(ValueError):
    """A bag that cannot be read at all (the message says why, in one line)."""


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: type, message count, the QoS it was offered with, and whether the
    type's definition is known (needed to decode it, not to replay it)."""

    name: str
    msgtype: str
    count: int
    qos: tuple[QosSpec, ...] = ()
    known_type: bool = True
    definition: str = ""     # the message definition stored in the bag (rosbag2 text)


@dataclass(frozen=True)
class BagMessage:
    topic: str
    msgtype: str
    timestamp_ns: int
    data: bytes | memoryview


class _RosbagsSource:
    """A complete bag (directory or file) through rosbags."""

    def __init__(self, path: Path) -> None:
        self.reader = Reader(path)
        self.reader.open()
        self.complete = True
        self.topics: dict[str, tuple[str, int, tuple[QosSpec, ...], str, str]] = {}
        fmt = {MessageDefinitionFormat.MSG: "ros2msg", MessageDefinitionFormat.IDL: "ros2idl"}
        for c in self.reader.connections:
            qos = tuple(QosSpec.from_rosbags(q) for q in getattr(c.ext, "offered_qos_profiles", []))
            prev = self.topics.get(c.topic)
            count = c.msgcount + (prev[1] if prev else 0)
            self.topics[c.topic] = (c.msgtype, count, qos, fmt.get(c.msgdef.format, ""), c.msgdef.data)
        self.start_ns = self.reader.start_time if self.reader.message_count else None
        self.end_ns = self.reader.end_time - 1 if self.reader.message_count else None

    def messages(self, topics: set[str] | None, start_ns: int | None, stop_ns: int | None
                 ) -> Iterator[tuple[str, str, int, Any]]:
        conns = [c for c in self.reader.connections if topics is None or c.topic in topics]
        if not conns:
            return
        for conn, ts, data in self.reader.messages(conns, start=start_ns, stop=stop_ns):
            yield conn.topic, conn.msgtype, ts, data

    def close(self) -> None:
        if self.reader.is_open:
            self.reader.close()


class _SalvageSource:
    """An MCAP file without a footer or with damaged records."""

    def __init__(self, path: Path) -> None:
        self.salvage = McapSalvage(path)
        scan = self.salvage.scan
        self.complete = scan.complete and scan.stop_reason is None
        self.stop_reason = scan.stop_reason
        self.topics = {}
        self.channel_topic: dict[int, tuple[str, str]] = {}
        for cid, ch in scan.channels.items():
            schema = scan.schemas.get(ch.schema_id)
            msgtype = normalise_type(schema.name) if schema else "unknown/msg/Unknown"
            try:
                qos = tuple(QosSpec.from_rosbags(q) for q in parse_qos(ch.metadata.get("offered_qos_profiles", "")))
            except Exception:  # unreadable QoS metadata: replay falls back to the topic's default
                qos = ()
            prev = self.topics.get(ch.topic)
            count = scan.counts.get(cid, 0) + (prev[1] if prev else 0)
            self.topics[ch.topic] = (msgtype, count, qos, schema.encoding if schema else "", schema.data if schema else "")
            self.channel_topic[cid] = (ch.topic, msgtype)
        self.start_ns, self.end_ns = scan.start_ns, scan.end_ns

    def messages(self, topics: set[str] | None, start_ns: int | None, stop_ns: int | None
                 ) -> Iterator[tuple[str, str, int, Any]]:
        ids = {cid for cid, (t, _) in self.channel_topic.items() if topics is None or t in topics}
        for cid, ts, data in self.salvage.messages(ids, start_ns):
            if stop_ns is not None and ts >= stop_ns:
                continue
            topic, msgtype = self.channel_topic[cid]
            yield topic, msgtype, ts, data

    def close(self) -> None:
        pass


def _recover_sqlite_journal(db: Path) -> str | None:
    """Roll back the transaction a killed writer left open (hot journal / WAL), so that the
    committed part reads consistently. Returns a note, or None when there was nothing to do."""
    if not any(db.with_name(db.name + s).exists() for s in ("-journal", "-wal")):
        return None
    try:
        with sqlite3.connect(db) as conn:
            conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
        return f"{db.name}: rolled back the transaction its writer left open"
    except sqlite3.Error as exc:
        return f"{db.name}: could not roll back the unfinished transaction ({exc})"


def _open_file(path: Path, notes: list[str]):
    kind = STORAGE_SUFFIXES.get(path.suffix)
    if kind == "sqlite3":
        note = _recover_sqlite_journal(path)
        if note:
            notes.append(note)
        try:
            return _RosbagsSource(path)
        except Exception as exc:  # apsw/rosbags errors of a damaged database
            raise BagError(f"{path}: not a readable SQLite bag ({_reason(exc)})") from None
    if kind == "mcap":
        try:
            return _RosbagsSource(path)
        except Exception as exc:  # rosbags refuses unfinished/damaged files: stream what is there
            first = _reason(exc)
        try:
            src = _SalvageSource(path)
        except McapDamaged as exc:
            raise BagError(str(exc)) from None
        if not src.topics:
            raise BagError(f"{path}: no readable records ({src.stop_reason or first})")
        notes.append(f"{path.name}: incomplete MCAP ({first}); read what it holds: "
                     f"{src.stop_reason or 'all records'}")
        return src
    raise BagError(f"{path}: not a bag file (expected .mcap or .db3)")


def _reason(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


class BagReader:
    """A bag opened for reading (see the module docstring). Use as a context manager."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.notes: list[str] = []
        self._sources: list[Any] = []
        if not self.path.exists():
            raise BagError(f"{self.path}: no such bag")
        try:
            self._open()
        except BagError:
            self.close()
            raise
        self.storage = self._storage
        self.complete = self._metadata_ok and all(s.complete for s in self._sources)
        self.topics: dict[str, TopicInfo] = {}
        for src in self._sources:
            for name, (msgtype, count, qos, enc, text) in src.topics.items():
                prev = self.topics.get(name)
                known = register_definition(msgtype, enc, text)
                self.topics[name] = TopicInfo(name, msgtype, count + (prev.count if prev else 0),
                                              qos or (prev.qos if prev else ()), known, text)
        starts = [s.start_ns for s in self._sources if s.start_ns is not None]
        ends = [s.end_ns for s in self._sources if s.end_ns is not None]
        self.start_ns: int | None = min(starts) if starts else None
        self.end_ns: int | None = max(ends) if ends else None
        for t in self.topics.values():
            if not t.known_type:
                self.notes.append(f"{t.name}: message type {t.msgtype} is unknown (no definition in the bag or "
                                  f"installed); it can be replayed only if installed, not decoded")

    def _open(self) -> None:
        p = self.path
        self._metadata_ok = True
        if p.is_file():
            self._storage = STORAGE_SUFFIXES.get(p.suffix, "?")
            self._sources = [_open_file(p, self.notes)]
            return
        files = sorted(f for f in p.iterdir() if f.suffix in STORAGE_SUFFIXES and f.is_file())
        if not files:
            raise BagError(f"{p}: not a bag (no .mcap or .db3 file in it)")
        self._storage = STORAGE_SUFFIXES[files[0].suffix]
        meta = p / "metadata.yaml"
        self._metadata_ok = False
        if meta.exists():
            try:
                self._sources = [_RosbagsSource(p)]
                self._metadata_ok = True
                return
            except Exception as exc:
                self.notes.append(f"metadata.yaml or index unusable ({_reason(exc)}); reading the storage files directly")
        else:
            self.notes.append("no metadata.yaml: the recording was not closed (recorder killed?); "
                              "reading what its files hold")
        for f in files:
            try:
                self._sources.append(_open_file(f, self.notes))
            except BagError as exc:
                self.notes.append(str(exc))
        if not self._sources:
            raise BagError(f"{p}: nothing readable; " + "; ".join(self.notes[-len(files):]))

    # -- reading ----------------------------------------------------------------------------
    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    @property
    def duration_s(self) -> float:
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) * 1e-9

    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 stop_ns: int | None = None) -> Iterator[BagMessage]:
        """Messages of ``topics`` (all if None) with ``start_ns <= t < stop_ns``. A read error
        half-way ends the iteration and is added to :attr:`notes`."""
        wanted = None if topics is None else set(topics)
        for src in self._sources:
            it = src.messages(wanted, start_ns, stop_ns)
            while True:
                try:
                    topic, msgtype, ts, data = next(it)
                except StopIteration:
                    break
                except Exception as exc:  # damaged storage: keep what was read before
                    self.notes.append(f"reading stopped early: {_reason(exc)}")
                    break
                yield BagMessage(topic, normalise_type(msgtype), ts, data)

    def topic_span_ns(self, topic: str) -> tuple[int, int] | None:
        """(first, last) receive time [ns] of ``topic``'s messages, or None when it has none.
        Reads its first message and then windows back from the bag's end (1 s, 4 s, 16 s, …),
        so only the storage chunks near both ends are decoded, not the whole bag."""
        first = next((m.timestamp_ns for m in self.messages([topic])), None)
        if first is None or self.end_ns is None:
            return None
        window = 1_000_000_000
        while True:
            start = max(first, self.end_ns - window)
            last = None
            for m in self.messages([topic], start_ns=start):
                last = m.timestamp_ns if last is None else max(last, m.timestamp_ns)
            if last is not None or start == first:
                return first, first if last is None else last
            window *= 4

    def topic_rate_hz(self, topic: str) -> float | None:
        """Messages per second of ``topic`` over its own span (first to last message), not the
        bag's: a topic that started late or ended early is not reported slower than it ran."""
        info = self.topics.get(topic)
        span = self.topic_span_ns(topic) if info is not None and info.count > 1 else None
        if span is None or span[1] <= span[0]:
            return None
        return (info.count - 1) / ((span[1] - span[0]) * 1e-9)

    def decode(self, msg: BagMessage) -> Any:
        """Deserialise a message into a rosbags message object; :class:`BagError` if its type is
        unknown or its bytes do not parse."""
        try:
            return typestore().deserialize_cdr(bytes(msg.data), msg.msgtype)
        except Exception as exc:
            raise BagError(f"{msg.topic} at {msg.timestamp_ns * 1e-9:.3f} s: cannot decode {msg.msgtype} "
                           f"({_reason(exc)})") from None

    def close(self) -> None:
        for s in self._sources:
            try:
                s.close()
            except Exception:
                pass
        self._sources = []

    def __enter__(self) -> "BagReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
