"""Stale inputs of the spv node: which inputs stopped, and what the display shows instead (no ROS).

An input is *stale* when it has arrived before and nothing came for longer than its bound:

    bound = min(max(FLOOR_S, PERIODS × period), CAP_S), but never less than SLOW_FACTOR × period

with ``period`` the median of its last :data:`HISTORY` arrival intervals (receive times on the
monotonic clock, so a replayed bag's stamps do not matter). Until :data:`MIN_INTERVALS` intervals
are known (a source's first frames come irregularly) the bound is :data:`UNKNOWN_BOUND_S`. With
the display tick (≤ 20 ms at 50 Hz) that shows the change, an input at 10 Hz or faster is
detected and shown within 300 ms of its last message; an input slower than ``CAP_S /
SLOW_FACTOR`` (~6 Hz) cannot be told apart from its own gaps that fast and gets 1.2 periods.

An input that never arrived is not stale (the mode waits for it, phosphenes dark, as before),
except the scene node's outputs a scene mode needs: once the camera has been arriving for
longer than its bound without them (the scene node starting, or an spv restarted while the scene
node's first messages to it are still on their way) they are stale, and the depth fallback
shows the camera meanwhile.

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
from typing import Iterable, Sequence

FLOOR_S = 0.10        # never call an input stale sooner than this after its last message [s]
PERIODS = 3.0         # ... nor before this many of its periods passed (two lost in a row are jitter)
CAP_S = 0.26          # ... and at most this late: + one display tick ≤ 0.3 s detected and shown
SLOW_FACTOR = 1.2     # an input slower than CAP_S / SLOW_FACTOR: stale after 1.2 of its periods
HISTORY = 16          # arrival intervals the period is the median of
MIN_INTERVALS = 3     # ... and how many are needed before it is trusted
UNKNOWN_BOUND_S = 0.5  # the bound until then [s]

CAMERA_INPUTS = ("color", "depth")
SCENE_INPUTS = frozenset({"scene", "scene_labels"})
# inputs from other nodes whose loss the node notices (pose, head and odometry are not: the
# display reprojection holds the newest, and a still head sends no orientation)
MONITORED = frozenset({"color", "depth", "scene", "scene_labels", "nav_path", "nav_guidance", "stairs",
                       "segmentation"})
FALLBACK_MODE = "depth"
NO_DATA = "no_data"   # the PhospheneFrame.mode of the no-data pattern


def stale_bound(period_s: float | None) -> float:
    """Seconds without a message after which an input of ``period_s`` (None: not known yet) is stale."""
    if period_s is None:
        return UNKNOWN_BOUND_S
    return max(min(max(FLOOR_S, PERIODS * period_s), CAP_S), SLOW_FACTOR * period_s)


class _InputClock:
    __slots__ = ("first_s", "last_s", "intervals", "bound_s", "follows")

    def __init__(self) -> None:
        self.first_s: float | None = None
        self.last_s: float | None = None
        self.intervals: deque[float] = deque(maxlen=HISTORY)
        self.bound_s = UNKNOWN_BOUND_S
        self.follows: _InputClock | None = None     # never arrived: stale once this one flows longer than its bound

    @property
    def period_s(self) -> float | None:
        return statistics.median(self.intervals) if len(self.intervals) >= MIN_INTERVALS else None

    def stale(self, now_s: float) -> bool:
        if self.last_s is not None:
            return now_s - self.last_s > self.bound_s
        f = self.follows
        return f is not None and f.first_s is not None and now_s - f.first_s > f.bound_s


class StalenessMonitor:
    """Arrival times of the watched inputs → which are stale now (times: monotonic seconds).

    Thread-safe for one writer (ROS callbacks: :meth:`arrived`, :meth:`watch`) and one reader
    (the display thread: :meth:`check`): the clocks are replaced, not mutated in place, when
    the watched set changes.
    """

    def __init__(self) -> None:
        self._clocks: dict[str, _InputClock] = {}
        self._stale: frozenset[str] = frozenset()
        self.episodes = 0                        # times an input went stale

    def watch(self, names: Iterable[str], expected_with: dict[str, str] | None = None) -> None:
        """Watch ``names`` (those not in :data:`MONITORED` are ignored); clocks of inputs still
        watched are kept, the others forgotten. ``expected_with`` {input: other input}: an input
        that never arrived is stale once the other one has been arriving for longer than its bound."""
        wanted = MONITORED.intersection(names)
        clocks = {n: self._clocks.get(n) or _InputClock() for n in sorted(wanted)}
        for name, clock in clocks.items():
            clock.follows = clocks.get((expected_with or {}).get(name, ""))
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
            clock.intervals.append(now_s - clock.last_s)
            clock.bound_s = stale_bound(clock.period_s)
        if clock.first_s is None:
            clock.first_s = now_s
        clock.last_s = now_s

    def check(self, now_s: float) -> frozenset[str]:
        """The inputs stale at ``now_s`` (the same object as last time while nothing changed)."""
        changed = False
        for name, clock in self._clocks.items():
            if clock.stale(now_s) != (name in self._stale):
                changed = True
                break
        if changed:
            new = frozenset(n for n, c in self._clocks.items() if c.stale(now_s))
            self.episodes += len(new - self._stale)
            self._stale = new
        return self._stale

    def describe(self, name: str, now_s: float) -> str:
        """'scene (nothing for 0.31 s; expected every 0.10 s)' for logs."""
        clock = self._clocks.get(name)
        if clock is None or clock.last_s is None:
            return f"{name} (never arrived)"
        period = clock.period_s
        expected = f"; expected every {period:.2f} s" if period is not None else ""
        return f"{name} (nothing for {now_s - clock.last_s:.2f} s{expected})"


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
