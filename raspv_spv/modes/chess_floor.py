"""Chess-Floor (paper §IV-A1): a checkerboard of full and half level on the obstacle-free
floor only, fixed to the world and aligned with the Manhattan axes.

Each phosphene's ray r_i (camera optical frame) meets the floor plane at P = t·r_i (paper: planes
via ray intersection); P in the world frame (``camera_pose``, W ← C: ground truth in the sim,
odometry on real data) picks the tile, so the texture stays put while the camera moves. The
tiles are turned to the Manhattan orientation, estimated once in the world and kept. Without
a pose the tiles live in the floor frame F (origin below the camera) turned to the Manhattan
axes: aligned with the room, but moving with the subject. A phosphene is drawn only when its
camera pixel is obstacle-free floor in ``/scene/labels``.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_perception import scene_labels as L
from raspv_spv.modes.base import Mode, quantise


def _quarter_turn(angle: float) -> float:
    """An axis direction [rad] folded into [−45°, 45°): the four Manhattan directions are one
    orientation (the smallest turn keeps the checkerboard's colours where they were)."""
    q = math.pi / 2
    return (angle + q / 2) % q - q / 2


def floor_points(scene, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (N, 3) where ``rays`` (N, 3) meet the scene's floor, and (N,) bool
    for rays that do (in front of the camera)."""
    plane = np.asarray(scene.floor_plane, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -plane[3] / (rays @ plane[:3])
    hit = np.isfinite(t) & (t > 0)
    return rays * np.where(hit, t, 0.0)[:, None], hit


class ChessFloorMode(Mode):
    """Tiles of ``chess_tile`` m at full and half level on obstacle-free floor; all else off."""

    name = "chess_floor"
    description = "world-fixed checkerboard (full/half level) on the obstacle-free floor"
    needs = frozenset({"scene", "scene_labels", "camera"})
    optional_inputs = frozenset({"camera_pose"})     # used when a source publishes it
    defaults = {"chess_tile": 0.5}

    def __init__(self, settings=None) -> None:
        super().__init__(settings)
        self.world_angle: float | None = None    # Manhattan orientation in W [rad], kept once found

    def tile_parity(self, inputs, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N,) 0/1 tile colour of each ray's floor point, and (N,) bool: the ray meets the floor."""
        scene = inputs.scene
        P, hit = floor_points(scene, rays)
        pose = inputs.camera_pose
        if pose is not None:
            pose = np.asarray(pose, dtype=np.float64)
            world = P @ pose[:3, :3].T + pose[:3, 3]
            if self.world_angle is None and scene.manhattan_found:
                mz = pose[:3, :3] @ np.asarray(scene.manhattan_z, dtype=np.float64)
                self.world_angle = _quarter_turn(math.atan2(mz[1], mz[0]))
            angle = self.world_angle or 0.0
            x, y = world[:, 0], world[:, 1]
        else:
            F_from_C = np.linalg.inv(np.asarray(scene.camera_to_floor, dtype=np.float64))
            in_f = P @ F_from_C[:3, :3].T + F_from_C[:3, 3]
            angle = 0.0
            if scene.manhattan_found:
                mz = F_from_C[:3, :3] @ np.asarray(scene.manhattan_z, dtype=np.float64)
                angle = _quarter_turn(math.atan2(mz[0], mz[2]))
            x, y = in_f[:, 2], in_f[:, 0]           # forward, right
        c, s = math.cos(angle), math.sin(angle)
        tile = float(self.settings["chess_tile"])
        a = np.floor((c * x + s * y) / tile)
        b = np.floor((-s * x + c * y) / tile)
        return ((a + b) % 2).astype(np.uint8), hit

    def on_free_floor(self, inputs, sampling) -> np.ndarray:
        """(N,) bool: the phosphene's camera pixel is obstacle-free floor."""
        return sampling.sample(inputs.scene_labels, fill=L.NONE) == L.FLOOR

    def levels(self, inputs, sampling, num_levels):
        out = np.zeros(sampling.count, dtype=np.uint8)
        if not inputs.scene.floor_found:
            return out
        draw = self.on_free_floor(inputs, sampling)
        if not draw.any():
            return out
        parity, hit = self.tile_parity(inputs, sampling.rays[draw])
        full, half = num_levels - 1, int(quantise(np.array([0.5]), num_levels)[0])
        out[draw] = np.where(hit, np.where(parity == 0, full, half), 0)
        return out
