"""The experimenter's view and keys, and when a trial ends — as state machines without I/O (no
rclpy, no terminal), so they are tested directly; :mod:`raspv_experiments.terminal` draws the
line and reads the keys.

Keys: ``p`` pause / continue (the world holds still; the trial clock, which is simulation time,
stops with it), ``r`` repeat the current trial (it is recorded as ``repeated`` and run again),
``s`` skip it (recorded as ``skipped``), ``q`` quit (the session can be resumed with
``--resume``), Enter: start the trial / end a break when no headset client does.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

KEYS_HELP = "p pause · r repeat · s skip · q quit · Enter start"


@dataclass
class ExperimenterControl:
    """Experimenter's requests, held until the runner takes them."""

    paused: bool = False
    request: str | None = None          # "repeat", "skip" or "quit"
    start: bool = False                 # Enter: start the trial / end the break
    message: str = ""

    def key(self, key: str) -> None:
        k = key.lower() if len(key) == 1 else key
        if k == "p":
            self.paused = not self.paused
            self.message = "paused: the world holds still (p continues)" if self.paused else "continuing"
        elif k in ("r", "s", "q"):
            self.request = {"r": "repeat", "s": "skip", "q": "quit"}[k]
            self.paused = False
            self.message = {"repeat": "repeating this trial", "skip": "skipping this trial",
                            "quit": "quitting (resume later with --resume)"}[self.request]
        elif k in ("\n", "\r", "enter"):
            self.start = True
        else:
            self.message = f"key {key!r} does nothing; {KEYS_HELP}"

    def take_request(self) -> str | None:
        req, self.request = self.request, None
        return req

    def take_start(self) -> bool:
        start, self.start = self.start, False
        return start


@dataclass
class TrialMonitor:
    """Decides when a running trial ends: the base inside the goal region, the time limit (in
    simulation time since the start), or the subject's abort. Positions count only once one
    near the start pose came in (``armed``): poses still in flight from before the reset — the
    previous trial may have ended in this goal — are ignored."""

    goal_x: float
    goal_y: float
    goal_radius: float
    time_limit: float
    start_t: float
    t: float = 0.0
    start_x: float | None = None
    start_y: float | None = None
    arm_radius: float = 0.5
    armed: bool = False
    outcome: str | None = None
    collisions: list[str] = field(default_factory=list)

    @property
    def elapsed(self) -> float:
        return max(0.0, self.t - self.start_t)

    def update(self, t: float | None = None, x: float | None = None, y: float | None = None) -> str | None:
        """New sim time [s] and/or base position [m, W]; returns the outcome once decided."""
        if self.outcome is not None:
            return self.outcome
        if t is not None and math.isfinite(t):
            self.t = max(self.t, t)
        if x is not None and y is not None and not self.armed:
            self.armed = self.start_x is None or math.hypot(x - self.start_x, y - self.start_y) <= self.arm_radius
        if self.armed and x is not None and y is not None and \
                math.hypot(x - self.goal_x, y - self.goal_y) <= self.goal_radius:
            self.outcome = "goal"
        elif self.elapsed >= self.time_limit - 1e-6:        # sim time sums steps: 39.99999… is the limit
            self.outcome = "time_limit"
        return self.outcome

    def abort(self) -> None:
        if self.outcome is None:
            self.outcome = "aborted"

    def collision(self, what: str) -> None:
        self.collisions.append(what)


@dataclass
class ClockWatch:
    """Whether the simulation clock stands still: the wall seconds the runner itself watched it
    not advance. A gap between two polls longer than ``max_gap_s`` — the runner was suspended or
    starved of CPU (a paused process group, a loaded machine), so the graph was too — counts as
    ``max_gap_s`` only: a pause of the whole machine is not the graph's stall."""

    stall_s: float = 60.0               # watched seconds without a new sim time: stuck
    max_gap_s: float = 1.0              # the most one poll-to-poll gap counts
    still_s: float = 0.0
    last_t: float | None = None
    last_wall: float | None = None

    def update(self, sim_t: float | None, wall: float) -> bool:
        """A poll: the sim time [s] (None: none yet) at monotonic ``wall`` [s]; True once stuck."""
        if self.last_wall is not None:
            if sim_t is not None and sim_t != self.last_t:
                self.still_s = 0.0
            else:
                self.still_s += min(max(0.0, wall - self.last_wall), self.max_gap_s)
        self.last_t, self.last_wall = sim_t, wall
        return self.still_s > self.stall_s

    def reset(self) -> None:
        """Start again (after the experimenter's pause: the world held still on purpose)."""
        self.still_s, self.last_t, self.last_wall = 0.0, None, None


@dataclass
class ViewState:
    """What the experimenter's status line shows."""

    done: int = 0                       # trials finished in the session
    total: int = 0
    index: int = 0                      # the current trial's planned index
    label: str = ""
    phase: str = "starting"             # starting, instructions, running, paused, break, finished
    elapsed: float = 0.0                # s of simulation time in the trial
    time_limit: float = 0.0
    collisions: int = 0
    last_hit: str = ""
    message: str = ""
    started: float | None = None        # monotonic time [s] the run started
    done_before: int = 0                # trials done before this run (resumed sessions)
    now: float | None = None            # monotonic time of this view (None: time.monotonic())


def elapsed_and_eta(done: int, total: int, elapsed: float) -> str:
    """``elapsed 3:12, ETA 5:40`` from the units done in ``elapsed`` seconds (no ETA before the first)."""
    text = f"elapsed {_clock(elapsed)}"
    if done > 0 and total > done:
        text += f", ETA {_clock(elapsed / done * (total - done))}"
    return text


def _clock(seconds: float) -> str:
    s = int(round(max(0.0, seconds)))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


def progress_bar(done: int, total: int, width: int = 20) -> str:
    filled = 0 if total <= 0 else round(width * min(done, total) / total)
    return "[" + "#" * filled + "." * (width - filled) + "]"


def status_line(v: ViewState, width: int = 100) -> str:
    """One line: progress over the session, the trial, its time, collisions, the last message."""
    import time

    parts = [f"{progress_bar(v.done, v.total)} {v.done}/{v.total}"]
    if v.started is not None:
        now = time.monotonic() if v.now is None else v.now
        parts[0] += " " + elapsed_and_eta(v.done - v.done_before, v.total - v.done_before, now - v.started)
    if v.index:
        parts.append(f"trial {v.index}: {v.label}")
    parts.append(v.phase)
    if v.phase in ("running", "paused"):
        parts.append(f"{v.elapsed:5.1f}/{v.time_limit:.0f} s")
        parts.append(f"{v.collisions} collision{'s' if v.collisions != 1 else ''}"
                     + (f" (last: {v.last_hit})" if v.last_hit else ""))
    if v.message:
        parts.append(v.message)
    line = " | ".join(parts)
    return line if len(line) <= width else line[: max(0, width - 1)] + "…"
