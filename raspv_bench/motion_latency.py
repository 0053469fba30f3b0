"""Motion-to-phosphene latency as a headset wearer feels it (no rclpy).

A client with control of the bridge holds the head still, steps its yaw by ``amplitude``
degrees, holds, steps back, … (each hold a little longer than the last, so steps land at every
phase of the camera and display clocks), and keeps every phosphene frame it receives (reduced
4× by area averaging) with its receipt time. For each step, timed from the moment the first
head message with the new yaw was sent:

- **onset**: the first frame that clearly changes — its mean absolute difference d from the
  last frame P before the step reaches :data:`ONSET_FRACTION` of the step's whole change
  d(P, F) (F: the settled frames before the next step) and :data:`NOISE_FACTOR` × the largest
  frame-to-frame difference while holding still;
- **50 % of the change**: the first frame f with d(f, P) ≥ ½·d(P, F) — half of the step's
  change has reached the display (the issue's probe);
- **half-way to the new view**: the first frame with d(f, F) ≤ ½·d(P, F). It differs from the
  above when part of the display goes dark: display-time reprojection shows what the last
  camera frame did not see as dark, which changes the image at once but is not the new view
  (between two views that share most of their light, a dark wedge is farther from either).

Steps whose views hardly differ (less than :data:`MIN_CHANGE` grey levels or the noise) are
not counted. Times are in the server's clock (offset NTP-style from ping/pong, as the
reference client does), so they compare with the stamps the graph carries.

With ``--gaze`` the steps are the eye's (gaze yaw, 120 Hz samples, the head held straight ahead):
the spv node's ``gaze_mode`` then moves the field on the display through the same display-on-input
path as a head turn.

Run as a process: ``python -m raspv_bench.motion_latency URL OUT.npz [--steps 20 ...]`` (what
``raspv bench e2e`` does); :func:`analyse_steps` reads the result.
"""
from __future__ import annotations

import argparse
import asyncio
import json
import math
import random
import sys
from dataclasses import dataclass, field

import numpy as np

from raspv_hmd import protocol as P

REDUCE = 4                  # frames are kept area-averaged by this factor
ONSET_FRACTION = 0.1        # a clear change: this fraction of the step's whole change …
NOISE_FACTOR = 3.0          # … and this many times the largest still-frame difference
MIN_CHANGE = 1.0            # grey levels (mean absolute difference) for a step to count
STILL_WINDOW_S = 0.3        # frames before a step that show it settled (noise, P)
SETTLED_WINDOW_S = 0.25     # frames before the next step averaged into F
HALF = 0.5


@dataclass
class StepSchedule:
    """Head yaw steps: ``warmup_s`` at 0°, then ``steps`` alternating steps to ``amplitude_deg``
    and back, the i-th hold ``hold_s`` + a random 0–``jitter_s`` (seeded)."""

    steps: int = 20
    amplitude_deg: float = 40.0
    hold_s: float = 1.5
    jitter_s: float = 0.1
    warmup_s: float = 2.0
    seed: int = 1
    times: list[float] = field(init=False)       # step k at times[k] s after the start

    def __post_init__(self) -> None:
        rng = random.Random(self.seed)
        t, self.times = self.warmup_s, []
        for _ in range(self.steps):
            self.times.append(t)
            t += self.hold_s + rng.uniform(0.0, self.jitter_s)
        self.end_s = t

    def yaw_deg(self, t: float) -> float:
        """Commanded yaw at ``t`` s after the start: 0, amplitude, 0, …"""
        k = sum(1 for s in self.times if s <= t)
        return self.amplitude_deg if k % 2 else 0.0

    def at(self, t: float) -> tuple[float, float, float]:
        """(roll, pitch, yaw) [rad], the reference client's head-script interface."""
        return 0.0, 0.0, math.radians(self.yaw_deg(t))


@dataclass
class StepResult:
    """One step: ``sent`` [s, server clock], the step's ``change`` d(P, F) [grey levels], the
    ``onset_s``, ``half_s`` (50 % of the change) and ``halfway_s`` (half-way to the new view)
    latencies (None when the frames never showed it) and the image stamps of those frames [s]."""

    sent: float
    change: float
    onset_s: float | None = None
    half_s: float | None = None
    halfway_s: float | None = None
    onset_stamp: float | None = None
    half_stamp: float | None = None
    halfway_stamp: float | None = None


def mean_abs_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a.astype(np.float32) - b.astype(np.float32))))


def analyse_steps(receipt: np.ndarray, stamps: np.ndarray, frames: np.ndarray,
                  step_times: np.ndarray) -> tuple[list[StepResult], int]:
    """Per-step onset and 50 % latencies from received ``frames`` (K, h, w) with ``receipt``
    times and image ``stamps`` (K,) [s, server clock] and the steps' send times. Returns the
    counted steps and how many were skipped (views too alike, or no frames around them)."""
    results, skipped = [], 0
    ends = list(step_times[1:]) + [receipt[-1] + 1e-6 if len(receipt) else 0.0]
    for ts, end in zip(step_times, ends):
        before = np.flatnonzero((receipt >= ts - STILL_WINDOW_S) & (receipt < ts))
        after = np.flatnonzero((receipt >= ts) & (receipt < end))
        settled = np.flatnonzero((receipt >= end - SETTLED_WINDOW_S) & (receipt < end))
        if len(before) < 2 or len(after) < 2 or len(settled) == 0:
            skipped += 1
            continue
        pre = frames[before[-1]].astype(np.float32)
        final = frames[settled].astype(np.float32).mean(axis=0)
        noise = max(mean_abs_diff(frames[i], frames[j]) for i, j in zip(before[:-1], before[1:]))
        change = mean_abs_diff(pre, final)
        if change < max(MIN_CHANGE, NOISE_FACTOR * noise):
            skipped += 1
            continue
        result = StepResult(float(ts), change)
        threshold = max(ONSET_FRACTION * change, NOISE_FACTOR * noise)
        for i in after:
            latency, stamp = float(receipt[i] - ts), float(stamps[i])
            moved = mean_abs_diff(frames[i], pre)
            if result.onset_s is None and moved >= threshold:
                result.onset_s, result.onset_stamp = latency, stamp
            if result.half_s is None and moved >= HALF * change:
                result.half_s, result.half_stamp = latency, stamp
            if result.halfway_s is None and mean_abs_diff(frames[i], final) <= HALF * change:
                result.halfway_s, result.halfway_stamp = latency, stamp
            if result.onset_s is not None and result.half_s is not None and result.halfway_s is not None:
                break
        results.append(result)
    return results, skipped


class GazeSteps:
    """The eyes' version of a :class:`StepSchedule`: gaze yaw steps (head held straight ahead)."""

    def __init__(self, schedule: StepSchedule) -> None:
        self.schedule = schedule

    def at(self, t: float) -> np.ndarray:
        from raspv_spv.gaze import direction_from_angles
        return direction_from_angles(self.schedule.yaw_deg(t), 0.0)


def gaze_step_send_times(gazes_sent: list[tuple[float, tuple[float, float, float] | None]],
                         min_jump_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Send times and yaws [deg] of the gaze messages that start a step (:func:`step_send_times` for the eyes)."""
    times, yaws, last = [], [], None
    for t, d in gazes_sent:
        if d is None:
            continue
        yaw = math.degrees(math.atan2(d[1], d[0]))
        if last is not None and abs(yaw - last) > min_jump_deg:
            times.append(t)
            yaws.append(yaw)
        last = yaw
    return np.array(times), np.array(yaws)


def step_send_times(heads_sent: list[tuple[float, tuple[float, float, float, float]]],
                    min_jump_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Send times [s, client clock] and yaws [deg] of the head messages that start a step (the
    yaw jumps by more than ``min_jump_deg`` from the message before)."""
    times, yaws, last = [], [], None
    for t, (x, y, z, w) in heads_sent:
        yaw = math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
        if last is not None and abs(yaw - last) > min_jump_deg:
            times.append(t)
            yaws.append(yaw)
        last = yaw
    return np.array(times), np.array(yaws)


def reduce_frame(image: np.ndarray) -> np.ndarray:
    """A received frame → grey (the green channel of rgb8), area-averaged by :data:`REDUCE`."""
    import cv2
    grey = image[..., 1] if image.ndim == 3 else image
    h, w = grey.shape
    return cv2.resize(grey, (max(1, w // REDUCE), max(1, h // REDUCE)), interpolation=cv2.INTER_AREA)


async def record_steps(url: str, schedule: StepSchedule, head_rate_hz: float = 60.0, gaze: bool = False,
                       gaze_rate_hz: float = 120.0) -> dict:
    """Connect as the controlling client, run ``schedule`` (with ``gaze``: as gaze steps at
    ``gaze_rate_hz``, the head held straight ahead), and return what was received:
    ``receipt``/``stamps`` [s, server clock], reduced ``frames``, ``step_times`` [s, server
    clock], ``step_yaws`` [deg] and a ``report`` dict (fps, frames, clock offset, closed)."""
    from raspv_hmd.reference_client import ClientOptions, parse_endpoint, run_client

    received: list[tuple[float, float, np.ndarray]] = []

    def keep(now: float, header: P.FrameHeader, image: np.ndarray) -> None:
        received.append((now, header.stamp, reduce_frame(image)))

    still = StepSchedule(0, 0.0, warmup_s=0.0)
    options = ClientOptions(role="control", format="auto", window=2, duration_s=schedule.end_s + 0.3,
                            head=still if gaze else schedule, head_rate_hz=head_rate_hz, ping_hz=5.0,
                            name="raspv bench e2e", on_frame=keep, gaze=GazeSteps(schedule) if gaze else None,
                            gaze_rate_hz=gaze_rate_hz)
    report = await run_client(parse_endpoint(url), options)
    offset = report.clock_offset_s or 0.0
    times, yaws = (gaze_step_send_times(report.gazes_sent, schedule.amplitude_deg / 2) if gaze
                   else step_send_times(report.heads_sent, schedule.amplitude_deg / 2))
    frames = np.stack([r[2] for r in received]) if received else np.zeros((0, 1, 1), np.uint8)
    return {"receipt": np.array([r[0] for r in received]) + offset, "stamps": np.array([r[1] for r in received]),
            "frames": frames, "step_times": times + offset, "step_yaws": yaws,
            "report": {"frames": report.frames, "fps": report.fps, "elapsed_s": report.elapsed_s,
                       "clock_offset_s": offset, "closed": report.closed, "role": report.role,
                       "formats": report.formats_seen}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="head-yaw steps through the bridge; frames and times to an .npz")
    parser.add_argument("url")
    parser.add_argument("out")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--amplitude", type=float, default=40.0)
    parser.add_argument("--hold", type=float, default=1.5)
    parser.add_argument("--warmup", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--gaze", action="store_true", help="step the gaze (120 Hz samples), not the head")
    parser.add_argument("--priority", choices=("headset", "normal"), default="normal",
                        help="headset: real-time where allowed, as the headset's own processor (bench e2e)")
    args = parser.parse_args(argv)
    if args.priority == "headset":
        from raspv_common.thread_priority import raise_thread_priority
        raise_thread_priority(realtime=True)
    from raspv_hmd.reference_client import ClientError

    schedule = StepSchedule(args.steps, args.amplitude, args.hold, warmup_s=args.warmup, seed=args.seed)
    try:
        data = asyncio.run(record_steps(args.url, schedule, gaze=args.gaze))
    except ClientError as exc:
        print(f"motion_latency: {exc}", file=sys.stderr)
        return 1
    report = data.pop("report")
    np.savez_compressed(args.out, report=json.dumps(report), **data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
