"""Local planning: obstacles from depth and the Dynamic Window Approach (Fox et al. 1997), no rclpy.

``obstacle_points`` turns a depth frame into obstacle positions on the floor (world x, y)
from the points between ``min_height`` and ``max_height`` above the floor. ``DWAPlanner``
samples (v, w) commands reachable within one control period, rolls each out as a unicycle arc
(closed form, all at once), discards those that come closer than the robot radius to an
obstacle, and scores the rest by progress along the global path, clearance and speed — the
optimal collision-free velocity of the paper's local planner.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from raspv_common.intrinsics import CameraIntrinsics


def obstacle_points(depth: np.ndarray, intrinsics: CameraIntrinsics, world_from_camera: np.ndarray,
                    min_height: float = 0.10, max_height: float = 1.80, max_range: float = 4.0,
                    stride: int = 4) -> np.ndarray:
    """Depth (H, W) metres + pose W ← C → obstacle points (N, 2) on the floor plane of W [m].
    Every ``stride``-th pixel is used; invalid depth is ignored; floor height is world z = 0."""
    d = np.asarray(depth, dtype=np.float32)[::stride, ::stride]
    v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
    ok = np.isfinite(d) & (d > 0) & (d < max_range)
    rays = intrinsics.rays(u[ok], v[ok]) * d[ok][:, None]
    pw = rays @ world_from_camera[:3, :3].T + world_from_camera[:3, 3]
    keep = (pw[:, 2] > min_height) & (pw[:, 2] < max_height)
    return pw[keep, :2]


@dataclass
class DWAConfig:
    max_speed: float = 0.8          # [m/s] forward only (a person walking)
    max_turn: float = 1.5           # [rad/s]
    max_accel: float = 1.5          # [m/s²]
    max_turn_accel: float = 4.0     # [rad/s²]
    control_period: float = 0.1     # [s]
    horizon: float = 2.0            # [s] roll-out length
    samples_v: int = 9
    samples_w: int = 21
    robot_radius: float = 0.30      # [m]
    lookahead: float = 1.5          # [m] target distance along the path
    weight_progress: float = 1.0
    weight_clearance: float = 0.4
    weight_speed: float = 0.2


@dataclass
class DWAResult:
    linear: float                   # [m/s]
    angular: float                  # [rad/s]
    trajectory: np.ndarray          # (T, 2) chosen roll-out in W
    feasible: bool                  # False: every sampled command collides → stop


class DWAPlanner:
    def __init__(self, config: DWAConfig | None = None) -> None:
        self.config = config or DWAConfig()
        c = self.config
        self._t = np.arange(1, int(round(c.horizon / c.control_period)) + 1) * c.control_period

    def rollout(self, pose: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Unicycle arcs from ``pose`` (x, y, yaw) for commands (K,) → points (K, T, 2)."""
        x, y, th = pose
        t = self._t[None, :]
        v, w = v[:, None], w[:, None]
        small = np.abs(w) < 1e-6
        ws = np.where(small, 1.0, w)
        dx = np.where(small, v * t * np.cos(th), v / ws * (np.sin(th + w * t) - math.sin(th)))
        dy = np.where(small, v * t * np.sin(th), -v / ws * (np.cos(th + w * t) - math.cos(th)))
        return np.stack([x + dx, y + dy], axis=-1)

    def command(self, pose, velocity, path: np.ndarray, obstacles: np.ndarray) -> DWAResult:
        """Best (v, w) from ``pose`` (x, y, yaw) and current ``velocity`` (v, w) towards the
        global ``path`` (N, 2) avoiding ``obstacles`` (M, 2), all in W."""
        c = self.config
        pose = np.asarray(pose, dtype=float)
        v0, w0 = velocity
        vs = np.linspace(max(0.0, v0 - c.max_accel * c.control_period), min(c.max_speed, v0 + c.max_accel * c.control_period), c.samples_v)
        ws = np.linspace(max(-c.max_turn, w0 - c.max_turn_accel * c.control_period),
                         min(c.max_turn, w0 + c.max_turn_accel * c.control_period), c.samples_w)
        V, W = (a.ravel() for a in np.meshgrid(vs, ws))
        traj = self.rollout(pose, V, W)
        K, T, _ = traj.shape
        if len(obstacles):
            dist, _ = cKDTree(obstacles).query(traj.reshape(-1, 2), k=1)
            clearance = dist.reshape(K, T).min(axis=1)
        else:
            clearance = np.full(K, np.inf)
        ok = clearance > c.robot_radius
        target = lookahead_point(path, pose[:2], c.lookahead)
        end = traj[:, -1]
        progress = -np.linalg.norm(end - target, axis=1)
        score = (c.weight_progress * progress + c.weight_clearance * np.minimum(clearance, 2.0)
                 + c.weight_speed * V)
        score[~ok] = -np.inf
        best = int(np.argmax(score))
        if not np.isfinite(score[best]):
            return DWAResult(0.0, 0.0, traj[0, :1], False)
        return DWAResult(float(V[best]), float(W[best]), traj[best], True)


def lookahead_point(path: np.ndarray, position: np.ndarray, distance: float) -> np.ndarray:
    """The point ``distance`` metres along ``path`` beyond its point closest to ``position``."""
    path = np.asarray(path, dtype=float)
    if len(path) == 1:
        return path[0]
    seg = np.diff(path, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    rel = position - path[:-1]
    s = np.clip((rel * seg).sum(axis=1) / np.maximum(seg_len ** 2, 1e-12), 0.0, 1.0)
    closest = path[:-1] + s[:, None] * seg
    i = int(np.argmin(np.linalg.norm(closest - position, axis=1)))
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    target_s = cum[i] + s[i] * seg_len[i] + distance
    if target_s >= cum[-1]:
        return path[-1]
    j = int(np.searchsorted(cum, target_s) - 1)
    return path[j] + (target_s - cum[j]) / max(seg_len[j], 1e-12) * seg[j]
