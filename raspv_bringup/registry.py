"""Node kinds the launcher can start: kind → node module and parameter schema.

A graph file names nodes by kind (``kind: spv``); the launcher runs ``python -m <module>`` and
validates the node's parameters against ``<params module>:PARAMS`` before starting anything.
Parameter modules import nothing heavy, so validating a graph takes milliseconds.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

from raspv_common.params import ParamSchema


@dataclass(frozen=True)
class NodeSpec:
    module: str        # python -m <module> runs the node
    params: str        # "<module>:<attribute>" holding list[Param]
    help: str


NODES: dict[str, NodeSpec] = {
    "synthetic": NodeSpec("raspv_camera.synthetic_node", "raspv_camera.synthetic_params:PARAMS",
                          "RGB-D source rendering an analytic room (no simulator; tests, quick demos)"),
    "planner": NodeSpec("raspv_nav.planner_node", "raspv_nav.planner_params:PARAMS",
                        "navigation assistant: global path on the building map, obstacles from depth, DWA hint"),
    "sim": NodeSpec("raspv_sim.sim_node", "raspv_sim.sim_params:PARAMS", "virtual world (PyBullet): avatar, RGB-D camera, ground truth, collisions, logs"),
    "spv": NodeSpec("raspv_spv.spv_node", "raspv_spv.spv_params:PARAMS", "phosphene simulator: representation mode, temporal model, phosphene image"),
    "scene": NodeSpec("raspv_perception.scene_node", "raspv_perception.scene_params:PARAMS", "scene perception from depth: floor and gravity frame, planes, obstacles, free floor, per-pixel classes"),
    "stairs": NodeSpec("raspv_perception.stairs_node", "raspv_perception.stairs_params:PARAMS", "staircase detection from depth and the scene's floor: /stairs with pose, riser, tread, width and every step"),
    "segmentation": NodeSpec("raspv_perception.segmentation_node", "raspv_perception.segmentation_params:PARAMS", "semantic segmentation: person model with depth fusion, your ONNX/TorchScript model, or the sim's ground truth"),
    "odometry": NodeSpec("raspv_perception.odometry_node", "raspv_perception.odometry_params:PARAMS", "RGB-D odometry publishing /camera/pose for sources without a pose"),
    "slam": NodeSpec("raspv_slam.slam_node", "raspv_slam.slam_params:PARAMS",
                     "RGB-D SLAM: /camera/pose in the map frame, map → odom → base_link tf, tracking state, saved maps"),
    "bridge": NodeSpec("raspv_hmd.bridge_node", "raspv_hmd.bridge_params:PARAMS", "headset bridge: streams /spv/image to browser/native clients, publishes their head pose and teleop"),
    "teleop": NodeSpec("raspv_sim.teleop_node", "raspv_sim.teleop_params:PARAMS", "keyboard teleoperation of the avatar and its head (run in a terminal)"),
    "subject": NodeSpec("raspv_experiments.subject_node", "raspv_experiments.subject_params:PARAMS",
                        "scripted subject: sees /spv/frame and /spv/map only, drives /cmd_vel (experiments, sweeps)"),
    "camera": NodeSpec("raspv_camera.camera_node", "raspv_camera.camera_params:PARAMS", "a real RGB-D camera (RealSense, OpenNI2, DepthAI) or its SDK's recording: colour, registered depth, camera info, IMU"),
    "viz": NodeSpec("raspv_viz.viz_node", "raspv_viz.viz_params:PARAMS",
                    "RViz/Foxglove markers of planes, obstacles, free floor, stairs, path and phosphenes; depth as a point cloud"),
    "foxglove": NodeSpec("raspv_viz.foxglove_node", "raspv_viz.foxglove_params:PARAMS",
                         "Foxglove WebSocket server: the graph's topics (ROS 2 CDR) and run-time parameters, for the Foxglove app"),
    "replay": NodeSpec("raspv_camera.replay_node", "raspv_camera.replay_params:PARAMS", "a recorded bag as the source: original timing, rate, loop, remapping, /clock"),
}


def schema_for(kind: str) -> ParamSchema:
    """The parameter schema of node ``kind`` (KeyError for unknown kinds)."""
    spec = NODES[kind]
    module, attr = spec.params.split(":")
    return ParamSchema.of(getattr(importlib.import_module(module), attr))
