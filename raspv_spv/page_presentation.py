"""Does the wearer's page keep the display rate? The display budget (``display_budget.py``)
prices the spv node's frame from the configuration; what the page composites depends on the
browser, the headset's processor and, when the page runs beside the graph, the same cores. The
controlling page reports what it composited (frames per second, once a second, and the refresh
clock it presents on) through the bridge (``/hmd/presentation``); this core turns the reports
into a verdict per display rate for ``/spv/status``:

- asked: the display rate, or the page's refresh when that is lower (a 60 Hz page cannot show
  90 frames a second);
- over the newest ``WINDOW_S`` of reports made at that rate (at least ``MIN_REPORTS``), the
  median composited rate must be ≥ asked − ``MARGIN_FPS`` (the issue's 85 fps at 90 Hz, 45 at
  50 Hz); otherwise the rate is refused with the reason, e.g. "the page composited 57.6 of 90
  frames/s over 10 s on this machine: 90 Hz is not kept here".

Reports made within ``SETTLE_S`` after a rate change are not counted (the page's counter spans
the change). A verdict is kept per rate after the rate changes, stamped with its age, so the
status says what 90 Hz did even after switching back to 50. No ROS here.
"""
from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass

WINDOW_S = 10.0        # reports judged together [s]
MIN_REPORTS = 5        # fewer: no verdict yet
MARGIN_FPS = 5.0       # composited frames/s a page may fall below the asked rate and still keep it
SETTLE_S = 2.0         # reports this soon after a rate change are not counted [s]
MAX_FPS = 1000.0


@dataclass(frozen=True)
class PageVerdict:
    """What the page composited at one display rate."""

    rate_hz: float            # the display rate the reports were made at
    asked_fps: float          # min(rate, the page's refresh)
    presented_fps: float      # median of the window's reports
    refresh_hz: float | None  # the page's presentation clock, None: the browser's frame callback
    reports: int
    kept: bool
    measured_at: float        # monotonic time of the newest report [s]

    @property
    def reason(self) -> str:
        if self.kept:
            return ""
        clock = f"on its {self.refresh_hz:g} Hz clock" if self.refresh_hz else "on the browser's frame callback"
        lower = " (the page's refresh is below the display rate)" if self.asked_fps < self.rate_hz else ""
        return (f"the page composited {self.presented_fps:.1f} of {self.asked_fps:g} frames/s {clock} over "
                f"{WINDOW_S:g} s{lower}: {self.rate_hz:g} Hz is not kept here (need ≥ "
                f"{self.asked_fps - MARGIN_FPS:g}); a lower rate, a lighter load or the headset's own processor")

    def as_status(self, now: float) -> dict:
        out = {"rate_hz": self.rate_hz, "presented_fps": round(self.presented_fps, 1), "asked_fps": self.asked_fps,
               "refresh_hz": self.refresh_hz, "verdict": "ok" if self.kept else "refused",
               "age_s": round(max(0.0, now - self.measured_at), 1)}
        if not self.kept:
            out["reason"] = self.reason
        return out


def check_report(fps: float, refresh_hz: float | None) -> None:
    """Raise ValueError for a report no page can make."""
    if not 0.0 <= fps <= MAX_FPS:
        raise ValueError(f"presented fps {fps!r} outside 0..{MAX_FPS:g}")
    if refresh_hz is not None and not 0.0 < refresh_hz <= MAX_FPS:
        raise ValueError(f"refresh {refresh_hz!r} Hz outside (0, {MAX_FPS:g}]")


class PagePresentation:
    """Reports of the controlling page → a verdict per display rate (see the module docstring)."""

    def __init__(self) -> None:
        self._reports: deque[tuple[float, float, float | None]] = deque()   # (t [s], fps, refresh)
        self._rate_hz: float | None = None
        self._rate_since = 0.0
        self.verdicts: dict[float, PageVerdict] = {}

    def add(self, fps: float, refresh_hz: float | None, rate_hz: float, now: float) -> PageVerdict | None:
        """One report made while the display ran at ``rate_hz``, received at ``now`` (monotonic, s).
        Returns the rate's verdict when it changed (a first verdict, or kept ↔ refused)."""
        check_report(fps, refresh_hz)
        if rate_hz != self._rate_hz:
            self._rate_hz, self._rate_since = rate_hz, now
            self._reports.clear()
        if now - self._rate_since < SETTLE_S:
            return None
        self._reports.append((now, float(fps), refresh_hz))
        while self._reports and self._reports[0][0] < now - WINDOW_S:
            self._reports.popleft()
        if len(self._reports) < MIN_REPORTS or now - self._rate_since < SETTLE_S + WINDOW_S * 0.5:
            return None
        refresh = self._reports[-1][2]
        asked = min(rate_hz, refresh) if refresh else rate_hz
        presented = statistics.median(r[1] for r in self._reports)
        verdict = PageVerdict(rate_hz, float(asked), presented, refresh, len(self._reports),
                              presented >= asked - MARGIN_FPS, now)
        previous = self.verdicts.get(rate_hz)
        self.verdicts[rate_hz] = verdict
        return verdict if previous is None or previous.kept != verdict.kept else None

    def status(self, now: float) -> dict[str, dict]:
        """``{"<rate>": PageVerdict.as_status}`` for every rate the page was judged at."""
        return {f"{rate:g}": v.as_status(now) for rate, v in sorted(self.verdicts.items())}
