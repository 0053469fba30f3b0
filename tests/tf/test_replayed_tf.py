"""What the replay node sends on /tf and /tf_static from a recording (raspv_bags.replayed_tf)."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_bags.message_types import typestore
from raspv_bags.replayed_tf import TF_TYPE, ReplayedTf, _transform
from raspv_common import frames


def tf_bytes(*edges) -> bytes:
    store = typestore()
    msg = store.types[TF_TYPE](transforms=[_transform(p, c, np.eye(4), 0) for p, c in edges])
    return bytes(store.serialize_cdr(msg, TF_TYPE))


def children(data: bytes | None) -> list[str]:
    return [t.child_frame_id for t in typestore().deserialize_cdr(data, TF_TYPE).transforms]


def test_transforms_a_pose_node_owns_are_left_out_and_the_head_joint_kept():
    tf = ReplayedTf(exclude_children=[frames.ODOM, frames.BASE_LINK])
    both = tf_bytes((frames.ODOM, frames.BASE_LINK), (frames.BASE_LINK, frames.HEAD))
    assert children(tf.tf(both)) == [frames.HEAD]
    assert tf.tf(tf_bytes((frames.ODOM, frames.BASE_LINK))) is None          # nothing left: nothing sent
    assert ReplayedTf().tf(both) == both                                      # nothing excluded: bytes unchanged


def test_static_messages_of_several_recorded_nodes_are_sent_as_one_union():
    tf = ReplayedTf(exclude_children=[frames.ODOM])
    sim = tf_bytes((frames.MAP, frames.ODOM), (frames.HEAD, frames.CAMERA_LINK))
    camera = tf_bytes((frames.CAMERA_LINK, frames.CAMERA_OPTICAL))
    assert children(tf.tf_static(sim)) == [frames.CAMERA_LINK]               # map → odom is the slam node's
    assert sorted(children(tf.tf_static(camera))) == sorted([frames.CAMERA_LINK, frames.CAMERA_OPTICAL])
    assert tf.tf_static(tf_bytes((frames.MAP, frames.ODOM))) is None          # a loop's repeat adds nothing


def test_a_recording_without_tf_static_gets_the_camera_mounting_of_its_image_frame():
    sent = ReplayedTf().mounting("xtion_rgb_optical_frame", 5)
    store = typestore()
    got = {t.child_frame_id: t for t in store.deserialize_cdr(sent, TF_TYPE).transforms}
    assert {c: t.header.frame_id for c, t in got.items()} == {frames.CAMERA_LINK: frames.BASE_LINK,
                                                               "xtion_rgb_optical_frame": frames.CAMERA_LINK}
    q = got["xtion_rgb_optical_frame"].transform.rotation
    from raspv_common.rotations import quaternion_to_matrix
    assert quaternion_to_matrix(q.x, q.y, q.z, q.w) == pytest.approx(frames.LINK_FROM_OPTICAL[:3, :3])
