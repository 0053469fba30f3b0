"""The tf tree core: lookups between any two frames through static and stamped edges, the sim's
tf against its own camera pose, and what a replay sends from a recording's transforms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_common import frames
from raspv_common.transform_tree import TransformLookupError, TransformTree


def rot_z(deg: float, xyz=(0.0, 0.0, 0.0)) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = xyz
    return T


def test_lookup_composes_up_to_the_common_ancestor_and_down():
    tree = TransformTree()
    tree.set("map", "odom", rot_z(90, (1, 0, 0)), static=True)
    tree.set("odom", "base_link", rot_z(0, (2, 0, 0)), stamp=10.0)
    tree.set("base_link", "camera_link", rot_z(0, (0, 0, 1.5)), static=True)
    tree.set("map", "marker", rot_z(0, (5, 5, 0)), static=True)
    p_camera = np.array([0.0, 0.0, 0.0, 1.0])
    # camera origin: base (2, 0, 1.5) in odom → rotated 90° about z and moved 1 m in x in map
    assert tree.lookup("map", "camera_link", 10.0) @ p_camera == pytest.approx([1.0, 2.0, 1.5, 1.0])
    T = tree.lookup("camera_link", "marker", 10.0)                 # down from the common ancestor map
    assert T @ tree.lookup("marker", "camera_link", 10.0) == pytest.approx(np.eye(4))
    assert T @ p_camera == pytest.approx(np.linalg.inv(tree.lookup("map", "camera_link", 10.0)) @ [5, 5, 0, 1])
    assert tree.chain("camera_link") == ["camera_link", "base_link", "odom", "map"]
    assert tree.connected("marker", "camera_link") and not tree.connected("marker", "elsewhere")


def test_stamped_edges_are_interpolated_and_refused_far_outside_their_span():
    tree = TransformTree(max_extrapolation_s=0.1)
    tree.set("odom", "base_link", rot_z(0, (0, 0, 0)), stamp=1.0)
    tree.set("odom", "base_link", rot_z(90, (2, 0, 0)), stamp=2.0)
    mid = tree.lookup("odom", "base_link", 1.5)
    assert mid[:3, 3] == pytest.approx([1, 0, 0]) and mid[:3, :3] == pytest.approx(rot_z(45)[:3, :3])
    assert tree.lookup("odom", "base_link", 2.05)[:3, 3] == pytest.approx([2, 0, 0])   # held just past the newest
    with pytest.raises(TransformLookupError, match="newer than the newest"):
        tree.lookup("odom", "base_link", 3.0)
    assert tree.lookup("odom", "base_link")[:3, 3] == pytest.approx([2, 0, 0])            # no stamp: the newest


def test_bad_transforms_are_refused_with_the_reason():
    tree = TransformTree()
    tree.set("a", "b", np.eye(4), static=True)
    with pytest.raises(ValueError, match="loop"):
        tree.set("b", "a", np.eye(4), static=True)
    with pytest.raises(ValueError, match="needs a stamp"):
        tree.set("a", "c", np.eye(4))
    with pytest.raises(ValueError, match="finite 4x4"):
        tree.set("a", "c", np.full((4, 4), np.nan), static=True)
    with pytest.raises(TransformLookupError, match="not connected"):
        tree.lookup("a", "z")


def test_the_sims_tf_edges_compose_to_its_camera_pose():
    """base_link → head (joint) → camera_link → optical, as the sim node publishes them, is the
    avatar's own base ← camera: a frame placed by tf is where the sim rendered it."""
    from raspv_sim.avatar import Avatar, AvatarConfig, head_quaternion

    avatar = Avatar.__new__(Avatar)                # the pose arithmetic only: no world needed
    avatar._config = AvatarConfig()
    avatar.head = head_quaternion(0.2, -0.3, 0.6)
    tree = TransformTree()
    tree.set(frames.BASE_LINK, frames.HEAD, avatar.base_from_head(), stamp=0.0)
    tree.set(frames.HEAD, frames.CAMERA_LINK, avatar.head_from_camera_link(), static=True)
    tree.set(frames.CAMERA_LINK, frames.CAMERA_OPTICAL, frames.LINK_FROM_OPTICAL, static=True)
    assert tree.lookup(frames.BASE_LINK, frames.CAMERA_OPTICAL, 0.0) == pytest.approx(avatar.base_from_camera())


def test_a_mounting_reads_roll_pitch_yaw_as_urdf_does():
    T = frames.mounting_transform([0.1, 0.0, 1.2], [0.0, 0.0, 90.0])
    assert T[:3, 3] == pytest.approx([0.1, 0, 1.2]) and T[:3, 0] == pytest.approx([0, 1, 0])
    pitch_down = frames.mounting_transform([0, 0, 0], [0.0, 30.0, 0.0])
    assert pitch_down[:3, 0] @ [0, 0, 1] == pytest.approx(-0.5)      # x tilted 30° below the horizon
