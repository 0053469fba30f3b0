"""What the wearer saw: the share of displayed phosphene frames in the configured representation,
and which fallbacks were shown instead, for how long (no rclpy).

The spv node shows a fallback while inputs are stale — a scene mode falls back to ``depth``, a
stopped camera shows the ``no_data`` ring, an overlay whose input is stale is dropped — and
every ``/spv/frame`` (raspv_msgs/PhospheneFrame) says what was shown (``mode``, ``overlays``)
beside what the node is set to (``configured_mode``, ``configured_overlays``). One function,
:func:`shown_share`, turns a sequence of frames into the share; the experiment runner records it
per trial, ``raspv bag info`` prints it for a recording.

- A frame counts as **own** when it shows the expected mode and overlays: those given (a trial's
  condition), else the frame's configured ones, else — older recordings without
  ``configured_mode`` — the most frequent mode and overlays among frames that are not
  ``no_data`` (``inferred`` says so).
- Every other frame is a **fallback**, counted per kind: ``no_data``, ``mode:<shown>`` (a mode
  shown instead of the expected one), ``overlays:-<name>`` (an expected overlay dropped) and
  ``overlays:+<name>`` (one shown that is not expected). A frame can be of several kinds.
- **Seconds**: each frame lasts until the next one's display stamp; the last one for the median
  frame period, or until ``end_t`` when given. Stamps are display times [s] (sim time in
  lockstep sessions).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

NO_DATA = "no_data"
DEFAULT_THRESHOLD = 0.995            # a trial whose share is below this is flagged in the report


@dataclass(frozen=True)
class ShownFrame:
    """One displayed frame: display stamp ``t`` [s], what was shown, what the node was set to
    ("" / () when the recording predates ``configured_mode``)."""

    t: float
    mode: str
    overlays: tuple[str, ...] = ()
    configured_mode: str = ""
    configured_overlays: tuple[str, ...] = ()


@dataclass
class ShownShare:
    frames: int = 0
    own_frames: int = 0
    seconds: float = 0.0
    own_seconds: float = 0.0
    expected_mode: str = ""
    expected_overlays: tuple[str, ...] = ()
    inferred: bool = False                     # the expected mode was inferred (no configured_mode)
    fallbacks: dict[str, dict[str, float]] = field(default_factory=dict)   # kind → {frames, seconds}

    @property
    def share(self) -> float:
        """Fraction of frames shown as expected (1.0 when there were no frames: nothing else was shown)."""
        return self.own_frames / self.frames if self.frames else 1.0

    def as_dict(self) -> dict:
        return {"frames": self.frames, "own_frames": self.own_frames, "own_share": round(self.share, 6),
                "seconds": round(self.seconds, 4), "own_seconds": round(self.own_seconds, 4),
                "expected_mode": self.expected_mode, "expected_overlays": list(self.expected_overlays),
                "expected_inferred": self.inferred,
                "fallbacks": {k: {"frames": int(v["frames"]), "seconds": round(v["seconds"], 4)}
                              for k, v in sorted(self.fallbacks.items())}}

    def describe(self) -> str:
        """One line, e.g. ``99.2 % of 1500 frames in chess_floor+path (depth 11 frames / 0.22 s)``."""
        what = self.expected_mode + "".join(f"+{o}" for o in self.expected_overlays)
        text = f"{100 * self.share:.1f} % of {self.frames} frames in {what or '?'}"
        if self.inferred:
            text += " (configured mode inferred: the most frequent mode shown; this recording predates configured_mode)"
        if self.fallbacks:
            text += "; instead: " + ", ".join(f"{k} {int(v['frames'])} frames / {v['seconds']:.2f} s"
                                               for k, v in sorted(self.fallbacks.items()))
        return text


def fallback_kinds(frame: ShownFrame, mode: str, overlays: Sequence[str]) -> list[str]:
    """Why ``frame`` is not the expected ``mode`` + ``overlays`` (empty: it is)."""
    if frame.mode == NO_DATA:
        return [NO_DATA]
    kinds = [] if frame.mode == mode else [f"mode:{frame.mode}"]
    shown = set(frame.overlays)
    kinds += [f"overlays:-{o}" for o in overlays if o not in shown]
    kinds += [f"overlays:+{o}" for o in frame.overlays if o not in set(overlays)]
    return kinds


def shown_share(frames: Iterable[ShownFrame], mode: str | None = None, overlays: Sequence[str] | None = None,
                end_t: float | None = None) -> ShownShare:
    """The share of ``frames`` shown in ``mode`` + ``overlays`` (see the module docstring)."""
    frames = sorted(frames, key=lambda f: f.t)
    out = ShownShare()
    if not frames:
        out.expected_mode, out.expected_overlays = mode or "", tuple(overlays or ())
        return out
    if mode is None:
        configured = Counter((f.configured_mode, tuple(f.configured_overlays)) for f in frames if f.configured_mode)
        if configured:
            (mode, configured_overlays), _ = configured.most_common(1)[0]
        else:
            shown = Counter((f.mode, tuple(f.overlays)) for f in frames if f.mode != NO_DATA)
            (mode, configured_overlays), _ = shown.most_common(1)[0] if shown else ((NO_DATA, ()), 0)
            out.inferred = True
        overlays = configured_overlays if overlays is None else overlays
    overlays = tuple(overlays or ())
    out.expected_mode, out.expected_overlays = mode, overlays
    t = np.array([f.t for f in frames], float)
    gaps = np.diff(t)
    period = float(np.median(gaps)) if len(gaps) else 0.0
    last = max(0.0, end_t - t[-1]) if end_t is not None else period
    durations = np.append(gaps, last)
    for f, d in zip(frames, durations):
        kinds = fallback_kinds(f, mode, overlays)
        out.frames += 1
        out.seconds += float(d)
        if not kinds:
            out.own_frames += 1
            out.own_seconds += float(d)
        for k in kinds:
            entry = out.fallbacks.setdefault(k, {"frames": 0, "seconds": 0.0})
            entry["frames"] += 1
            entry["seconds"] += float(d)
    return out
