"""The launch-time check that an SDK recording opens (raspv_camera.recording_check): the SDKs' own
recordings pass, the same files cut short or replaced by text are one line naming the file."""
from __future__ import annotations

import shutil

import pytest

from raspv_camera.recording_check import check_recording_opens
from raspv_camera.rgbd_frame import CameraError


def _cut(src, dst, keep: float):
    data = src.read_bytes()
    dst.write_bytes(data[:int(len(data) * keep)])
    return dst


def test_realsense_recordings_open_and_cut_ones_do_not(realsense_recording, tmp_path):
    check_recording_opens(realsense_recording.path, "realsense")
    for keep in (0.5, 0.9):
        cut = _cut(realsense_recording.path, tmp_path / f"cut{keep}.db3", keep)
        with pytest.raises(CameraError, match=rf"{cut}: not a readable RealSense recording \(.*malformed"):
            check_recording_opens(cut, "realsense")


def test_a_ros1_bag_without_realsense_images_is_refused(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    bag = tmp_path / "old.bag"
    with Writer(bag) as w:
        conn = w.add_connection("/device_0/sensor_0/Depth_0/image/data", "std_msgs/msg/String", typestore=store)
        w.write(conn, 1, store.serialize_ros1(store.types["std_msgs/msg/String"](data="x"), "std_msgs/msg/String"))
    with pytest.raises(CameraError, match=r"old\.bag: the RealSense recording has no colour images"):
        check_recording_opens(bag, "realsense")
    _cut(bag, tmp_path / "cut.bag", 0.5)
    with pytest.raises(CameraError, match=r"cut\.bag: not a readable RealSense \(ROS 1\) recording"):
        check_recording_opens(tmp_path / "cut.bag", "realsense")


def test_openni_recordings_open_and_cut_ones_do_not(openni2_recording, tmp_path):
    path, _ = openni2_recording
    check_recording_opens(path, "openni2")
    cut = _cut(path, tmp_path / "cut.oni", 0.5)
    with pytest.raises(CameraError, match=rf"{cut}: OpenNI recording cut off at byte"):
        check_recording_opens(cut, "openni2")


def test_depthai_recordings_open_and_cut_ones_do_not(depthai_recording, tmp_path):
    check_recording_opens(depthai_recording.path, "depthai")
    folder = tmp_path / "cut"
    shutil.copytree(depthai_recording.path, folder)
    _cut(depthai_recording.path / "color.mcap", folder / "color.mcap", 0.5)
    with pytest.raises(CameraError, match=r"color\.mcap: a damaged DepthAI recording file"):
        check_recording_opens(folder, "depthai")


def test_a_ros2_bag_given_as_a_camera_recording_points_to_the_replay_graph(tmp_path):
    """`raspv bag from-frames` writes a ROS 2 bag (a folder with metadata.yaml and an .mcap): the
    camera node's file check took it for a DepthAI recording and the node retried for ever."""
    from pathlib import Path

    from raspv_bags.from_frames import CAMERA_PRESETS, discover_frames, write_frames_bag
    from raspv_camera.drivers import check_recording

    frames = discover_frames(Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_8")
    fx, fy, cx, cy = CAMERA_PRESETS["tum-fr1"]
    bag = tmp_path / "tum_bag"
    write_frames_bag(frames, {"fx": fx, "fy": fy, "cx": cx, "cy": cy}, bag)
    for given in (bag, next(bag.glob("*.mcap"))):
        with pytest.raises(ValueError, match=rf"{given}: a ROS 2 bag \(it has metadata\.yaml\), not a camera SDK's "
                                             rf"recording: play it with `raspv launch replay replay\.bag:={bag}`"):
            check_recording(str(given), {"driver": "auto"})


def test_a_folder_with_one_mcap_is_not_a_depthai_recording(depthai_recording, tmp_path):
    folder = tmp_path / "one"
    folder.mkdir()
    shutil.copy(depthai_recording.path / "color.mcap", folder / "color.mcap")
    with pytest.raises(CameraError, match=r"one: a DepthAI recording needs a depth and a colour \.mcap file \(found 1\)"):
        check_recording_opens(folder, "depthai")
