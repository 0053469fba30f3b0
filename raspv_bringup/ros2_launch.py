"""The launch description of a generated ``launch/*.launch.py`` file (`raspv export-launch`).

Imported by those files under a system ROS 2 (``launch`` and ``launch_ros`` are not on PyPI):
each node spec becomes a ``launch_ros.actions.Node`` printing to the screen, after the
launcher's middleware defaults — Fast DDS, discovery on this machine, the shared-memory
profile installed with raspv_bringup — each set only where the user's environment has none
(as ``raspv launch`` does, :mod:`raspv_bringup.middleware`).
"""
from __future__ import annotations

from typing import Any

MIDDLEWARE_DEFAULTS = (("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"), ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"))
SHM_PROFILE = ("config", "fastdds_shm.xml")     # under share/raspv_bringup


def launch_description(nodes: list[dict[str, Any]]):
    """A ``LaunchDescription`` starting ``nodes`` (keyword arguments of ``Node`` each)."""
    from launch import LaunchDescription
    from launch.actions import SetEnvironmentVariable
    from launch.substitutions import EnvironmentVariable, PathJoinSubstitution
    from launch_ros.actions import Node
    from launch_ros.substitutions import FindPackageShare

    profile = PathJoinSubstitution([FindPackageShare("raspv_bringup"), *SHM_PROFILE])
    defaults = [*MIDDLEWARE_DEFAULTS, ("FASTRTPS_DEFAULT_PROFILES_FILE", profile)]
    actions = [SetEnvironmentVariable(name, EnvironmentVariable(name, default_value=value)) for name, value in defaults]
    actions += [Node(output="screen", **spec) for spec in nodes]
    return LaunchDescription(actions)
