"""Lockstep stepping of the simulator (no rclpy): the world advances one step of sim time each
time a controller has answered the last published frame — as fast as the graph can close the
loop, independent of the wall clock, and the same on a loaded or an idle machine.

The sim node publishes frame k stamped with its sim time t_k and waits. A controller (a
scripted subject) answers with a command stamped t_k (``/sim/lockstep``, TwistStamped): the
world steps 1/rate s with that command. ``participants`` are further nodes that must answer
every frame too before the world steps (their answers carry their name as ``frame_id`` and no
command, e.g. the planner once its path for the frame is out), so what they compute from frame
k is the same in every run. An answer for an older frame is ignored; with no answer within
``timeout_s`` of wall time the world steps anyway with the last command (and the timeout is
counted), so a graph without a controller still runs, slowly — unless ``strict``: then the
world waits for every answer however long it takes (counted as ``late`` once per frame), since
a step taken on a timeout makes the run depend on the machine's load (a scripted session at
load 10-16 parted from its repetition where a frame's answer took over 2 s).

``hold`` stops stepping altogether (no timeouts either): with ``lockstep_hold`` the sim node
holds between trials and from the moment a trial reaches its goal or time limit, so the frames
every node sees — and so every trial record — are the same each time a session runs.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Lockstep:
    timeout_s: float = 2.0
    participants: frozenset[str] = frozenset()   # further answerers of every frame (by frame_id)
    waiting_for: float | None = None        # sim time [s] of the frame awaiting an answer
    since: float = 0.0                      # wall time [s] it was published
    command: tuple[float, float] = (0.0, 0.0)
    ready: bool = True                      # step now (nothing published yet, or answered)
    hold: bool = False                      # never step (between trials)
    timeouts: int = 0
    strict: bool = False                    # never step on a timeout: wait for the answers
    late: int = 0                           # frames whose answers took longer than timeout_s (strict)
    _controller: bool = False               # the controller answered the awaited frame
    _answered: set[str] = field(default_factory=set)
    _late_counted: bool = False

    def __post_init__(self) -> None:
        if not self.timeout_s > 0:
            raise ValueError(f"lockstep timeout must be positive, got {self.timeout_s}")
        self.participants = frozenset(self.participants)

    def published(self, stamp: float, wall: float) -> None:
        """Frame with sim time ``stamp`` went out at wall time ``wall``: wait for its answers."""
        self.waiting_for, self.since, self.ready = stamp, wall, False
        self._late_counted = False
        self._controller, self._answered = False, set()

    def answer(self, stamp: float, linear: float, angular: float, who: str = "") -> bool:
        """An answer for the frame of sim time ``stamp``: the controller's command, or (``who`` one
        of ``participants``) a participant's; True if it releases the step."""
        if self.waiting_for is None or stamp + 1e-6 < self.waiting_for:   # stamps carry ns rounding
            return False
        if who in self.participants:
            self._answered.add(who)
        else:
            self.command = (float(linear), float(angular))
            self._controller = True
        if self._controller and self._answered >= self.participants:
            self.ready = True
        return self.ready

    def restart(self) -> None:
        """A new trial: step at once with no command; answers to earlier frames no longer count."""
        self.waiting_for, self.ready, self.command = None, True, (0.0, 0.0)
        self._controller, self._answered = False, set()

    def poll(self, wall: float) -> bool:
        """True when the step is due: answered, or the answer is ``timeout_s`` late (counted)."""
        if self.hold:
            return False
        if self.ready:
            return True
        if wall - self.since >= self.timeout_s:
            if self.strict:
                if not self._late_counted:
                    self.late, self._late_counted = self.late + 1, True
                return False
            self.timeouts += 1
            self.ready = True
        return self.ready

    def missing(self) -> list[str]:
        """Who has not answered the awaited frame yet ("controller" and participants' names)."""
        return ((["controller"] if not self._controller else [])
                + sorted(self.participants - self._answered))

    def take(self) -> tuple[float, float]:
        """Consume the release: the command to step with."""
        self.ready = False
        return self.command
