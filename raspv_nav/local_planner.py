"""Local planning: the Dynamic Window Approach (Fox, Burgard & Thrun 1997), no rclpy.

From the subject's pose (x, y, yaw in W) and *measured* velocity (v, w), DWA

1. samples the **dynamic window**: the (v, w) reachable within one ``control_period`` at
   ``max_accel`` / ``max_turn_accel``, within the speed limits (forward only: a person walking);
2. rolls each command out as a circular arc (closed form, all at once) for ``horizon`` s and
   looks up the obstacle clearance along it (the costmap's distance field, or points);
3. keeps the **admissible** commands, those after which the subject can still brake before the
   first collision on the arc, holding the command one ``control_period`` first:
   v²/(2·``max_accel``) + v·period ≤ dist(v, w) and w²/(2·``max_turn_accel``) + |w|·period ≤
   angle(v, w), where dist is the free arc length before the collision and angle the turn made
   by then (Fox et al.'s v ≤ √(2·dist·v̇_b) with the reaction time added; commands free over the
   whole horizon are admissible). A collision is a roll-out point within ``robot_radius`` of an
   obstacle, or, for a subject already that close, nearer than it is now;
4. scores them G = α·heading + β·dist + γ·velocity (each in [0, 1]): heading = 1 − |θ|/π with
   θ the angle from the subject's heading to the target (the point ``lookahead`` m along the
   global path, which A* keeps in the middle of doors and corridors); dist = the free arc length
   before a collision, over ``clearance_cap`` (1 for arcs free over the horizon); velocity =
   v / ``max_speed``; the heading is taken at the pose reached after ``heading_time``
   s (Fox et al. take it after one interval; a second looks past the dynamic window's tiny arcs
   without overshooting the target ``lookahead`` m ahead);
5. returns the best command, or (0, 0) and ``feasible = False`` when none is admissible.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from raspv_nav.costmap import CostmapState
from raspv_common.occupancy import OccupancyGrid

ClearanceFn = Callable[[np.ndarray], np.ndarray]      # (K, 2) W points → (K,) distance to obstacles [m]


@dataclass
class DWAConfig:
    max_speed: float = 0.8          # [m/s] forward only (a person walking)
    max_turn: float = 1.5           # [rad/s]
    max_accel: float = 1.5          # [m/s²] also the braking deceleration
    max_turn_accel: float = 4.0     # [rad/s²]
    control_period: float = 0.1     # [s] the dynamic window spans one period
    horizon: float = 2.0            # [s] roll-out length
    rollout_step: float = 0.1       # [s] between roll-out samples
    samples_v: int = 9
    samples_w: int = 21
    robot_radius: float = 0.30      # [m] a roll-out point nearer an obstacle cell's centre is a
                                    # collision (the subject's body, 0.25 m, + a 5 cm cell's half diagonal)
    lookahead: float = 0.8          # [m] target distance along the global path
    heading_time: float = 0.5       # [s] heading is scored at the pose reached after this
    clearance_cap: float = 2.0      # [m] free arc lengths beyond this score the same
    weight_heading: float = 0.7     # α
    weight_clearance: float = 0.2   # β
    weight_velocity: float = 0.1    # γ


@dataclass
class DWAResult:
    linear: float                   # [m/s]
    angular: float                  # [rad/s]
    trajectory: np.ndarray          # (T, 2) chosen roll-out in W
    feasible: bool                  # False: no admissible command → stop
    target: np.ndarray | None = None  # (2,) the point on the path aimed at, W


def grid_clearance(state: CostmapState, grid: OccupancyGrid) -> ClearanceFn:
    """Clearance lookup in the costmap's distance field (nearest cell; 0 outside the map)."""
    field = state.clearance

    def lookup(points: np.ndarray) -> np.ndarray:
        rc = grid.world_to_cell(points)
        inside = grid.inside(rc)
        out = np.zeros(len(points))
        out[inside] = field[rc[inside, 0], rc[inside, 1]]
        return out
    return lookup


def points_clearance(obstacles: np.ndarray) -> ClearanceFn:
    """Clearance from a set of obstacle points (M, 2) in W (KD-tree)."""
    obstacles = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    tree = cKDTree(obstacles) if len(obstacles) else None

    def lookup(points: np.ndarray) -> np.ndarray:
        if tree is None:
            return np.full(len(points), np.inf)
        return tree.query(points, k=1)[0]
    return lookup


class DWAPlanner:
    def __init__(self, config: DWAConfig | None = None) -> None:
        self.config = config or DWAConfig()
        c = self.config
        self._t = np.arange(1, int(round(c.horizon / c.rollout_step)) + 1) * c.rollout_step

    def rollout(self, pose: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Arcs from ``pose`` (x, y, yaw) for commands (K,) → points (K, T, 2)."""
        x, y, th = pose
        t = self._t[None, :]
        v, w = v[:, None], w[:, None]
        small = np.abs(w) < 1e-6
        ws = np.where(small, 1.0, w)
        dx = np.where(small, v * t * math.cos(th), v / ws * (np.sin(th + w * t) - math.sin(th)))
        dy = np.where(small, v * t * math.sin(th), -v / ws * (np.cos(th + w * t) - math.cos(th)))
        return np.stack([x + dx, y + dy], axis=-1)

    def window(self, velocity) -> tuple[np.ndarray, np.ndarray]:
        """The sampled dynamic window around the measured ``velocity`` (v, w): (K,) v and w."""
        c = self.config
        v0, w0 = (float(velocity[0]), float(velocity[1]))
        v0 = min(max(v0, 0.0), c.max_speed)
        w0 = min(max(w0, -c.max_turn), c.max_turn)
        dv, dw = c.max_accel * c.control_period, c.max_turn_accel * c.control_period
        vs = np.linspace(max(0.0, v0 - dv), min(c.max_speed, v0 + dv), c.samples_v)
        ws = np.linspace(max(-c.max_turn, w0 - dw), min(c.max_turn, w0 + dw), c.samples_w)
        V, W = (a.ravel() for a in np.meshgrid(vs, ws))
        return V, W

    def command(self, pose, velocity, path: np.ndarray, clearance: ClearanceFn | np.ndarray) -> DWAResult:
        """Best (v, w) from ``pose`` (x, y, yaw) and measured ``velocity`` (v, w) towards the
        global ``path`` (N, 2) in W; ``clearance`` is a lookup (see :func:`grid_clearance`) or
        obstacle points (M, 2)."""
        c = self.config
        if not callable(clearance):
            clearance = points_clearance(clearance)
        pose = np.asarray(pose, dtype=float)
        V, W = self.window(velocity)
        traj = self.rollout(pose, V, W)
        K, T, _ = traj.shape
        clear = clearance(traj.reshape(-1, 2)).reshape(K, T)
        # inside the radius already (a wall brushed, a person stepping close): only coming
        # closer than now counts as a collision, so the subject can always move away
        radius = min(c.robot_radius, 0.9 * float(clearance(pose[None, :2])[0]))
        hit = clear <= radius
        collides = hit.any(axis=1)
        t_free = self._t[np.argmax(hit, axis=1)] - c.rollout_step      # last sample before the collision
        dist = np.where(collides, V * t_free, np.inf)         # free arc length [m]
        angle = np.where(collides, np.abs(W) * t_free, np.inf)
        # the command is held one control period, then the subject brakes at max_accel
        reaction = c.control_period
        admissible = ((V * V / (2.0 * c.max_accel) + V * reaction <= dist + 1e-9)
                      & (W * W / (2.0 * c.max_turn_accel) + np.abs(W) * reaction <= angle + 1e-9))
        target = lookahead_point(path, pose[:2], c.lookahead)
        k = min(max(int(round(c.heading_time / c.rollout_step)), 1), T) - 1
        yaw_k = pose[2] + W * self._t[k]
        to_target = np.arctan2(target[1] - traj[:, k, 1], target[0] - traj[:, k, 0])
        theta = np.abs(np.mod(to_target - yaw_k + math.pi, 2 * math.pi) - math.pi)
        heading = 1.0 - theta / math.pi
        free = np.minimum(dist, c.clearance_cap) / c.clearance_cap
        velocity_score = V / c.max_speed
        score = c.weight_heading * heading + c.weight_clearance * free + c.weight_velocity * velocity_score
        score[~admissible] = -np.inf
        best = int(np.argmax(score))
        if not np.isfinite(score[best]):
            return DWAResult(0.0, 0.0, traj[0, :1], False, target)
        return DWAResult(float(V[best]), float(W[best]), traj[best], True, target)


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
