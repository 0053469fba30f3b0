"""Scripted subjects: virtual patients that see only what a subject sees (no rclpy).

A policy gets the displayed brightness of every phosphene (``/spv/frame``, 0..1) and where each
phosphene is in the phosphene image (``/spv/map``) — not the world, not the camera — plus
what a person knows about their own body: the head pitch they hold and their eye height. It
returns a walking command (m/s, rad/s) and the head pitch. Policies:

``follow_path``
    steers toward the bright trail of the path overlay: the phosphenes near the brightest it
    saw lately (≥ ``bright_ratio`` × that) are taken as the trail, projected onto the floor
    through the head pose the subject holds (pure pursuit on the point about ``lookahead`` m
    ahead); without a trail in view it turns in place toward where it last saw one.
``wander_avoid``
    walks forward and turns away from bright phosphenes in the lower part of the view (near
    things: obstacles in Wall-Obstacles, near surfaces in depth mode).
``navigate`` (:mod:`raspv_experiments.navigate_policy`, the default virtual patient)
    follows a trail when one stands out, else walks toward the goal it was told about by path
    integration, steering around what stands out from the floor of each image row.

Every policy has a seeded **ability** (:class:`PolicyConfig`; a population of them in
:mod:`raspv_experiments.subject_ability`): motor noise (``noise`` rad/s), a perceptual threshold
(``min_brightness``: dimmer is not seen) and perceptual noise (``perception_noise``, added to
every brightness read), and a reaction time (``reaction_time_s``: a command acts that much
sim time after the frame it was decided on; until then the subject stands). All notice when
they walk into something they did not see — the view stops changing while they walk (no optic
flow) — and step back, turning a little. Frames:
phosphene image pixels (x right, y down, principal point at the image centre, focal f_P);
head frame x forward, y left, z up; pitch > 0 looks down.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PhospheneLayout:
    """Where the phosphenes are in the phosphene image (from ``/spv/map``)."""

    x: np.ndarray            # (N,) sampling centres [px]
    y: np.ndarray
    width: int               # image size [px]
    height: int
    focal_px: float          # f_P [px]
    map_id: int = 0

    def rays(self) -> np.ndarray:
        """(N, 3) unit-less view directions in the head frame (x forward, y left, z up) for a level head."""
        u = (self.x - self.width / 2.0) / self.focal_px
        v = (self.y - self.height / 2.0) / self.focal_px
        return np.column_stack([np.ones_like(u), -u, -v])


@dataclass(frozen=True)
class Command:
    linear: float            # m/s forward
    angular: float           # rad/s, positive turns left
    head_pitch: float        # rad, positive looks down


@dataclass
class PolicyConfig:
    max_linear: float = 0.6          # m/s
    max_angular: float = 1.0         # rad/s
    head_pitch_deg: float = 40.0     # held head pitch (looking down at the floor ahead)
    eye_height: float = 1.6          # m
    lookahead: float = 1.0           # m, follow_path's pursuit distance
    bright_ratio: float = 0.85       # follow_path: trail phosphenes are ≥ this × the frame's brightest
    min_brightness: float = 0.15     # perceptual threshold: nothing dimmer counts as seen
    noise: float = 0.05              # rad/s std. dev. of motor noise
    seed: int = 1
    reaction_time_s: float = 0.0     # s of sim time between a frame and the command decided on it
    perception_noise: float = 0.0    # std. dev. of the noise added to every brightness read (0..1 scale)
    contrast_threshold: float = 0.12  # navigate: brighter than its row's floor by this much stands out
    frame_period_s: float = 0.1      # assumed time between frames when they carry no time


def floor_points(layout: PhospheneLayout, config: PolicyConfig) -> tuple[np.ndarray, np.ndarray]:
    """The view rays (N, 3) of the phosphenes of ``layout`` with the head pitched down by
    ``config.head_pitch_deg`` (body frame: x forward, y left, z up) and the floor points (N, 2)
    [m, x forward, y left] they look at from ``config.eye_height`` (NaN at and above the horizon)."""
    pitch = math.radians(config.head_pitch_deg)
    r = layout.rays()
    c, s = math.cos(pitch), math.sin(pitch)
    rays = np.column_stack([c * r[:, 0] + s * r[:, 2], r[:, 1], -s * r[:, 0] + c * r[:, 2]])
    below = rays[:, 2] < -0.02
    scale = np.where(below, config.eye_height / np.maximum(-rays[:, 2], 1e-6), np.nan)
    return rays, rays[:, :2] * scale[:, None]


class Policy(ABC):
    name = ""

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None) -> None:
        self.layout = layout
        self.config = config or PolicyConfig()
        self.rng = np.random.default_rng(self.config.seed)
        self.rays, self.ground = floor_points(layout, self.config)    # pitched head; floor point each looks at
        self.ground_distance = np.hypot(self.ground[:, 0], self.ground[:, 1])
        self._history: deque[tuple[np.ndarray, float]] = deque(maxlen=self.STILL_FRAMES)
        self._back, self._back_side = 0, 1.0
        self._decided: deque[tuple[float, float, float]] = deque()      # (t, v, w) awaiting the reaction time
        self._acting = (0.0, 0.0)
        self.t: float | None = None                                      # sim time of the last frame [s]
        self.mode, self.overlays = "", ()                                # the representation shown (show())
        self.dt = self.config.frame_period_s

    STILL_FRAMES = 12          # frames walking with an (almost) unchanging view: blocked
    BACK_FRAMES = 15           # frames to step back and turn then
    STILL_CHANGE = 0.03        # mean brightness change over STILL_FRAMES below which the view is unchanged
    # (measured in the office at 10 Hz, 0.6 m/s: walking changes it by 0.1–0.28 over 12 frames)

    def act(self, brightness: np.ndarray, t: float | None = None) -> Command:
        """The command for one frame: its displayed brightness (0..1 per phosphene) and its sim
        time ``t`` [s] (None: frames ``frame_period_s`` apart)."""
        b = np.nan_to_num(np.asarray(brightness, dtype=float), nan=0.0)
        if b.shape != (len(self.layout.x),):
            raise ValueError(f"{len(b)} brightness values for {len(self.layout.x)} phosphenes")
        c = self.config
        t = (self.t + c.frame_period_s if self.t is not None else 0.0) if t is None else float(t)
        self.dt = c.frame_period_s if self.t is None else max(t - self.t, 0.0)
        self.t = t
        if c.perception_noise > 0:
            b = b + self.rng.normal(0.0, c.perception_noise, b.shape)
        b = np.where(b >= c.min_brightness, np.clip(b, 0.0, 1.0), 0.0)      # below the threshold: not seen
        v, w = self.unblock(b) or self.decide(b)
        self._history.append((b, v))
        v, w = self._react(t, float(np.clip(v, -c.max_linear, c.max_linear)), float(np.clip(w, -c.max_angular, c.max_angular)))
        self.executed(v, w)
        w += self.rng.normal(0.0, c.noise) if c.noise > 0 else 0.0
        return Command(v, float(np.clip(w, -c.max_angular, c.max_angular)), math.radians(c.head_pitch_deg))

    def _react(self, t: float, v: float, w: float) -> tuple[float, float]:
        """The command decided ``reaction_time_s`` ago (standing still before the first)."""
        rt = self.config.reaction_time_s
        if rt <= 0:
            return v, w
        self._decided.append((t, v, w))
        while self._decided and self._decided[0][0] <= t - rt + 1e-6:
            _, *self._acting = self._decided.popleft()
        return tuple(self._acting)

    def executed(self, v: float, w: float) -> None:
        """The command the body carries out now (m/s, rad/s, before motor noise): path integration."""

    def show(self, mode: str, overlays) -> None:
        """The representation the frames are in (named in each /spv/frame: a subject is told the condition)."""
        self.mode, self.overlays = str(mode), tuple(overlays)

    def touch(self) -> None:
        """The body bumped into something (a collision, felt): policies that use touch react."""

    def unblock(self, b: np.ndarray) -> tuple[float, float] | None:
        """Walking into something the subject did not see: the view stops changing while they
        walk (no optic flow), so they step back and turn a little. A command while that lasts."""
        if self._back > 0:
            self._back -= 1
            return -0.5 * self.config.max_linear, 0.6 * self.config.max_angular * self._back_side
        h = self._history
        if len(h) == h.maxlen and all(v > 0.1 for _, v in h) and float(np.abs(b - h[0][0]).mean()) < self.STILL_CHANGE:
            h.clear()
            self._back = self.BACK_FRAMES
            self._back_side = float(self.rng.choice([-1.0, 1.0]))
            return self.unblock(b)
        return None

    @abstractmethod
    def decide(self, brightness: np.ndarray) -> tuple[float, float]:
        """(linear m/s, angular rad/s) from the brightness of every phosphene."""


class FollowPath(Policy):
    name = "follow_path"

    PEAK_DECAY = 0.97                        # per frame: the remembered brightest fades over seconds

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None, **_) -> None:
        super().__init__(layout, config)
        self.last_side = 1.0                 # +1: the trail was last seen to the left
        self.peak = 0.0                      # the brightest the subject saw lately

    def trail(self, b: np.ndarray) -> np.ndarray:
        """Indices of the phosphenes taken as the trail on the floor: those near the brightest
        seen lately — so when the trail leaves the view, the dimmed rest is not taken for it."""
        top = float(b.max()) if len(b) else 0.0
        self.peak = max(top, self.peak * self.PEAK_DECAY)
        if top < self.config.min_brightness:
            return np.empty(0, int)
        return np.flatnonzero((b >= self.config.bright_ratio * self.peak) & np.isfinite(self.ground_distance))

    def decide(self, b: np.ndarray) -> tuple[float, float]:
        c = self.config
        idx = self.trail(b)
        if len(idx) == 0:
            return 0.0, 0.7 * c.max_angular * self.last_side      # look for it where it was last
        d = self.ground_distance[idx]
        near = np.abs(d - c.lookahead) <= 0.5
        pick = idx[near] if near.any() else idx[[int(np.argmin(np.abs(d - c.lookahead)))]]
        weights = b[pick]
        gx, gy = (self.ground[pick] * weights[:, None]).sum(axis=0) / weights.sum()
        bearing = math.atan2(gy, gx)
        self.last_side = 1.0 if bearing >= 0 else -1.0
        if abs(bearing) > math.radians(50):
            return 0.0, c.max_angular * self.last_side
        dist = max(math.hypot(gx, gy), 0.3)
        v = c.max_linear * max(0.2, math.cos(bearing) ** 2)
        return v, 2.0 * v * math.sin(bearing) / dist                # pure pursuit: ω = 2 v sin(α) / L


class WanderAvoid(Policy):
    name = "wander_avoid"

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None, **_) -> None:
        super().__init__(layout, config)
        lower = layout.y >= layout.height * 0.45
        u = (layout.x - layout.width / 2.0) / layout.width
        self.centre = lower & (np.abs(u) < 0.17)
        self.left = lower & (u <= -0.17)
        self.right = lower & (u >= 0.17)
        self.turning = 0.0

    def decide(self, b: np.ndarray) -> tuple[float, float]:
        c = self.config
        seen = np.where(b >= c.min_brightness, b, 0.0)
        mean = lambda m: float(seen[m].mean()) if m.any() else 0.0          # noqa: E731
        centre, left, right = mean(self.centre), mean(self.left), mean(self.right)
        if centre > 0.35 or (self.turning and centre > 0.2):
            if not self.turning:
                self.turning = 1.0 if left <= right else -1.0      # away from the brighter side
            return 0.05, c.max_angular * self.turning
        self.turning = 0.0
        return c.max_linear * (1.0 - min(centre, 0.5)), 1.5 * (right - left)


def policies() -> dict[str, type[Policy]]:
    from raspv_experiments.learned_policy import Learned
    from raspv_experiments.navigate_policy import Navigate

    return {"navigate": Navigate, "follow_path": FollowPath, "wander_avoid": WanderAvoid, "learned": Learned}


def make_policy(name: str, layout: PhospheneLayout, config: PolicyConfig | None = None, **kw) -> Policy:
    known = policies()
    if name not in known:
        raise ValueError(f"unknown scripted-subject policy {name!r}; known: {', '.join(known)}")
    return known[name](layout, config, **kw)
