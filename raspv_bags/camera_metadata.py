"""What a bag says about its camera beyond the camera info (no ROS).

ROS's ``sensor_msgs/CameraInfo`` carries intrinsics and lens distortion but not whether the colour
camera has a rolling shutter. ``raspv bag from-frames`` keeps a camera preset's readout in the
bag's ``metadata.yaml`` (rosbag2's ``custom_data``, key :data:`ROLLING_SHUTTER_KEY`), so it goes
with the recording: the graph launcher gives it to the `slam` node of a replay and ``raspv slam``
reads it from the bag.
"""
from __future__ import annotations

import math
from pathlib import Path

import yaml

from raspv_bags.from_frames import ROLLING_SHUTTER_KEY


def recorded_rolling_shutter(bag: str | Path) -> float | None:
    """The colour camera's rolling-shutter readout [s] a bag (its directory, or a storage file in
    it) carries in its metadata, None when it carries none or the metadata cannot be read (the
    bag's own reader reports a damaged bag)."""
    path = Path(bag).expanduser()
    meta = path / "metadata.yaml" if path.is_dir() else path.parent / "metadata.yaml"
    try:
        info = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]
        if path.is_file() and path.name not in [Path(f).name for f in info.get("relative_file_paths") or []]:
            return None                                   # another bag's metadata beside this file
        value = float((info.get("custom_data") or {})[ROLLING_SHUTTER_KEY])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError):
        return None
    return value if math.isfinite(value) and 0 <= value < 0.1 else None
