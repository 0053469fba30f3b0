"""Replaying a bag with its original timing (no ROS imports).

:class:`Player` reads a bag and hands each message's serialised bytes to a ``publish``
callback at the moment it is due. Scheduling is on the monotonic clock against the bag's
timestamps — message *i* is due at ``t0 + (ts_i − ts_first) / rate`` — so waiting errors never
accumulate (no sleep drift); a message that is late goes out at once and the schedule is kept.
The bag's time is handed to a ``clock`` callback at ``clock_rate_hz`` and before every message
(``/clock`` for nodes with ``use_sim_time``). :class:`TimingStats` collects how late each
message went out (publish call time − due time, ms).

Options: ``rate`` factor, ``start_offset_s`` into the bag, ``loop``, topic selection
(``topics``/``exclude``) and ``remap`` (bag topic → published topic). :func:`publisher_qos`
chooses the QoS each published topic gets, matching the live graph.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping

import numpy as np

from raspv_bags.reader import BagError, BagReader, TopicInfo
from raspv_bags.writer import QosSpec
from raspv_common import topics as T

# Topics of an RGB-D source: published like the simulator does (raspv_common.qos.SENSOR_QOS)
# whatever QoS the bag's recorder saw, so the graph's reliable subscribers always match.
SENSOR_TOPICS = frozenset({T.COLOR, T.DEPTH, T.CAMERA_INFO, T.CAMERA_POSE, T.ODOM, T.SIM_LABELS})
LATCHED_TOPICS = frozenset({T.SPV_MAP, T.SIM_CLASSES})
EVENT_TOPICS = frozenset({T.SIM_COLLISIONS})


def publisher_qos(topic: str, offered: Iterable[QosSpec] = ()) -> tuple[str, QosSpec]:
    """(QoS class, spec) for republishing ``topic`` (after remapping). Classes: ``sensor``,
    ``latched``, ``event`` (the graph's profiles in :mod:`raspv_common.qos`) or ``recorded``
    (the reliability/durability/depth the bag's publishers offered)."""
    offered = list(offered)
    if topic in SENSOR_TOPICS:
        return "sensor", QosSpec(True, False, 2)
    if offered:
        reliable = all(q.reliable for q in offered)
        latched = all(q.transient_local for q in offered)
        if latched and reliable:
            return "latched", QosSpec(True, True, 1)
        return "recorded", QosSpec(reliable, latched, max(q.depth for q in offered))
    if topic in LATCHED_TOPICS:
        return "latched", QosSpec(True, True, 1)
    if topic in EVENT_TOPICS:
        return "event", QosSpec(True, False, 50)
    return "recorded", QosSpec(True, False, 10)


@dataclass
class PlaybackOptions:
    rate: float = 1.0                 # 2.0 plays twice as fast
    start_offset_s: float = 0.0       # skip this much of the bag
    loop: bool = False
    topics: tuple[str, ...] = ()      # bag topics to play (empty: all)
    exclude: tuple[str, ...] = ()     # bag topics not to play
    remap: Mapping[str, str] = field(default_factory=dict)  # bag topic → published topic
    clock_rate_hz: float = 100.0      # /clock publishing rate (0: only before each message)

    def check(self) -> None:
        if not (self.rate > 0 and np.isfinite(self.rate)):
            raise ValueError(f"rate must be > 0, got {self.rate}")
        if self.start_offset_s < 0:
            raise ValueError(f"start offset must be >= 0 s, got {self.start_offset_s}")
        if self.clock_rate_hz < 0:
            raise ValueError(f"clock rate must be >= 0 Hz, got {self.clock_rate_hz}")


def parse_remap(items: Iterable[str]) -> dict[str, str]:
    """``["/a:=/b", …]`` → ``{"/a": "/b"}`` (ValueError naming the bad item)."""
    out: dict[str, str] = {}
    for item in items:
        src, sep, dst = item.partition(":=")
        if not sep or not src.startswith("/") or not dst.startswith("/"):
            raise ValueError(f"bad remapping {item!r}: expected /from:=/to")
        out[src] = dst
    return out


class TimingStats:
    """How late messages went out, in ms (0 = exactly on time)."""

    def __init__(self) -> None:
        self._errors: list[float] = []

    def add(self, error_s: float) -> None:
        self._errors.append(max(0.0, error_s) * 1e3)

    @property
    def count(self) -> int:
        return len(self._errors)

    def percentile(self, q: float) -> float:
        return float(np.percentile(self._errors, q)) if self._errors else 0.0

    def summary(self) -> dict[str, float]:
        return {"count": self.count, "p50_ms": self.percentile(50), "p95_ms": self.percentile(95),
                "max_ms": max(self._errors) if self._errors else 0.0}

    def line(self) -> str:
        s = self.summary()
        return (f"timing error over {s['count']} messages: p50 {s['p50_ms']:.2f} ms, "
                f"p95 {s['p95_ms']:.2f} ms, max {s['max_ms']:.2f} ms")


@dataclass
class PlaybackReport:
    counts: dict[str, int]            # published topic → messages published
    loops: int
    timing: TimingStats
    wall_s: float
    bag_s: float                      # bag time covered
    notes: list[str]
    stopped: bool                     # stopped before the end


class Player:
    """Plays one bag (see the module docstring). ``run`` blocks until the end or :meth:`stop`;
    :meth:`set_rate` and :meth:`set_paused` may be called from another thread."""

    def __init__(self, bag: str, options: PlaybackOptions,
                 publish: Callable[[str, str, bytes | memoryview], None],
                 clock: Callable[[int], None] | None = None) -> None:
        options.check()
        self.bag_path = bag
        self.options = options
        self._publish = publish
        self._clock = clock
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._paused = False
        self.reader = BagReader(bag)
        if self.reader.start_ns is None:
            self.reader.close()
            raise BagError(f"{bag}: the bag has no messages")
        selected = [t for t in self.reader.topics.values()
                    if (not options.topics or t.name in options.topics) and t.name not in options.exclude]
        missing = [t for t in options.topics if t not in self.reader.topics]
        self.notes: list[str] = list(self.reader.notes)
        if missing:
            self.notes.append(f"not in the bag: {', '.join(missing)} (it has {', '.join(sorted(self.reader.topics))})")
        if not selected:
            self.reader.close()
            raise BagError(f"{bag}: none of the selected topics are in the bag "
                           f"(it has {', '.join(sorted(self.reader.topics)) or 'no topics'})")
        self.topics: list[TopicInfo] = selected
        self.start_ns = self.reader.start_ns + int(round(options.start_offset_s * 1e9))
        if self.reader.end_ns is not None and self.start_ns > self.reader.end_ns:
            self.reader.close()
            raise BagError(f"start offset {options.start_offset_s:.2f} s is past the end of the bag "
                           f"({self.reader.duration_s:.2f} s long)")
        self.out_topic = {t.name: options.remap.get(t.name, t.name) for t in selected}
        self.timing = TimingStats()
        self.counts = {self.out_topic[t.name]: 0 for t in selected}
        self.rate = options.rate
        self._anchor_wall = 0.0
        self._anchor_bag = self.start_ns
        self.last_ts: int | None = None

    def drop_topics(self, names: Iterable[str], why: str) -> None:
        """Leave bag topics ``names`` out (before :meth:`run`), with a note saying ``why``."""
        names = set(names)
        for t in [t for t in self.topics if t.name in names]:
            self.topics.remove(t)
            self.counts.pop(self.out_topic[t.name], None)
            self.notes.append(f"{t.name}: {why}; not replayed")

    # -- control from other threads ----------------------------------------------------------
    def stop(self) -> None:
        self._stop.set()

    @property
    def stop_requested(self) -> bool:
        return self._stop.is_set()

    def wait_stop(self, timeout_s: float) -> bool:
        """Sleep up to ``timeout_s``; True as soon as :meth:`stop` was called."""
        return self._stop.wait(timeout_s)

    def set_rate(self, rate: float) -> None:
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate}")
        with self._lock:
            now = time.monotonic()
            self._anchor_bag = self._bag_time(now)
            self._anchor_wall = now
            self.rate = rate

    def set_paused(self, paused: bool) -> None:
        with self._lock:
            now = time.monotonic()
            self._anchor_bag = self._bag_time(now)
            self._anchor_wall = now
            self._paused = paused

    # -- playing ------------------------------------------------------------------------------
    def _bag_time(self, wall: float) -> int:
        if self._paused:
            return self._anchor_bag
        return self._anchor_bag + int((wall - self._anchor_wall) * self.rate * 1e9)

    def due_time(self, ts_ns: int) -> float:
        """Monotonic time at which bag time ``ts_ns`` is reached (inf while paused)."""
        with self._lock:
            if self._paused:
                return float("inf")
            return self._anchor_wall + (ts_ns - self._anchor_bag) / (self.rate * 1e9)

    def _wait_until(self, ts_ns: int) -> bool:
        """Wait until ``ts_ns`` is due, publishing /clock meanwhile; False when stopped."""
        period = 1.0 / self.options.clock_rate_hz if self.options.clock_rate_hz > 0 else None
        while not self._stop.is_set():
            now = time.monotonic()
            due = self.due_time(ts_ns)
            if now >= due:
                return True
            wait = due - now
            if self._clock is not None and period is not None:
                next_tick = self._next_clock
                if now >= next_tick:
                    with self._lock:
                        bag_now = self._bag_time(now)
                    self._clock(min(bag_now, ts_ns))
                    self._next_clock = now + period
                    continue
                wait = min(wait, next_tick - now)
            self._stop.wait(min(wait, 0.05))
        return False

    def run(self) -> PlaybackReport:
        names = [t.name for t in self.topics]
        types = {t.name: t.msgtype for t in self.topics}
        loops = 0
        wall0 = time.monotonic()
        bag_covered = 0
        period_ns = self._typical_period_ns()
        with self._lock:
            self._anchor_wall, self._anchor_bag = time.monotonic(), self.start_ns
        self._next_clock = time.monotonic()
        try:
            while not self._stop.is_set():
                last_ts = None
                for msg in self.reader.messages(names, start_ns=self.start_ns):
                    if not self._wait_until(msg.timestamp_ns):
                        break
                    late = time.monotonic() - self.due_time(msg.timestamp_ns)
                    out = self.out_topic[msg.topic]
                    if self._clock is not None:
                        self._clock(msg.timestamp_ns)
                    self._publish(out, types[msg.topic], msg.data)
                    self.timing.add(late)
                    self.counts[out] += 1
                    last_ts = self.last_ts = msg.timestamp_ns
                    bag_covered = max(bag_covered, msg.timestamp_ns - self.start_ns)
                if self._stop.is_set() or not self.options.loop or last_ts is None:
                    break
                loops += 1
                # The next pass starts one typical message period after this pass's last message.
                next_start = self.due_time(last_ts + period_ns)
                with self._lock:
                    self._anchor_wall, self._anchor_bag = next_start, self.start_ns
        finally:
            self.reader.close()
        self.notes = list(dict.fromkeys(self.notes + self.reader.notes))
        return PlaybackReport(dict(self.counts), loops + 1, self.timing, time.monotonic() - wall0,
                              bag_covered * 1e-9, self.notes, self._stop.is_set())

    @property
    def position_s(self) -> float:
        """Bag time of the last message published, from the bag's start [s]."""
        if self.last_ts is None or self.reader.start_ns is None:
            return 0.0
        return (self.last_ts - self.reader.start_ns) * 1e-9

    def _typical_period_ns(self) -> int:
        """Message period of the busiest selected topic (the gap left between loops)."""
        count = max(t.count for t in self.topics)
        span = (self.reader.end_ns or self.start_ns) - self.reader.start_ns
        return int(span / (count - 1)) if count > 1 and span > 0 else 10**8
