"""Recording a live graph into a bag: topic selection, writing, counts (no ROS imports).

The ROS side (`raspv bag record`, :mod:`raspv_bringup.bag_cli`) subscribes at start to the
graph's known topics (:mod:`raspv_bags.known_topics`: declared with :meth:`Recording.expect_topic`,
added to the bag with their first message, so topics nobody publishes leave no trace), discovers
the others, and hands every message (raw, serialised) here; :class:`Recording` writes
the bytes unchanged through :class:`~raspv_bags.writer.BagWriter` (which flushes every
``flush_interval_s``, so a killed recorder loses at most that much; MCAP chunks compressed
losslessly with zstd by default, :data:`DEFAULT_COMPRESSION`) and keeps the per-topic counts
shown on the status line.
"""
from __future__ import annotations

import fnmatch
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Sequence

from raspv_bags.sequence_gaps import SequenceGaps

if TYPE_CHECKING:
    from raspv_bags.writer import QosSpec

# Infrastructure topics left out of "record everything" (name them to record them).
DEFAULT_EXCLUDED = ("/rosout", "/parameter_events")
# Images their node renders only while someone subscribes are left out too, since a recorder's
# subscription makes it render them: the rendered phosphene image (800x800 at 50 Hz: ~32 MB/s,
# most of a demo recording; /spv/frame, /spv/map and /spv/sprites re-render it exactly,
# :mod:`raspv_bags.shown_render`) and the simulator's ground-truth labels (their render pass costs
# the simulator ~45 % more CPU per frame: the demo's camera fell from 5.6-6.6 to 2.8-3.0 Hz at load
# 24-30 while a recorder took them). Name them, or pass ``images=True`` (``--images``), to record them.
IMAGE_TOPICS = ("/spv/image", "/sim/labels")
# MCAP chunks compressed losslessly (raspv_bags.writer): the demo's camera streams 29 → 1.3 MB/s
DEFAULT_COMPRESSION = "zstd"


@dataclass(frozen=True)
class TopicSelection:
    """Which discovered topics to record: ``topics`` (names or shell patterns such as
    ``/camera/*``; empty = all but :data:`DEFAULT_EXCLUDED`) minus ``exclude`` (names or
    patterns). The images rendered on demand (:data:`IMAGE_TOPICS`) only when named or with ``images``."""

    topics: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    images: bool = False          # record the images rendered on demand (IMAGE_TOPICS) with everything

    def wants(self, name: str) -> bool:
        if any(fnmatch.fnmatchcase(name, p) for p in self.exclude):
            return False
        if not self.topics:
            return name not in DEFAULT_EXCLUDED and (self.images or name not in IMAGE_TOPICS)
        if name in IMAGE_TOPICS and name not in self.topics and not self.images:
            return False          # a pattern such as '/spv/*' does not bring the image in: name it
        return any(fnmatch.fnmatchcase(name, p) for p in self.topics)

    def unmatched(self, seen: Iterable[str]) -> list[str]:
        """Requested names/patterns that no topic in ``seen`` matched yet."""
        seen = list(seen)
        return [p for p in self.topics if not any(fnmatch.fnmatchcase(n, p) for n in seen)]


class Recording:
    """A bag being recorded from the graph."""

    def __init__(self, path: str | Path, storage: str = "mcap", flush_interval_s: float = 0.5,
                 compression: str | None = None) -> None:
        from raspv_bags.writer import BagWriter      # rosbags: imported only when a bag is written

        if compression is None:
            compression = DEFAULT_COMPRESSION if storage == "mcap" else "none"
        self.writer = BagWriter(path, storage, flush_interval_s=flush_interval_s, compression=compression)
        self.path = self.writer.path
        self.started = time.monotonic()
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self._expected: dict[str, tuple[str, list[QosSpec]]] = {}
        self.on_first_message = None          # callback(topic, msgtype) when a topic enters the bag
        self.gaps = SequenceGaps()            # messages published but never taken (the recorder behind)

    @property
    def topics(self) -> dict[str, str]:
        return dict(self.writer.types)

    def add_topic(self, topic: str, msgtype: str, offered: Sequence[QosSpec]) -> None:
        self._expected.pop(topic, None)
        self.writer.add_topic(topic, msgtype, offered)

    def expect_topic(self, topic: str, msgtype: str, offered: Sequence[QosSpec]) -> None:
        """Declare a topic subscribed ahead of discovery: added to the bag with its first message
        (``offered`` may be updated by calling this again before then)."""
        if topic not in self.writer.types:
            self._expected[topic] = (msgtype, list(offered))

    def on_message(self, topic: str, data: bytes, receive_ns: int, publication_number: int = 0) -> None:
        """Write one serialised message with its receive time (ns since the epoch) and its
        publisher's sequence number (0: unknown; holes are counted as lost, :attr:`gaps`). Raises
        :class:`~raspv_bags.writer.BagWriteError` when an expected topic cannot be added."""
        self.gaps.seen(topic, publication_number, time.monotonic())
        expected = self._expected.pop(topic, None)
        if expected is not None:
            self.writer.add_topic(topic, *expected)
            if self.on_first_message is not None:
                self.on_first_message(topic, expected[0])
        self.writer.write(topic, receive_ns, data)
        # a backlog taken after the bag opened comes topic by topic, not in time order
        self.first_ns = receive_ns if self.first_ns is None else min(self.first_ns, receive_ns)
        self.last_ns = receive_ns if self.last_ns is None else max(self.last_ns, receive_ns)

    @property
    def counts(self) -> dict[str, int]:
        return dict(self.writer.counts)

    def status_line(self, width: int = 120) -> str:
        """``12.3 s  41.2 MB  /camera/color/image_raw 245  /camera/pose 245 …`` cut to ``width``
        (MB on disk)."""
        elapsed = time.monotonic() - self.started
        head = f"recording {elapsed:6.1f} s  {self.writer.file_bytes / 1e6:7.1f} MB"
        if self.gaps.total:
            head += f"  LOST {self.gaps.total}"
        parts = [f"{t} {n}" for t, n in sorted(self.writer.counts.items())]
        line = "  ".join([head] + parts) if parts else head + "  (waiting for topics)"
        return line if len(line) <= width else line[: max(0, width - 1)] + "…"

    def summary(self) -> str:
        total = sum(self.writer.counts.values())
        span = (self.last_ns - self.first_ns) * 1e-9 if self.first_ns is not None else 0.0
        on_disk, raw = self.writer.file_bytes, self.writer.bytes_written
        how = (f"{self.writer.storage}, {self.writer.compression}: {raw / 1e6:.1f} MB of messages, "
               f"{raw / max(on_disk, 1):.1f}×" if self.writer.compression != "none" else self.writer.storage)
        rate = f", {on_disk / 1e6 / span:.2f} MB/s" if span > 0 else ""
        lines = [f"{self.path}: {total} messages over {span:.1f} s, {on_disk / 1e6:.1f} MB{rate} ({how})"]
        for t, n in sorted(self.writer.counts.items()):
            lost = self.gaps.lost.get(t, 0)
            lines.append(f"  {t:40s} {n:7d}  {self.writer.types[t]}" + (f"  ({lost} lost)" if lost else ""))
        if self.gaps.total:
            lines.append(f"{self.gaps.total} messages were published but lost before the recorder took them (it fell "
                         "behind: the machine too busy for it)")
        return "\n".join(lines)

    def flush(self) -> None:
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()
