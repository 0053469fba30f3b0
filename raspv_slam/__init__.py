"""RGB-D SLAM (no ROS): tracking against keyframes, loop closure, saved maps and localisation.

The parts, split the way the field splits them (ORB-SLAM2's threads, RTAB-Map's localisation
mode): :mod:`features` (ORB with depth), :mod:`tracking` (every frame: PnP against the reference
keyframe, refined by dense RGB-D registration), :mod:`keyframe` and :mod:`slam_map` (keyframes,
pose graph), :mod:`place_recognition` (bag of binary words), :mod:`loop_closing` (verified loop
and covisibility edges, GTSAM pose-graph optimisation in a background thread),
:mod:`relocalisation`, :mod:`map_store` (maps on disk), :mod:`floor_occupancy` (the map seen
from above) and :mod:`slam_system` (the one object a node or a command uses).
"""
from raspv_slam.config import SlamConfig
from raspv_slam.results import MapSnapshot, SlamResult, TrackingState

__all__ = ["SlamConfig", "SlamResult", "TrackingState", "MapSnapshot"]
