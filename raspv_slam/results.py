"""What the SLAM system returns: the per-frame result and a picture of the map (no ROS).

Frames (REP 105): M the map frame (gravity-aligned once anchored to a floor: z up, z = 0 on the
floor, x along the first view direction), O the odometry frame (continuous, drifts), C the
camera optical frame (x right, y down, z forward). Poses are 4×4 matrices, metres.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from raspv_common.occupancy import OccupancyGrid


class TrackingState(str, enum.Enum):
    INITIALISING = "initialising"    # no frame with depth and features yet (or a loaded map not yet found)
    TRACKING = "tracking"
    LOST = "lost"                    # N consecutive frames failed; relocalising
    RELOCALISED = "relocalised"      # this frame found its place in the map again (after LOST or at start)
    LOOP_CLOSED = "loop_closed"      # a pose-graph correction was applied at this frame
    NEW_MAP = "new_map"              # lost too long in an unmapped place: a new sub-map starts here (map_id changes)
    MAP_MERGED = "map_merged"        # this sub-map was recognised in an older one and re-expressed in its frame


@dataclass
class SlamResult:
    """One frame's result. ``map_from_camera`` is None while lost or initialising;
    ``odom_from_camera`` never jumps; ``map_from_odom`` is the correction (jumps at loop
    closures, relocalisations and merges): map_from_camera = map_from_odom @ odom_from_camera.
    ``map_id``: the sub-map whose frame ``map_from_camera`` is in (0 = the first map). A new
    sub-map's frame continues the last pose before LOST (the motion while lost is unknown), so
    its poses are not in the first map's frame: when ``map_id`` changes the world did, until a
    merge (state map_merged) brings the id back and moves ``map_from_odom``."""

    stamp: float
    state: TrackingState
    map_from_camera: np.ndarray | None
    odom_from_camera: np.ndarray
    map_from_odom: np.ndarray
    keyframe_id: int | None          # the reference keyframe the frame was tracked against
    inliers: int                     # PnP inliers of the frame (0 when the dense registration alone tracked it)
    time_ms: float                   # processing time of this frame (wall clock)
    map_id: int = 0


@dataclass
class MapSnapshot:
    """The map now: keyframe poses M ← C (id → 4×4), a sample of landmark points in M (N, 3),
    loop edges (pairs of keyframe ids), the floor-projected occupancy (None before the map is
    anchored to a floor), and whether it is gravity-aligned."""

    keyframe_poses: dict[int, np.ndarray]
    landmarks: np.ndarray
    loop_edges: list[tuple[int, int]]
    occupancy: OccupancyGrid | None
    anchored: bool = False
    covisibility_edges: list[tuple[int, int]] = field(default_factory=list)
