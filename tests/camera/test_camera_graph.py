"""config/camera.yaml — camera + scene + odometry + spv + bridge — on each SDK's own recording:
phosphenes built from the camera's frames reach a headset client; IMU gravity reaches scene
perception through /camera/imu."""
import asyncio
import json
import re

import numpy as np
import pytest
from raspv_msgs.msg import PhospheneFrame
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from sensor_msgs.msg import CameraInfo

from raspv_bringup.graph import CONFIG_DIR
from raspv_bringup.testing import RunningGraph
from raspv_bench.camera import tum_drift_frames
from raspv_camera.sdk_recordings import (SourceFrame, write_depthai_recording, write_realsense_recording)
from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_hmd.reference_client import ClientOptions, parse_endpoint, run_client
from raspv_perception.imu_gravity import STANDARD_GRAVITY
from raspv_perception.scene_perception import ScenePerception

from .conftest import needs_openni2

pytestmark = [pytest.mark.integration, pytest.mark.slow]
BRIDGE = ["bridge.port:=0", "bridge.tcp_port:=-1"]


@pytest.fixture(scope="module")
def tum_recordings(tmp_path_factory):
    """RealSense (.db3, with an accelerometer agreeing with the frame's floor) and DepthAI
    recordings of 30 frames of the real TUM desk frame drifting sideways."""
    folder = tmp_path_factory.mktemp("tum")
    frames = list(tum_drift_frames(30))
    K = frames[0][2]
    up = ScenePerception().process(frames[0][1], K).structure.floor_plane[:3]
    mm = [SourceFrame(c, np.nan_to_num(d * 1000).astype(np.uint16), t, STANDARD_GRAVITY * up) for c, d, _, t in frames]
    return {"realsense": write_realsense_recording(folder / "tum.db3", mm, K, with_accel=True),
            "depthai": write_depthai_recording(folder / "tum_depthai", mm, K), "up": up}


def phosphenes_from_the_camera(probe, timeout=120, lit=True, mode=None):
    """The first /spv/frame built from a camera frame (with phosphenes lit, in ``mode``: while the
    scene node starts, the spv node shows the camera in its depth fallback)."""
    return probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=timeout,
                                  predicate=lambda m: stamp_to_seconds(m.source_stamp) > 0
                                  and (not lit or max(m.levels, default=0) > 0) and (mode is None or m.mode == mode))


class TestTheRealSenseRecording:
    """config/camera.yaml on the RealSense recording, started once for two tests in this order: its
    phosphenes reach a headset client, then its loops over the following seconds."""

    @pytest.fixture(scope="class")
    def realsense_graph(self, tmp_path_factory, ros_domain, tum_recordings):
        g = RunningGraph(CONFIG_DIR / "camera.yaml", tmp_path_factory.mktemp("realsense_graph"),
                         [f"camera.file:={tum_recordings['realsense']}", *BRIDGE])
        yield g
        code = g.stop()
        assert code == 0, f"the camera graph ended with exit code {code}:\n{g.output[-3000:]}"

    def test_realsense_recording_to_phosphenes_in_the_headset_client(self, realsense_graph, probe):
        g = realsense_graph
        phosphenes_from_the_camera(probe, mode="chess_floor")     # the graph's mode: the scene node's frames come
        url = re.search(r"open (http://\S+) in a browser", g.wait_for_output(r"open http://\S+ in a browser").group(0)).group(1)
        report = asyncio.run(run_client(parse_endpoint(url), ClientOptions(duration_s=60, max_frames=20,
                                                                           keep_last_frame=True)))
        assert report.frames == 20 and report.last_frame is not None and np.asarray(report.last_frame).max() > 0
        g.wait_for_output(r"\[scene\].*first frame 640x480: floor 1\.\d\d m below", timeout=30)

    def test_a_recordings_loop_is_not_a_stop(self, realsense_graph, probe):
        """A 1-second recording looping (issue 21): its camera node stays alive and delivering while it
        re-opens the file, so the wearer never sees the no-data ring at a loop, and the scene node,
        alive, never makes the mode fall back — over some eight loops (and none since the graph started)."""
        from std_msgs.msg import String

        from raspv_common.qos import LATCHED_QOS

        phosphenes_from_the_camera(probe, mode="chess_floor")
        status = probe.subscribe(topics.SPV_STATUS, String, qos=LATCHED_QOS)
        frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
        got = frames.wait(400, timeout=120)                     # 8 s of 50 Hz display: ~8 loops of the recording
        shown = {}
        for f in got:
            shown[f.mode] = shown.get(f.mode, 0) + 1
        last = json.loads(status.wait(1, timeout=10)[0].data) if not status.messages else json.loads(status.messages[-1].data)
        print(f"\nover {len(got)} display frames: {shown}; status {last}")
        assert shown.get("no_data", 0) == 0 and set(shown) == {"chess_floor"}, shown
        assert last["stale_episodes"] == 0, last


def test_depthai_recording_to_phosphenes(graph, probe, tum_recordings):
    graph(CONFIG_DIR / "camera.yaml", [f"camera.file:={tum_recordings['depthai']}", *BRIDGE])
    phosphenes_from_the_camera(probe, mode="chess_floor")


def test_openni2_recording_to_phosphenes(graph, probe, openni2_recording):
    needs_openni2()
    path, _ = openni2_recording
    # the dummy device's picture is nearly black (0.3 % of its pixels lit, 0.5 % with depth):
    # phosphenes are built from its frames, but few or none light up
    graph(CONFIG_DIR / "camera.yaml", [f"camera.file:={path}", *BRIDGE])
    frame = phosphenes_from_the_camera(probe, lit=False)
    info = probe.wait_for_message(topics.CAMERA_INFO, CameraInfo, timeout=30)
    assert abs(stamp_to_seconds(frame.source_stamp) - stamp_to_seconds(info.header.stamp)) < 60   # the camera's clock


@pytest.mark.parametrize("imu", [True, False])
def test_imu_gravity_finds_a_floor_the_mounting_rules_out(graph, probe, tum_recordings, imu):
    """The TUM camera is 1.79 m above the floor: outside a robot mounting's 0.1–1.5 m. With the
    recording's accelerometer on /camera/imu the scene node finds the floor anyway (its first
    frames wait for the gravity estimate to settle)."""
    graph({"launch": {"nodes": [{"kind": "camera"}, {"kind": "scene"}]},
           "camera": {"ros__parameters": {"file": str(tum_recordings["realsense"]), "imu": imu}},
           "scene": {"ros__parameters": {"mounting": "robot"}}})
    msgs = probe.collect(topics.SCENE_STRUCTURE, SceneStructureMsg, 5, timeout=120)
    last = msgs[-1]
    if imu:
        assert last.floor_found and last.camera_height == pytest.approx(1.79, abs=0.08)
        assert last.gravity_source == SceneStructureMsg.GRAVITY_FLOOR
    else:     # the mounting's limits rule the real floor out (the desk top, 1.07 m below, is in range)
        assert not (last.floor_found and abs(last.camera_height - 1.79) < 0.2)
