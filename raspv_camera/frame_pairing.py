"""Pairing colour and depth frames that come on two streams (no ROS).

Drivers whose SDK delivers colour and depth separately (OpenNI2 streams, RealSense sensors)
pair them here by timestamp: a frame pairs with the other stream's frame closest in time if
that is within ``tolerance`` seconds (half a frame period: the two sensors of a device are
triggered together, or at least once per frame); frames older than a pair have lost their
partner and are dropped. Each stream keeps its last ``keep`` unpaired frames, so one stream
running a frame or two ahead of the other (as recordings are read) loses nothing.
"""
from __future__ import annotations

from typing import Any, Generic, TypeVar

T = TypeVar("T")
KINDS = ("color", "depth")


class FramePairer(Generic[T]):
    def __init__(self, tolerance: float, keep: int = 4) -> None:
        if not tolerance > 0 or keep < 1:
            raise ValueError("tolerance must be positive and keep at least 1")
        self.tolerance = tolerance      # s
        self.keep = keep
        self.pending: dict[str, list[tuple[float, T]]] = {k: [] for k in KINDS}
        self.dropped = 0

    def reset(self) -> None:
        self.pending = {k: [] for k in KINDS}

    def add(self, kind: str, t: float, item: T) -> tuple[tuple[float, T], tuple[float, T]] | None:
        """Add a ``color`` or ``depth`` frame taken at ``t`` [s]; returns ((t, colour), (t, depth))
        when it completes a pair, else None."""
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        other_kind = "depth" if kind == "color" else "color"
        mine, other = self.pending[kind], self.pending[other_kind]
        partner = min(other, key=lambda e: abs(e[0] - t), default=None)
        if partner is None or abs(partner[0] - t) > self.tolerance:
            mine.append((t, item))
            if len(mine) > self.keep:
                self.dropped += len(mine) - self.keep
                del mine[:-self.keep]
            return None
        before = len(mine) + len(other)
        other[:] = [e for e in other if e[0] > partner[0]]
        mine[:] = [e for e in mine if e[0] > t]
        self.dropped += before - len(mine) - len(other) - 1
        this = (t, item)
        return (this, partner) if kind == "color" else (partner, this)


def pair_tolerance(fps: Any) -> float:
    """Half a frame period [s] for a frame rate [Hz] (30 Hz when unknown)."""
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        fps = 0.0
    return 0.5 / (fps if fps > 0 else 30.0)
