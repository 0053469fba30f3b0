"""Collision events from per-step contacts: one event per new contact, debounced (no rclpy).

An object stays "in contact" while the avatar touches it and for ``debounce_s`` seconds after
the last touch, so grazing a wall while sliding along it is one collision, not fifty.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Touch:
    """The avatar touching object ``name`` (class ``cls``) now: point on the avatar and normal
    from the object to the avatar, world frame."""

    name: str
    cls: str
    position: tuple[float, float, float]
    normal: tuple[float, float, float]


@dataclass(frozen=True)
class CollisionEvent:
    """A new contact at time ``t`` [s] while moving at ``speed`` [m/s]; ``count`` numbers the
    collisions of the run from 1."""

    t: float
    name: str
    cls: str
    position: tuple[float, float, float]
    normal: tuple[float, float, float]
    speed: float
    count: int


class CollisionMonitor:
    def __init__(self, debounce_s: float = 0.5):
        if debounce_s < 0:
            raise ValueError(f"debounce must be non-negative, got {debounce_s}")
        self.debounce_s = float(debounce_s)
        self.count = 0
        self._last_touch: dict[str, float] = {}

    def update(self, t: float, touches: list[Touch], speed: float, clock: float | None = None) -> list[CollisionEvent]:
        """Contacts of the step at time ``t``; returns the events for contacts that just began.
        ``clock`` [s] (default ``t``) is the time the debounce is measured on: the simulator gives
        its trial clock, so whether a touch exactly ``debounce_s`` after the last is new does not
        depend on the absolute time the trial started at (float rounding)."""
        now = t if clock is None else clock
        events = []
        for touch in touches:
            last = self._last_touch.get(touch.name)
            if last is None or now - last > self.debounce_s:
                self.count += 1
                events.append(CollisionEvent(t, touch.name, touch.cls, touch.position, touch.normal, float(speed), self.count))
            self._last_touch[touch.name] = now
        return events
