"""Messages a subscriber never got, from the publishers' sequence numbers (no ROS imports).

DDS numbers each publisher's messages 1, 2, 3, …; a subscription whose history (keep-last N)
overflowed before it took them — a recorder that fell behind — loses the oldest without any
event. The numbers it did take show the holes. The middleware does not tell which publisher
sent a message, so each number continues the stream whose last number is the closest below it
(a topic's publishers number their messages independently; a restarted one starts again at 1,
a new stream): exact for a topic with one publisher, and for several unless their numbers
interleave across a hole.
"""
from __future__ import annotations

STALE_STREAM_S = 30.0     # a stream not continued for this long is forgotten (its publisher gone) [s]
MAX_JUMP = 100_000        # a larger step is a different publisher, not a hole


class SequenceGaps:
    """Counts, per topic, the messages missing between the sequence numbers seen."""

    def __init__(self) -> None:
        self._streams: dict[str, dict[int, float]] = {}   # topic -> {last number: time seen [s]}
        self.lost: dict[str, int] = {}

    def seen(self, topic: str, number: int, now_s: float) -> int:
        """Note message ``number`` (0: the middleware does not number them) of ``topic`` taken
        at ``now_s``; how many it shows lost."""
        if number <= 0:
            return 0
        streams = self._streams.setdefault(topic, {})
        below = [last for last in streams if last < number and number - last <= MAX_JUMP]
        missing = 0
        if below:
            last = max(below)
            del streams[last]
            missing = number - last - 1
            if missing:
                self.lost[topic] = self.lost.get(topic, 0) + missing
        for last, t in list(streams.items()):
            if now_s - t > STALE_STREAM_S:
                del streams[last]
        streams[number] = now_s
        return missing

    @property
    def total(self) -> int:
        return sum(self.lost.values())
