"""The spv node in a graph: outputs, run-time parameters, bad input."""
import re
import subprocess
import time
import sys

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import LATCHED_QOS
from raspv_msgs.msg import PhospheneFrame, PhospheneMap

pytestmark = [pytest.mark.integration, pytest.mark.usefixtures("warm_node_tables")]

SOURCE = {"kind": "synthetic", "name": "cam"}
SOURCE_PARAMS = {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120, "walk_speed": 0.0}}


def lit(msg: Image) -> bool:
    return max(msg.data) > 0


def test_spv_node_turns_camera_frames_into_phosphene_images(graph, probe):
    graph({"launch": {"nodes": [SOURCE, {"kind": "spv"}]}, "cam": SOURCE_PARAMS,
           "spv": {"ros__parameters": {"mode": "depth", "max_depth": 5.0, "width": 300, "device": "argus_iii",
                                       "rate": 25.0}}})
    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    assert (m.device, m.width, m.height, m.map_id, m.num_levels) == ("argus_iii", 300, 180, 1, 8)
    assert m.grid == PhospheneMap.GRID_RECTANGULAR and len(m.x) == len(m.dropped) == 240
    assert m.focal_px == pytest.approx(300 / (2 * np.tan(np.radians(10))), rel=1e-5)
    img = probe.wait_for_message(topics.SPV_IMAGE, Image, timeout=60, predicate=lit)
    assert (img.width, img.height, img.encoding) == (300, 180, "mono8")
    # (until the camera's first frame the no-data ring is shown)
    frame = probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=30,
                                   predicate=lambda f: f.mode == "depth" and max(f.levels) > 0)
    assert frame.map_id == 1 and frame.mode == "depth" and frame.temporal
    assert len(frame.levels) == len(frame.brightness) == 240
    assert 0 <= min(frame.brightness) and max(frame.brightness) <= 1.0
    assert frame.source_stamp.sec > 0


def test_parameters_change_at_run_time_and_bad_values_are_refused(graph, probe):
    g = graph({"launch": {"nodes": [SOURCE, {"kind": "spv"}]}, "cam": SOURCE_PARAMS,
               "spv": {"ros__parameters": {"width": 200, "rate": 20.0}}})
    probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    [(_, ok, _)] = probe.set_params("spv", {"num_phosphenes": 200})
    assert ok
    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=30, qos=LATCHED_QOS,
                               predicate=lambda m: m.map_id == 2)
    assert 200 <= len(m.x) <= 230                                       # close to N at this small size
    for name, value, reason in [("mode", "sonar", "not allowed"),
                                ("device", "argus_iv", "unknown device preset 'argus_iv'; presets: alpha_ims"),
                                ("num_levels", 1, "num_levels must be an integer in \\[2, 256\\]"),
                                ("edge_low", 500.0, "edge_low \\(500.0\\) must not exceed edge_high"),
                                ("num_phosphenes", 20000, "do not fit a 200x200 image")]:
        [(_, ok, why)] = probe.set_params("spv", {name: value})
        assert not ok and re.search(reason, why), why
    assert probe.get_params("spv", ["mode", "num_phosphenes", "device"]) == {
        "mode": "grey", "num_phosphenes": 200, "device": "default"}
    # the user's command line, and the green headset output
    cli = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "param", "set", "spv", "dropout", "2.0"],
                         capture_output=True, text=True, timeout=60)
    assert cli.returncode == 1 and "refused dropout=2.0" in cli.stderr
    results = probe.set_params("spv", {"output_format": "green", "device": "argus_ii", "num_phosphenes": 0})
    assert all(ok for _, ok, _ in results), results
    # changes are built in the background: wait for the image of the last one (argus_ii's aspect 0.6)
    img = probe.wait_for_message(topics.SPV_IMAGE, Image, timeout=60,
                                 predicate=lambda i: i.encoding == "rgb8" and i.height == 120)
    assert (img.width, img.height) == (200, 120)
    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=30, qos=LATCHED_QOS,
                               predicate=lambda m: m.device == "argus_ii" and len(m.x) == 60)
    # one rebuild per parameter, each a new map id (the map or its sprites changed): green output,
    # argus_ii with 200, then the device's 60
    assert m.map_id == 5
    [(_, ok, _)] = probe.set_params("spv", {"rate": 30.0})             # a new display timer
    assert ok
    probe.collect(topics.SPV_IMAGE, Image, 10, timeout=30)
    assert "Traceback" not in g.output


def test_bad_input_is_skipped_with_one_warning_and_display_goes_on(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "spv"}]},
               "spv": {"ros__parameters": {"mode": "depth", "width": 100, "rate": 20.0}}})
    probe.wait_for_message(topics.SPV_IMAGE, Image, timeout=60)      # displays before any input
    depth_pub = probe.publisher(topics.DEPTH, Image, wait_for_subscribers=1)
    info_pub = probe.publisher(topics.CAMERA_INFO, CameraInfo, wait_for_subscribers=1)
    cam = CameraIntrinsics.from_hfov(64, 48, 60.0)
    depth = np.full((48, 64), 1.0, np.float32)
    depth[:, :10] = np.nan
    depth[:, 10:20] = np.inf
    depth[:, 20:30] = 0.0
    for _ in range(30):                                                  # no camera info yet
        depth_pub.publish(array_to_image(depth, "32FC1"))
        probe.collect(topics.SPV_IMAGE, Image, 1)
    g.wait_for_output(r"images arrive but no camera info on /camera/color/camera_info", timeout=30)
    for _ in range(5):                                                   # wrong encoding
        depth_pub.publish(array_to_image(np.zeros((48, 64, 3), np.uint8), "rgb8"))
        info_pub.publish(intrinsics_to_camera_info(cam))
    g.wait_for_output(r"ignoring depth image on /camera/depth/image_raw: expected a depth image", timeout=30)
    wrong_size = CameraIntrinsics.from_hfov(64, 64, 60.0)
    mismatch = r"cannot use this frame: depth is 64x48 but the camera model is 64x64"
    for _ in range(60):              # the two topics race: the depth may be handled before the new info
        info_pub.publish(intrinsics_to_camera_info(wrong_size))
        depth_pub.publish(array_to_image(depth, "32FC1"))
        if re.search(mismatch, g.output):
            break
        time.sleep(0.5)
    g.wait_for_output(mismatch, timeout=5)
    col = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    shown = lambda f: f.mode == "depth" and max(f.levels) > 0           # noqa: E731 (not the no-data ring)
    for _ in range(20):                                                  # NaN, inf and 0 depth: rendered
        info_pub.publish(intrinsics_to_camera_info(cam))
        depth_pub.publish(array_to_image(depth, "32FC1"))
        try:
            col.wait(1, timeout=0.5, predicate=shown)
            break
        except TimeoutError:
            continue
    assert any(shown(m) for m in col.messages)
    probe.unsubscribe(col)
    assert g.running() and "Traceback" not in g.output
    assert g.output.count("ignoring depth image") == 1                   # rate-limited


def test_an_impossible_configuration_is_one_line_at_start(graph, tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("name: broken\nnum_phosphenes: 10\nfov_deg: 20\ngrid: hexagonal\n")
    g = graph({"launch": {"nodes": [{"kind": "spv"}]}, "spv": {"ros__parameters": {"device": str(bad)}}})
    g.proc.wait(timeout=60)                       # the launcher checks the device file before starting the node
    assert g.stop() == 2 and "Traceback" not in g.output
    assert re.search(r"spv\.ros__parameters\.device: .*broken.yaml: missing key\(s\) num_levels, phosphene_fov_deg",
                     g.output), g.output
