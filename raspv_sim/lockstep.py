"""Lockstep stepping of the simulator (no rclpy): the world advances one step of sim time each
time a controller has answered the last published frame — as fast as the graph can close the
loop, independent of the wall clock, and the same on a loaded or an idle machine.

The sim node publishes frame k stamped with its sim time t_k and waits. A controller (a
scripted subject) answers with a command stamped t_k (``/sim/lockstep``, TwistStamped): the
world steps 1/rate s with that command. An answer for an older frame is ignored; with no
answer within ``timeout_s`` of wall time the world steps anyway with the last command (and the
timeout is counted), so a graph without a controller still runs, slowly.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Lockstep:
    timeout_s: float = 2.0
    waiting_for: float | None = None        # sim time [s] of the frame awaiting an answer
    since: float = 0.0                      # wall time [s] it was published
    command: tuple[float, float] = (0.0, 0.0)
    ready: bool = True                      # step now (nothing published yet, or answered)
    timeouts: int = 0

    def __post_init__(self) -> None:
        if not self.timeout_s > 0:
            raise ValueError(f"lockstep timeout must be positive, got {self.timeout_s}")

    def published(self, stamp: float, wall: float) -> None:
        """Frame with sim time ``stamp`` went out at wall time ``wall``: wait for its answer."""
        self.waiting_for, self.since, self.ready = stamp, wall, False

    def answer(self, stamp: float, linear: float, angular: float) -> bool:
        """A controller's command for the frame of sim time ``stamp``; True if it releases the step."""
        if self.waiting_for is None or stamp + 1e-6 < self.waiting_for:   # stamps carry ns rounding
            return False
        self.command = (float(linear), float(angular))
        self.ready = True
        return True

    def poll(self, wall: float) -> bool:
        """True when the step is due: answered, or the answer is ``timeout_s`` late (counted)."""
        if self.ready:
            return True
        if wall - self.since >= self.timeout_s:
            self.timeouts += 1
            self.ready = True
        return self.ready

    def take(self) -> tuple[float, float]:
        """Consume the release: the command to step with."""
        self.ready = False
        return self.command
