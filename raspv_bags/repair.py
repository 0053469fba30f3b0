"""Turning an unfinished or damaged bag into a complete one (no ROS imports).

:func:`repair_bag` reads whatever :class:`~raspv_bags.reader.BagReader` can read from a
bag (e.g. one whose recorder was SIGKILLed) and writes it, bytes unchanged, into a new complete
bag that every ROS 2 tool opens. The original is left as it is.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from raspv_bags.reader import BagReader
from raspv_bags.recording import DEFAULT_COMPRESSION
from raspv_bags.writer import BagWriter, BagWriteError


@dataclass
class RepairReport:
    output: Path
    counts: dict[str, int]
    notes: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


def repair_bag(source: str | Path, output: str | Path, storage: str | None = None,
               progress: Callable[[int, int], None] | None = None) -> RepairReport:
    """Copy every readable message of ``source`` into the new bag ``output`` (``storage``:
    ``mcap``/``sqlite3``, default: the source's). ``progress(done, total)`` is called as it goes.
    Raises :class:`~raspv_bags.reader.BagError` when nothing is readable and
    :class:`~raspv_bags.writer.BagWriteError` when the output cannot be written."""
    with BagReader(source) as reader:
        total = reader.message_count
        storage = storage or (reader.storage if reader.storage in ("mcap", "sqlite3") else "mcap")
        # an MCAP copy compressed as a recording is (a repaired study session stays its size)
        writer = BagWriter(output, storage, flush_interval_s=None,
                           compression=DEFAULT_COMPRESSION if storage == "mcap" else "none")
        try:
            notes: list[str] = []
            kept = []
            for t in reader.topics.values():
                try:
                    writer.add_topic(t.name, t.msgtype, t.qos, msgdef=t.definition or None)
                    kept.append(t.name)
                except BagWriteError as exc:
                    notes.append(f"{t.name} left out: {exc}")
            done = 0
            for msg in reader.messages(kept):
                writer.write(msg.topic, msg.timestamp_ns, msg.data)
                done += 1
                if progress is not None and done % 200 == 0:
                    progress(done, total)
        finally:
            writer.close()
        if progress is not None:
            progress(done, total)
        return RepairReport(Path(output), dict(writer.counts), list(reader.notes) + notes)
