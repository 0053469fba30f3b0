"""Who controls the avatar, and stopping it when the controls go quiet (no I/O, no clock).

Rule: the controller is the earliest-connected client that wants control (a client's hello
says ``"role": "control"`` or ``"watch"``; ``{"type": "control", "want": …}`` changes it later).
Everyone else watches: they receive frames, and their head/teleop/key/parameter messages are
ignored (counted, not refused). When the controller leaves or gives control up, the next
earliest-connected client that wants it takes over.
"""
from __future__ import annotations

import math


class ControlArbiter:
    def __init__(self) -> None:
        self._order: list[int] = []          # client ids in connection order
        self._wants: dict[int, bool] = {}

    @property
    def controller(self) -> int | None:
        return next((c for c in self._order if self._wants[c]), None)

    def add(self, client: int, wants: bool) -> bool:
        """Register a new client; True if the controller changed."""
        before = self.controller
        self._order.append(client)
        self._wants[client] = wants
        return self.controller != before

    def remove(self, client: int) -> bool:
        before = self.controller
        if client in self._wants:
            self._order.remove(client)
            del self._wants[client]
        return self.controller != before

    def set_want(self, client: int, wants: bool) -> bool:
        before = self.controller
        if client in self._wants:
            self._wants[client] = wants
        return self.controller != before


class DeadMan:
    """Teleop watchdog: after ``timeout_s`` without teleop input, one zero twist goes out.

    Times are seconds of any monotonic clock. A zero twist is due only if the last command
    sent was not already zero, so an idle client causes no traffic.
    """

    def __init__(self, timeout_s: float = 0.5) -> None:
        if not (timeout_s > 0 and math.isfinite(timeout_s)):
            raise ValueError(f"dead-man timeout must be a positive number of seconds, got {timeout_s!r}")
        self.timeout_s = timeout_s
        self.last_input = -math.inf
        self.moving = False                   # the last command sent was not zero

    def input(self, linear: float, angular: float, now: float) -> None:
        self.last_input = now
        self.moving = linear != 0.0 or angular != 0.0

    def deadline(self) -> float | None:
        """When a stop is due if nothing else arrives (None: nothing to stop)."""
        return self.last_input + self.timeout_s if self.moving else None

    def poll(self, now: float) -> bool:
        """True exactly once when the timeout expired on a moving command: send a zero twist."""
        if self.moving and now - self.last_input >= self.timeout_s:
            self.moving = False
            return True
        return False

    def release(self) -> bool:
        """The controller left: True if a zero twist must go out now."""
        was_moving, self.moving = self.moving, False
        self.last_input = -math.inf
        return was_moving
