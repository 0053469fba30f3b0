"""The `camera` node playing each SDK's own recording: the standard topics, unchanged."""
import shutil

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image, Imu
from tf2_msgs.msg import TFMessage

from raspv_common import frames, topics
from raspv_common.conversions import camera_info_to_intrinsics, image_to_array, stamp_to_seconds, transform_to_matrix
from raspv_common.qos import TF_STATIC_LISTENER_QOS

from .conftest import DEPTHAI_LENS, GRAVITY_C, RATE, needs_openni2

pytestmark = pytest.mark.integration


def camera_graph(params: dict) -> dict:
    return {"launch": {"nodes": [{"kind": "camera"}]},
            "camera": {"ros__parameters": {"at_end": "loop", **params}}}


def collect(probe, count, with_imu=False):
    cols = {t: probe.subscribe(t, cls) for t, cls in ((topics.COLOR, Image), (topics.DEPTH, Image),
                                                      (topics.CAMERA_INFO, CameraInfo), (topics.DEPTH_INFO, CameraInfo))}
    if with_imu:
        cols[topics.IMU] = probe.subscribe(topics.IMU, Imu)
    try:
        for t, col in cols.items():
            col.wait(1 if t == topics.IMU else count, timeout=90)
        return {t: list(col.messages) for t, col in cols.items()}
    finally:
        for col in cols.values():
            probe.unsubscribe(col)


def test_realsense_recording_arrives_unchanged(graph, probe, realsense_recording):
    rec = realsense_recording
    graph(camera_graph({"file": str(rec.path)}))
    got = collect(probe, 12, with_imu=True)
    by_color = {rec.frames[i].color.tobytes(): i for i in range(len(rec.frames))}
    seen = []
    for msg in got[topics.COLOR]:
        assert msg.encoding == "rgb8" and msg.header.frame_id == "camera_color_optical_frame"
        i = by_color[image_to_array(msg).tobytes()]                  # colour bit-exact
        seen.append((i, stamp_to_seconds(msg.header.stamp)))
    for msg in got[topics.DEPTH]:
        assert msg.encoding == "32FC1"
        depth = image_to_array(msg)
        ok = np.isfinite(depth)
        # REP 118 metres: the recording's millimetres × its depth scale (0.001), through the SDK's registration
        assert ok.mean() > 0.9 and np.nanmin(depth) >= 1.0 and np.nanmax(depth) < 1.2
    for t in (topics.CAMERA_INFO, topics.DEPTH_INFO):
        assert all(camera_info_to_intrinsics(m) == rec.camera for m in got[t])   # intrinsics exact, both infos
    # stamps: the recording's own spacing (frames 1/30 s apart), mapped to ROS time at rate 1
    # (the recording loops: compare consecutive frames of one pass)
    steps = [((j - i) / RATE, t2 - t1) for (i, t1), (j, t2) in zip(seen, seen[1:]) if j > i]
    assert len(steps) >= 5 and np.allclose(*zip(*steps), atol=1e-6)
    imu = got[topics.IMU][0]
    a = imu.linear_acceleration
    assert np.allclose([a.x, a.y, a.z], GRAVITY_C, atol=1e-5) and imu.orientation_covariance[0] == -1.0
    assert imu.header.frame_id == "camera_color_optical_frame"


def test_openni2_recording_in_millimetres(graph, probe, openni2_recording):
    needs_openni2()
    from raspv_camera.camera_driver import CameraSettings
    from raspv_camera.openni2_driver import OpenNI2Driver
    from raspv_camera.rgbd_frame import EndOfRecording

    path, _ = openni2_recording
    depths, colors = [], []
    with OpenNI2Driver(CameraSettings(file=str(path))) as d:    # the file as the driver reads it (test_openni2_driver
        while True:                                             # checks that against what was recorded)
            try:
                f = d.read(2.0)
            except EndOfRecording:
                break
            depths.append(f.depth.tobytes())
            colors.append(f.color.tobytes())
    graph(camera_graph({"file": str(path), "depth_encoding": "16UC1"}))
    got = collect(probe, 8)
    for msg in got[topics.DEPTH]:
        assert msg.encoding == "16UC1" and image_to_array(msg).tobytes() in depths       # the .oni's millimetres, exact
    for msg in got[topics.COLOR]:
        assert image_to_array(msg).tobytes() in colors
    assert camera_info_to_intrinsics(got[topics.CAMERA_INFO][0]).width == 320


def test_depthai_recording(graph, probe, depthai_recording):
    """… and the camera's mounting on /tf_static: base_link → camera_link → its optical frame."""
    rec = depthai_recording
    graph(camera_graph({"file": str(rec.path), "mounting_xyz": [0.1, 0.0, 1.2], "mounting_rpy": [0.0, 30.0, 0.0]}))
    got = collect(probe, 8)
    static = probe.wait_for_message(topics.TF_STATIC, TFMessage, qos=TF_STATIC_LISTENER_QOS, timeout=30)
    edges = {(t.header.frame_id, t.child_frame_id): transform_to_matrix(t.transform) for t in static.transforms}
    assert set(edges) == {(frames.BASE_LINK, frames.CAMERA_LINK), (frames.CAMERA_LINK, frames.CAMERA_OPTICAL)}
    assert edges[frames.BASE_LINK, frames.CAMERA_LINK] == pytest.approx(
        frames.mounting_transform([0.1, 0.0, 1.2], [0.0, 30.0, 0.0]))
    assert edges[frames.CAMERA_LINK, frames.CAMERA_OPTICAL] == pytest.approx(frames.LINK_FROM_OPTICAL)
    depths = {f.depth.tobytes(): i for i, f in enumerate(rec.frames)}
    # colour and depth of one frame share a stamp; the two subscriptions may start a frame apart
    colors = {(c.header.stamp.sec, c.header.stamp.nanosec): c for c in got[topics.COLOR]}
    pairs = [(colors[k], d) for d in got[topics.DEPTH] if (k := (d.header.stamp.sec, d.header.stamp.nanosec)) in colors]
    assert len(pairs) >= len(got[topics.DEPTH]) - 2, "colour and depth frames do not share stamps"
    for c, d in pairs:
        mm = np.nan_to_num(image_to_array(d) * 1000.0).round().astype(np.uint16)
        i = depths[mm.tobytes()]                                        # RAW16 → metres → mm, exact
        assert np.array_equal(image_to_array(c), rec.frames[i].color)
    assert camera_info_to_intrinsics(got[topics.DEPTH_INFO][0]) == rec.camera
    for t in (topics.CAMERA_INFO, topics.DEPTH_INFO):          # the lens's distortion, as ROS names it
        info = got[t][0]
        assert info.distortion_model == "rational_polynomial" and list(info.d) == pytest.approx(DEPTHAI_LENS, abs=1e-7)


def test_no_camera_is_reported_and_retried_while_the_graph_runs(graph, probe, tmp_path, realsense_recording):
    # the launcher opens the recording before it starts anything (a file that does not open is
    # refused there), so it breaks while the graph runs: at the end of a pass the node reopens it
    later = tmp_path / "later.db3"
    shutil.copy(realsense_recording.path, later)
    g = graph(camera_graph({"driver": "realsense", "file": str(later), "retry_period": 0.2}))
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    (tmp_path / "empty.db3").write_bytes(b"")
    (tmp_path / "empty.db3").replace(later)                          # the recording is gone to nothing
    g.wait_for_output(r"later\.db3.*; retrying every 0\.2 s", timeout=60)
    tmp = tmp_path / "writing.db3"
    tmp.write_bytes(realsense_recording.path.read_bytes())
    tmp.replace(later)                                                # the recording is back, whole
    g.wait_for_output(r"camera back", timeout=30)
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    assert g.running()


def test_missing_device_with_no_file(graph):
    g = graph({"launch": {"nodes": [{"kind": "camera"}]}, "camera": {"ros__parameters": {"retry_period": 0.5}}})
    g.wait_for_output(r"no camera connected \(searched: RealSense, OpenNI2, DepthAI\); retrying every 0\.5 s", timeout=60)
    assert g.running()
