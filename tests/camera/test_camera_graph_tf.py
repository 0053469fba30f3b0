"""The shipped camera graph's tf tree (camera + scene + slam + spv, an SDK recording as the camera):
every frame_id a topic of the graph uses reaches ``map`` through what its nodes publish on /tf
and /tf_static — the camera's mounting, the slam node's map → odom → base_link, spv's phosphene frame."""
from __future__ import annotations

import pytest
import yaml

from raspv_bringup.graph import CONFIG_DIR
from raspv_common import frames
from tests.tf.test_tf_tree_graphs import FrameWatch

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_camera_graph_connects_every_frame_it_uses_to_map(graph, probe, depthai_recording):
    doc = yaml.safe_load((CONFIG_DIR / "camera.yaml").read_text())
    doc["launch"]["nodes"] = [n for n in doc["launch"]["nodes"] if n["kind"] != "bridge"]
    doc["camera"]["ros__parameters"].update({"file": str(depthai_recording.path), "at_end": "loop"})
    doc["spv"]["ros__parameters"].update({"headless": True})
    doc["slam"] = {"ros__parameters": {"save_on_exit": False, "autosave_period": 0.0, "anchor_timeout": 0.5}}
    watch = FrameWatch(probe)
    graph(doc)
    used = {frames.CAMERA_OPTICAL, "phosphene"}          # images, camera info, IMU; /spv/*
    watch.wait_for(used, timeout=120)
    assert used <= set(watch.frames), watch.frames
    assert not watch.unconnected(), (watch.unconnected(), watch.tree.edges())
    assert watch.tree.chain("phosphene") == ["phosphene", frames.CAMERA_OPTICAL, frames.CAMERA_LINK, frames.BASE_LINK,
                                             frames.ODOM, frames.MAP]
