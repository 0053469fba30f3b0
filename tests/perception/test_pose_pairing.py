"""Depth frames paired with the camera pose of their stamp (raspv_perception.pose_pairing): in
lockstep a frame waits for its own pose, so the prior it is processed with never depends on
which message came first."""
import numpy as np

from raspv_perception.pose_pairing import PosePairing


def pose(z):
    T = np.eye(4)
    T[2, 3] = z
    return T


def test_on_arrival_a_frame_takes_the_nearest_pose_there_is():
    p = PosePairing(0.2)
    assert p.add_frame(0.1, "f1") == (0.1, "f1") and p.prior(0.1) is None      # the first frame: no pose yet
    p.add_pose(0.1, pose(1.5))
    assert p.add_frame(0.2, "f2") == (0.2, "f2")
    assert p.prior(0.2)[2, 3] == 1.5                                            # the previous frame's
    assert p.prior(0.5) is None                                                  # older than max_age


def test_in_lockstep_a_frame_waits_for_the_pose_of_its_stamp():
    p = PosePairing(0.2, wait=True)
    assert p.add_frame(0.1, "f1") is None                       # the first frame too
    assert p.add_pose(0.1, pose(1.5)) == (0.1, "f1") and p.prior(0.1)[2, 3] == 1.5
    assert p.add_frame(0.2, "f2") is None                       # the pose of 0.1 is not this frame's
    assert p.add_pose(0.2 + 1e-9, pose(1.6)) == (0.2, "f2") and p.prior(0.2)[2, 3] == 1.6
    p.add_pose(0.3, pose(1.7))                                   # its pose overtook the frame
    assert p.add_frame(0.3, "f3") == (0.3, "f3") and p.waiting is None


def test_a_newer_frame_replaces_one_still_waiting():
    p = PosePairing(0.2, wait=True)
    p.add_frame(0.1, "f1")
    p.add_frame(0.2, "f2")
    assert p.dropped == 1
    assert p.add_pose(0.1, pose(1.5)) is None                   # not the waiting frame's pose
    assert p.add_pose(0.2, pose(1.6)) == (0.2, "f2")
