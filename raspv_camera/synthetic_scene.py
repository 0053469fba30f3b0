"""An analytic RGB-D scene rendered by ray casting in numpy (no simulator, no rclpy).

A closed room (floor, ceiling, four walls) with box obstacles; a camera at eye height walks a
closed loop, looking slightly down. Depth, colour and the camera pose are exact, which makes it
a ground truth for tests and a source that runs anywhere in a few milliseconds per frame.

Frames: world W (x, y on the floor, z up, metres); camera optical frame C (x right, y down,
z forward). ``pose_at(t)`` returns the 4×4 matrix W ← C.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

# Optical frame axes expressed in the base frame (x forward, y left, z up).
R_BASE_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def camera_rotation(yaw_rad: float, pitch_down_rad: float) -> np.ndarray:
    """Rotation W ← C of a camera with heading ``yaw`` (about world z) tilted down by ``pitch``."""
    cz, sz = math.cos(yaw_rad), math.sin(yaw_rad)
    cp, sp = math.cos(pitch_down_rad), math.sin(pitch_down_rad)
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return rz @ ry @ R_BASE_OPTICAL


@dataclass(frozen=True)
class Box:
    """Axis-aligned box obstacle: ``lo``/``hi`` corners in W [m], RGB colour 0..1."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    color: tuple[float, float, float]


@dataclass
class SyntheticRoom:
    """Room of ``size`` (x, y) metres centred on the origin, ``height`` m high."""

    intrinsics: CameraIntrinsics
    size: tuple[float, float] = (8.0, 6.0)
    height: float = 2.6
    eye_height: float = 1.6
    pitch_down_deg: float = 15.0
    walk_radius: float = 1.6            # the camera walks a circle of this radius [m]
    walk_speed: float = 0.4             # [m/s]
    texture_cell: float = 0.0           # side of random grey blocks painted on every surface [m] (0: plain);
                                        # what feature-based tracking (ORB) needs to find corners
    boxes: list[Box] = field(default_factory=lambda: [
        Box((2.3, -0.6, 0.0), (3.1, 0.6, 0.75), (0.80, 0.25, 0.20)),    # low cabinet
        Box((-0.4, 2.0, 0.0), (0.4, 2.6, 1.10), (0.25, 0.45, 0.80)),    # tall box
        Box((-3.0, -2.2, 0.0), (-2.2, -1.4, 0.45), (0.30, 0.70, 0.30)),  # low box
    ])

    def __post_init__(self) -> None:
        intr = self.intrinsics
        u, v = np.meshgrid(np.arange(intr.width), np.arange(intr.height))
        self._rays_c = intr.rays(u, v).astype(np.float64)  # (N, 3), z = 1

    def pose_at(self, t: float) -> np.ndarray:
        """Camera pose W ← C at time ``t`` seconds (walking counter-clockwise on the circle,
        looking along the direction of walking)."""
        omega = self.walk_speed / self.walk_radius
        a = omega * t
        T = np.eye(4)
        T[:3, :3] = camera_rotation(a + math.pi / 2, math.radians(self.pitch_down_deg))
        T[:3, 3] = (self.walk_radius * math.cos(a), self.walk_radius * math.sin(a), self.eye_height)
        return T

    def render(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Colour (H, W, 3) uint8 RGB and depth (H, W) float32 metres (z in C) seen from ``pose``."""
        intr = self.intrinsics
        R, o = pose[:3, :3], pose[:3, 3]
        d = self._rays_c @ R.T                      # world directions, scaled so that z_C = 1
        n = d.shape[0]
        t_best = np.full(n, np.inf)
        color = np.zeros((n, 3))
        hx, hy = self.size[0] / 2, self.size[1] / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            # Floor (z = 0) and ceiling.
            for z0, normal_z, base in ((0.0, 1.0, None), (self.height, -1.0, (0.92, 0.92, 0.90))):
                t = (z0 - o[2]) / d[:, 2]
                hit = (t > 0) & (t < t_best)
                t_best = np.where(hit, t, t_best)
                if base is None:
                    px, py = o[0] + t * d[:, 0], o[1] + t * d[:, 1]
                    tile = (np.floor(px / 0.6) + np.floor(py / 0.6)) % 2
                    shade = np.where(tile > 0, 0.55, 0.45)[:, None] * np.array([1.0, 0.95, 0.85])
                    color = np.where(hit[:, None], shade, color)
                else:
                    color = np.where(hit[:, None], np.array(base), color)
            # Walls.
            walls = ((0, hx, (0.85, 0.80, 0.70)), (0, -hx, (0.70, 0.78, 0.85)),
                     (1, hy, (0.80, 0.85, 0.72)), (1, -hy, (0.88, 0.75, 0.75)))
            for axis, c, rgb in walls:
                t = (c - o[axis]) / d[:, axis]
                hit = (t > 0) & (t < t_best)
                t_best = np.where(hit, t, t_best)
                color = np.where(hit[:, None], np.array(rgb), color)
            # Boxes (slab method); faces shaded by orientation.
            for box in self.boxes:
                lo, hi = np.array(box.lo), np.array(box.hi)
                t1, t2 = (lo - o) / d, (hi - o) / d
                tmin = np.nanmax(np.minimum(t1, t2), axis=1)
                tmax = np.nanmin(np.maximum(t1, t2), axis=1)
                hit = (tmax >= tmin) & (tmin > 0) & (tmin < t_best)
                face = np.argmax(np.minimum(t1, t2), axis=1)
                shade = np.array([0.8, 0.65, 1.0])[face][:, None] * np.array(box.color)
                t_best = np.where(hit, tmin, t_best)
                color = np.where(hit[:, None], shade, color)
        if self.texture_cell > 0:
            hit = np.isfinite(t_best)
            p = o + (t_best[hit, None] - 1e-3) * d[hit]         # 1 mm in front of the surface: a stable cell
            cell = np.floor(p / self.texture_cell).astype(np.int64)
            h = (cell[:, 0] * 73856093) ^ (cell[:, 1] * 19349663) ^ (cell[:, 2] * 83492791)
            h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF          # mix the bits, keep 32 of them
            color[hit] *= (0.35 + 0.65 * (((h >> 16) & 0xFFFF) / 65535.0))[:, None]
        depth = t_best.reshape(intr.height, intr.width).astype(np.float32)  # t along z=1 rays = z_C
        depth[~np.isfinite(depth)] = np.nan
        rgb = (np.clip(color, 0, 1) * 255).astype(np.uint8).reshape(intr.height, intr.width, 3)
        return rgb, depth
