"""``raspv_msgs/StairDetection`` ↔ :class:`~raspv_perception.stair_model.Staircase` (no rclpy:
message classes only). ``None`` travels as ``detected = false``. A step's ``measured`` flag is
not in the message and comes back True."""
from __future__ import annotations

import numpy as np
from raspv_msgs.msg import StairDetection
from raspv_msgs.msg import Step as StepMsg
from std_msgs.msg import Header

from raspv_common.conversions import array_to_point, matrix_to_pose, pose_to_matrix, xyz_to_array
from raspv_perception.stair_model import Staircase, StairDirection, StairStep


def staircase_to_msg(stair: Staircase | None, header: Header | None = None) -> StairDetection:
    """Core result → message (``header``: stamp and frame of the depth image)."""
    msg = StairDetection(header=header or Header(), detected=stair is not None)
    if stair is None:
        return msg
    msg.direction = int(stair.direction)
    msg.pose = matrix_to_pose(stair.camera_from_stair)
    msg.riser, msg.tread, msg.width, msg.distance = (float(stair.riser), float(stair.tread), float(stair.width),
                                                     float(stair.distance))
    msg.steps = [StepMsg(index=s.index, height=float(s.height), depth=float(s.depth), width=float(s.width),
                         tread_corners=[array_to_point(c) for c in s.tread_corners])
                 for s in stair.steps]
    return msg


def staircase_from_msg(msg: StairDetection) -> Staircase | None:
    """Message → core result (None when nothing was detected)."""
    if not msg.detected:
        return None
    steps = [StairStep(int(s.index), float(s.height), float(s.depth), float(s.width),
                       np.array([xyz_to_array(c) for c in s.tread_corners]))
             for s in msg.steps]
    return Staircase(StairDirection(msg.direction), pose_to_matrix(msg.pose), float(msg.riser), float(msg.tread),
                     float(msg.width), float(msg.distance), steps)
