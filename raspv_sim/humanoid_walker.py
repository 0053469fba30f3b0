"""The pybullet_data humanoid animated with its walking motion clip (DeepMimic format).

The clip is a list of frames ``[duration, root xyz (3), root quat (4), chest (4), neck (4),
right hip (4), right knee (1), right ankle (4), right shoulder (4), right elbow (1), left hip (4),
left knee (1), left ankle (4), left shoulder (4), left elbow (1)]`` with quaternions (w, x, y, z)
in the model's y-up frame. The walking phase follows the distance walked so the feet do not slide.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

URDF = "humanoid/humanoid.urdf"
CLIP = "data/motions/humanoid3d_walk.txt"
MODEL_HEIGHT = 1.62      # m, standing height of the humanoid at scale 0.25 (the clip's units)
BASE_SCALE = 0.25
# clip field → (URDF joint index, number of values)
_JOINTS = (("chest", 1, 4), ("neck", 2, 4), ("right_hip", 3, 4), ("right_knee", 4, 1), ("right_ankle", 5, 4),
           ("right_shoulder", 6, 4), ("right_elbow", 7, 1), ("left_hip", 9, 4), ("left_knee", 10, 1),
           ("left_ankle", 11, 4), ("left_shoulder", 12, 4), ("left_elbow", 13, 1))   # link order as in the clip
# link index → body part, for dressing the model
LINK_PARTS = {0: "hips", 1: "torso", 2: "head", 3: "leg", 4: "leg", 5: "foot", 6: "arm", 7: "arm", 8: "hand",
              9: "leg", 10: "leg", 11: "foot", 12: "arm", 13: "arm", 14: "hand"}


def _nlerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    if float(np.dot(a, b)) < 0:
        b = -b
    q = (1 - t) * a + t * b
    return q / np.linalg.norm(q)


@dataclass
class WalkPose:
    """Root height above the feet [m], root orientation (x, y, z, w) in the y-up model frame, and
    joint targets: joint index → quaternion (x, y, z, w) or [angle rad]."""

    root_height: float
    root_quat: np.ndarray
    joints: dict[int, list[float]]


class WalkClip:
    """The walking clip, sampled by distance walked."""

    def __init__(self, data_dir: Path):
        frames = np.asarray(json.loads((Path(data_dir) / CLIP).read_text())["Frames"], dtype=float)
        self.frames = frames
        self.times = np.concatenate([[0.0], np.cumsum(frames[:-1, 0])])
        self.duration = float(self.times[-1])
        self.stride = float(np.hypot(frames[-1, 1] - frames[0, 1], frames[-1, 3] - frames[0, 3]))  # m per cycle
        self.ground = float(frames[:, 2].min())

    def pose(self, distance: float, scale: float) -> WalkPose:
        """Pose after walking ``distance`` m, for a model scaled by ``scale`` relative to the clip."""
        phase = (distance / (self.stride * scale)) % 1.0 if self.stride > 0 else 0.0
        t = phase * self.duration
        i = min(int(np.searchsorted(self.times, t, side="right")) - 1, len(self.frames) - 2)
        a = (t - self.times[i]) / max(self.times[i + 1] - self.times[i], 1e-9)
        f0, f1 = self.frames[i], self.frames[i + 1]
        root_h = ((1 - a) * f0[2] + a * f1[2]) * scale

        def quat(k: int) -> np.ndarray:
            q = _nlerp(f0[k:k + 4], f1[k:k + 4], a)   # (w, x, y, z)
            return np.array([q[1], q[2], q[3], q[0]])

        joints: dict[int, list[float]] = {}
        k = 8
        for _, index, size in _JOINTS:
            joints[index] = list(quat(k)) if size == 4 else [float((1 - a) * f0[k] + a * f1[k])]
            k += size
        return WalkPose(root_h, quat(4), joints)


def z_up_orientation(heading: float, root_quat_yup: np.ndarray) -> tuple[float, float, float, float]:
    """World orientation (x, y, z, w) of the humanoid's root: yaw ``heading`` [rad] about W's z,
    the model's y-up frame turned to z-up, then the clip's root rotation."""
    def mul(p, q):
        x1, y1, z1, w1 = p
        x2, y2, z2, w2 = q
        return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)
    yaw = (0.0, 0.0, math.sin(heading / 2), math.cos(heading / 2))
    y_to_z = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))
    return mul(mul(yaw, y_to_z), tuple(root_quat_yup))
