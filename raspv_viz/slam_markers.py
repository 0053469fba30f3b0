"""A SLAM map as marker shapes (no ROS): keyframes, the keyframe trajectory, landmarks and loop edges.

Input is plain arrays (keyframe poses map ← camera optical by id, landmark points in the map, loop
and covisibility edges as pairs of keyframe ids), so any SLAM core's snapshot draws the same way;
:mod:`raspv_viz.viz_msg` turns the shapes into a ``visualization_msgs/MarkerArray`` in ``map``.
"""
from __future__ import annotations

import numpy as np

from raspv_viz.shapes import LINE_LIST, LINE_STRIP, SPHERE_LIST, MarkerShape

KEYFRAME = (0.20, 0.60, 1.00, 1.00)        # blue: keyframe camera centres and their viewing direction
TRAJECTORY = (0.20, 0.60, 1.00, 0.50)
LANDMARK = (0.85, 0.85, 0.85, 0.80)        # light grey points
LOOP = (1.00, 0.20, 0.80, 1.00)            # magenta: loop closures
COVISIBILITY = (0.40, 0.80, 0.40, 0.35)    # faint green: keyframes that see the same place
VIEW_LENGTH = 0.15                         # m: the viewing-direction tick drawn at each keyframe
MAX_LANDMARKS = 20_000                     # points drawn at most (a marker of more slows RViz down)


def slam_markers(keyframe_poses: dict[int, np.ndarray], landmarks: np.ndarray,
                 loop_edges: list[tuple[int, int]], covisibility_edges: list[tuple[int, int]] = ()
                 ) -> list[MarkerShape]:
    """Shapes in the map frame: ``keyframes`` (centres and a viewing tick each), ``trajectory``
    (keyframes in id order), ``landmarks``, ``loop_edges``, ``covisibility`` (edges whose two
    keyframes are both known)."""
    ids = sorted(keyframe_poses)
    centres = np.array([keyframe_poses[i][:3, 3] for i in ids], dtype=np.float64).reshape(-1, 3)
    forward = np.array([keyframe_poses[i][:3, 2] for i in ids], dtype=np.float64).reshape(-1, 3)
    shapes = []
    if len(ids):
        ticks = np.stack([centres, centres + VIEW_LENGTH * forward], axis=1).reshape(-1, 3)
        shapes += [MarkerShape("keyframes", 0, SPHERE_LIST, KEYFRAME, (0.06, 0.06, 0.06), centres),
                   MarkerShape("keyframes", 1, LINE_LIST, KEYFRAME, (0.01, 0.0, 0.0), ticks),
                   MarkerShape("trajectory", 0, LINE_STRIP, TRAJECTORY, (0.01, 0.0, 0.0), centres)]
    points = np.asarray(landmarks, dtype=np.float64).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) > MAX_LANDMARKS:
        points = points[np.linspace(0, len(points) - 1, MAX_LANDMARKS).astype(int)]
    if len(points):
        shapes.append(MarkerShape("landmarks", 0, SPHERE_LIST, LANDMARK, (0.02, 0.02, 0.02), points))
    index = {kf: k for k, kf in enumerate(ids)}
    for ns, edges, color, width in (("loop_edges", loop_edges, LOOP, 0.03),
                                    ("covisibility", covisibility_edges, COVISIBILITY, 0.005)):
        pairs = [(index[a], index[b]) for a, b in edges if a in index and b in index]
        if pairs:
            segments = centres[np.array(pairs, dtype=int).reshape(-1)]
            shapes.append(MarkerShape(ns, 0, LINE_LIST, color, (width, 0.0, 0.0), segments))
    return shapes
