"""Stale inputs of the spv node: dead or slow, which inputs stopped, and what the display shows
instead (no ROS).

*Dead or slow — told apart.* Every RASPV node announces that its process lives (DDS liveliness,
:mod:`raspv_common.liveliness`) and what its source is doing (``delivering``, ``paused``,
``down``); the spv node learns, for each input, the state of the node(s) publishing it — the
*producer*:

- ``alive`` (delivering): a gap in its data is *lateness*, not a fault. The input is stale only
  when nothing came for :func:`late_bound` (``max(LATE_S, PERIODS × period)``: a second at
  10 Hz or faster) — a node alive but hung, or starved beyond use; meanwhile scene results are
  carried into each new depth frame and overlays keep their last input. With hysteresis: after
  such a late episode the input counts again only once two messages come within
  :data:`RECOVER_S` of each other (no flicker at the bound).
- ``paused`` (a source's known pause: a replay paused by the user, a recording reopened to
  loop): never stale; when it delivers again its inputs' ages count from the moment it did.
- ``gone`` (its process died or is stopped — the DDS lease expired — or it announced ``down``,
  e.g. a camera unplugged) and ``unknown`` (a publisher that announces nothing, e.g. a foreign
  driver): judged by the gaps of its data alone, as a crash detector must be —

      bound = min(max(FLOOR_S, PERIODS × period), CAP_S), but never less than SLOW_FACTOR × period

  with ``period`` the median of its last :data:`HISTORY` arrival intervals (receive times on
  the monotonic clock). Until :data:`MIN_INTERVALS` intervals are known the bound is
  :data:`UNKNOWN_BOUND_S`. With the display tick (≤ 20 ms at 50 Hz) a dead input at 10 Hz or
  faster is shown within 300 ms of its last message.

*Never arrived.* The camera a mode needs (``required``) is stale until its first message: the
wearer sees the no-data ring from the node's first frame until the camera delivers (a graph
starting, an spv restarted, a recording that never opens). Scene outputs a scene mode needs are
stale once the camera has been arriving longer than their bound (the scene node starting: the
depth fallback shows the camera meanwhile). Other inputs that never arrived are not stale (an
overlay without input draws nothing). Waiting for a first message is not an *episode*;
:attr:`StalenessMonitor.episodes` counts inputs that had arrived and went stale
(:attr:`~StalenessMonitor.late_episodes` of them stale while their producer was alive — when it
went stale or later in the episode, as the log line describing it says).

What the wearer sees (:func:`plan_display`, documented in docs/spv.md "Stale inputs"):

- the camera (the mode's image: colour, else depth; for scene modes depth) is stale →
  the *no-data* pattern (:mod:`raspv_spv.no_data`): a dotted ring blinking at 2 Hz, never
  the last frame;
- the scene node's outputs (``scene``, ``scene_labels``) are stale → the mode falls back to
  :data:`FALLBACK_MODE` (``depth``, which needs only the camera);
- an overlay's input (path, guidance, stairs, segmentation, …) is stale → that overlay is
  dropped, the mode and other overlays stay.

When the inputs come back the normal mode resumes at the next frame. :meth:`StalenessMonitor.check`
is O(number of inputs) and allocates only when the set of stale inputs changes (display thread).
"""
from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

FLOOR_S = 0.10        # never call an input stale sooner than this after its last message [s]
PERIODS = 3.0         # ... nor before this many of its periods passed (two lost in a row are jitter)
CAP_S = 0.26          # ... and, from a dead producer, at most this late: + one display tick ≤ 0.3 s
SLOW_FACTOR = 1.2     # an input slower than CAP_S / SLOW_FACTOR: stale after 1.2 of its periods
HISTORY = 16          # arrival intervals the period is the median of
MIN_INTERVALS = 3     # ... and how many are needed before it is trusted
UNKNOWN_BOUND_S = 0.5  # the bound until then [s]
LATE_S = 1.0          # an alive producer's input is late, not stale, for this long [s] (scene results carried)
RECOVER_S = LATE_S / 2  # after a late episode: back when two messages come this close [s]

# producer states (raspv_common.liveliness announces them; the spv node resolves them per input)
ALIVE, PAUSED, GONE, UNKNOWN = "alive", "paused", "gone", "unknown"
PRODUCER_STATES = (ALIVE, PAUSED, GONE, UNKNOWN)

CAMERA_INPUTS = ("color", "depth")
SCENE_INPUTS = frozenset({"scene", "scene_labels"})
# inputs from other nodes whose loss the node notices (pose, head and odometry are not: the
# display reprojection holds the newest, and a still head sends no orientation)
MONITORED = frozenset({"color", "depth", "scene", "scene_labels", "nav_path", "nav_guidance", "stairs",
                       "segmentation"})
FALLBACK_MODE = "depth"
NO_DATA = "no_data"   # the PhospheneFrame.mode of the no-data pattern


def stale_bound(period_s: float | None) -> float:
    """Seconds without a message after which an input of ``period_s`` (None: not known yet)
    from a dead or silent producer is stale."""
    if period_s is None:
        return UNKNOWN_BOUND_S
    return max(min(max(FLOOR_S, PERIODS * period_s), CAP_S), SLOW_FACTOR * period_s)


def late_bound(period_s: float | None) -> float:
    """Seconds without a message after which an input of ``period_s`` from an *alive* producer
    is stale (hung or starved beyond use): :data:`LATE_S`, or 3 periods of a slower input."""
    return max(LATE_S, PERIODS * period_s) if period_s is not None else LATE_S


class _InputClock:
    __slots__ = ("first_s", "last_s", "resumed_s", "intervals", "bound_s", "late_s", "follows", "required",
                 "recovering", "late_counted")

    def __init__(self) -> None:
        self.first_s: float | None = None
        self.last_s: float | None = None
        self.resumed_s = float("-inf")              # its producer ended a pause then (display thread's clock)
        self.intervals: deque[float] = deque(maxlen=HISTORY)
        self.bound_s = UNKNOWN_BOUND_S
        self.late_s = LATE_S
        self.follows: _InputClock | None = None     # never arrived: stale once this one flows longer than its bound
        self.required = False                       # never arrived: stale (the camera a mode needs)
        self.recovering = False                     # went stale while its producer lived: hysteresis
        self.late_counted = False                   # this stale episode is counted as late (its producer alive)

    @property
    def period_s(self) -> float | None:
        return statistics.median(self.intervals) if len(self.intervals) >= MIN_INTERVALS else None

    def stale(self, now_s: float, producer: str) -> bool:
        if producer == PAUSED:
            return False
        if self.last_s is None:
            if self.required:
                return True
            f = self.follows
            if f is None or f.first_s is None:
                return False
            return now_s - f.first_s > (max(f.bound_s, LATE_S) if producer == ALIVE else f.bound_s)
        age = now_s - max(self.last_s, self.resumed_s)
        if producer == ALIVE:
            return self.recovering or age > self.late_s
        return age > self.bound_s


class StalenessMonitor:
    """Arrival times of the watched inputs and their producers' states → which are stale now
    (times: monotonic seconds).

    Thread-safe for one writer (ROS callbacks: :meth:`arrived`, :meth:`watch`) and one reader
    (the display thread: :meth:`check`): the clocks are replaced, not mutated in place, when
    the watched set changes.
    """

    def __init__(self, monitored: frozenset[str] = MONITORED) -> None:
        self.monitored = frozenset(monitored)    # the input names it watches (others are ignored)
        self._clocks: dict[str, _InputClock] = {}
        self._stale: frozenset[str] = frozenset()
        self._paused: set[str] = set()             # inputs whose producer was paused at the last check
        self.episodes = 0                        # times an input that had arrived went stale
        self.late_episodes = 0                   # ... of them past the late bound of an alive producer

    def watch(self, names: Iterable[str], expected_with: dict[str, str] | None = None,
              required: Iterable[str] = ()) -> None:
        """Watch ``names`` (those not in ``monitored`` are ignored); clocks of inputs still
        watched are kept, the others forgotten. ``expected_with`` {input: other input}: an input
        that never arrived is stale once the other one has been arriving for longer than its
        bound. ``required``: inputs stale while they never arrived (the mode's camera)."""
        wanted = self.monitored.intersection(names)
        required = set(required)
        clocks = {n: self._clocks.get(n) or _InputClock() for n in sorted(wanted)}
        for name, clock in clocks.items():
            clock.follows = clocks.get((expected_with or {}).get(name, ""))
            clock.required = name in required
        self._clocks = clocks

    @property
    def watched(self) -> frozenset[str]:
        return frozenset(self._clocks)

    def arrived(self, name: str, now_s: float) -> None:
        """A message of input ``name`` was received at ``now_s``."""
        clock = self._clocks.get(name)
        if clock is None:
            return
        if clock.last_s is not None and now_s > clock.last_s:
            interval = now_s - clock.last_s
            clock.intervals.append(interval)
            period = clock.period_s
            clock.bound_s, clock.late_s = stale_bound(period), late_bound(period)
            if clock.recovering and interval <= RECOVER_S:
                clock.recovering = False
        if clock.first_s is None:
            clock.first_s = now_s
        clock.last_s = now_s

    def check(self, now_s: float, producers: Mapping[str, str] | None = None) -> frozenset[str]:
        """The inputs stale at ``now_s`` given their producers' states (input → one of
        :data:`PRODUCER_STATES`; missing: :data:`UNKNOWN`). The same object as last time while
        nothing changed."""
        producers = producers or {}
        if self._paused or PAUSED in producers.values():
            paused = {n for n, state in producers.items() if state == PAUSED}
            for name in self._paused - paused:          # delivering again: its age counts from now
                if producers.get(name) == ALIVE and (clock := self._clocks.get(name)) is not None:
                    clock.resumed_s = now_s
            self._paused = paused
        changed = False
        for name, clock in self._clocks.items():
            if clock.stale(now_s, producers.get(name, UNKNOWN)) != (name in self._stale):
                changed = True
                break
        if changed:
            new = frozenset(n for n, c in self._clocks.items() if c.stale(now_s, producers.get(n, UNKNOWN)))
            for name in new - self._stale:
                clock = self._clocks[name]
                if clock.last_s is None:
                    continue                     # waiting for a first message: not an episode
                self.episodes += 1
                clock.late_counted = False
            self._stale = new
        for name in self._stale:                 # stale while its producer lives: a late episode, counted once
            clock = self._clocks[name]
            if not clock.late_counted and clock.last_s is not None and producers.get(name, UNKNOWN) == ALIVE:
                clock.late_counted = clock.recovering = True
                self.late_episodes += 1
        return self._stale

    def never_arrived(self, name: str) -> bool:
        """True while watched input ``name`` has not delivered a first message."""
        clock = self._clocks.get(name)
        return clock is not None and clock.last_s is None

    def describe(self, name: str, now_s: float, producer: str = UNKNOWN) -> str:
        """'scene (nothing for 0.31 s; expected every 0.10 s; its node gone)' for logs."""
        clock = self._clocks.get(name)
        node = {ALIVE: "; its node alive but late", GONE: "; its node gone", PAUSED: "; paused"}.get(producer, "")
        if clock is None or clock.last_s is None:
            return f"{name} (nothing yet{node})"
        period = clock.period_s
        expected = f"; expected every {period:.2f} s" if period is not None else ""
        return f"{name} (nothing for {now_s - clock.last_s:.2f} s{expected}{node})"


@dataclass(frozen=True)
class DisplayPlan:
    """What the display shows: ``mode`` (:data:`NO_DATA` for the no-data pattern) and
    ``overlays``, given the inputs in ``stale``; ``normal`` when nothing was changed."""

    mode: str
    overlays: tuple[str, ...]
    stale: frozenset[str] = frozenset()
    normal: bool = True

    @property
    def no_data(self) -> bool:
        return self.mode == NO_DATA

    def describe(self, configured_mode: str) -> str:
        if self.normal:
            return f"mode {configured_mode}"
        if self.no_data:
            return "the no-data pattern (blinking ring)"
        what = f"mode {self.mode}" + (" (fallback)" if self.mode != configured_mode else "")
        return what + (f" with overlays {', '.join(self.overlays)}" if self.overlays else " without overlays")


def camera_input(mode_needs: frozenset[str]) -> str:
    """The camera image a mode runs on: colour when it reads colour, else depth."""
    return "color" if "color" in mode_needs else "depth"


def watched_inputs(mode_needs: frozenset[str], overlay_reads: Iterable[frozenset[str]]) -> frozenset[str]:
    """Inputs to watch (and subscribe to) for a mode and its overlays: the mode's camera and
    scene inputs, the fallback's camera (depth) for scene modes, and what overlays read."""
    out = set(mode_needs) | {camera_input(mode_needs)}
    if mode_needs & SCENE_INPUTS:
        out.add(camera_input(frozenset()))
    for reads in overlay_reads:
        out |= reads
    return frozenset(out) & MONITORED


def required_inputs(mode_needs: frozenset[str]) -> frozenset[str]:
    """The camera inputs that show the no-data ring while they never arrived: the mode's camera
    (colour, else depth) and, for scene modes, the depth of the fallback."""
    out = {camera_input(mode_needs)}
    if mode_needs & SCENE_INPUTS:
        out.add(camera_input(frozenset()))
    return frozenset(out)


def expected_with(mode_needs: frozenset[str]) -> dict[str, str]:
    """{input: the input whose flow makes its absence stale}: a scene mode's scene inputs follow
    the camera of its fallback (see the module's docstring)."""
    return {name: camera_input(frozenset()) for name in mode_needs & SCENE_INPUTS}


def plan_display(mode: str, mode_needs: frozenset[str], overlays: Sequence[tuple[str, frozenset[str]]],
                 stale: frozenset[str]) -> DisplayPlan:
    """What to show for ``mode`` (reading ``mode_needs``) and ``overlays`` ((name, inputs it
    reads, needed or optional), in order) while the inputs in ``stale`` are stale."""
    names = tuple(n for n, _ in overlays)
    if not stale:
        return DisplayPlan(mode, names)
    shown_mode, needs = mode, mode_needs
    if mode_needs & SCENE_INPUTS & stale:
        shown_mode, needs = FALLBACK_MODE, frozenset({"depth", "camera"})
    if camera_input(needs) in stale:
        return DisplayPlan(NO_DATA, (), stale, False)
    kept = tuple(n for n, reads in overlays if not reads & stale)
    return DisplayPlan(shown_mode, kept, stale, shown_mode == mode and kept == names)
