"""A camera the viewer's head does not carry is never turned by the viewer's head
(raspv_spv.camera_source; the launcher sets spv's camera_source from the graph's source node)."""
import math

import numpy as np
import pytest

from raspv_bringup.graph import GraphError, load_graph
from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.camera_source import CAMERA_SOURCES, camera_source_of, head_turns_camera
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.reprojection import DisplayFrame, DisplayView
from raspv_spv.simulator import PhospheneSimulator

K = CameraIntrinsics.from_hfov(320, 240, 60.0)


def head_q(yaw_deg):
    y = math.radians(yaw_deg) / 2
    return (0.0, 0.0, math.sin(y), math.cos(y))


def test_only_the_sim_head_camera_and_a_head_mounted_camera_follow_the_head():
    assert {s for s in CAMERA_SOURCES if head_turns_camera(s)} == {"sim", "head"}
    with pytest.raises(ValueError, match="unknown camera source 'helmet'"):
        head_turns_camera("helmet")


@pytest.mark.parametrize("kind, file, mounting, expected", [
    ("sim", "", "head", "sim"),
    ("camera", "", "head", "head"),                      # a live camera on the head: it may
    ("camera", "walk.db3", "head", "recording"),         # its recording: never
    ("camera", "", "hand", "hand"), ("camera", "", "chest", "chest"), ("camera", "", "robot", "robot"),
    ("replay", "", "head", "recording"),
    ("synthetic", "", "head", "unknown"),
])
def test_camera_source_of_the_graph_source(kind, file, mounting, expected):
    assert camera_source_of(kind, file, mounting) == expected


def spv_params(graph, overrides=()):
    g = load_graph(graph, list(overrides), check_files=False)
    return next(n for n in g.nodes if n.kind == "spv").params


@pytest.mark.parametrize("graph, overrides, expected", [
    ("config/demo.yaml", [], "sim"),
    ("config/camera.yaml", [], "head"),
    ("config/camera.yaml", ["camera.file:=walk.db3"], "recording"),
    ("config/camera.yaml", ["scene.mounting:=hand"], "hand"),
    ("config/replay.yaml", ["replay.bag:=walk.db3"], "recording"),
])
def test_the_launcher_sets_camera_source_from_the_graph(graph, overrides, expected):
    params = spv_params(graph, overrides)
    assert params["camera_source"] == expected
    assert params.get("reprojection", True)           # the switch stays on; the source decides


def test_a_camera_source_contradicting_the_graph_is_refused():
    with pytest.raises(GraphError, match=r"spv\.ros__parameters\.camera_source: 'head', but the images come from "
                                         r"a recording \(camera node\): 'recording'"):
        load_graph("config/camera.yaml", ["camera.file:=walk.db3", "spv.camera_source:=head"], check_files=False)


def ramp():
    u = np.linspace(0, 255, K.width, dtype=np.float32)
    return np.repeat(np.broadcast_to(u, (K.height, K.width))[..., None], 3, axis=2).astype(np.uint8)


@pytest.mark.parametrize("source", sorted(CAMERA_SOURCES))
def test_the_display_follows_the_head_only_for_a_camera_on_it(source):
    sim = PhospheneSimulator(spv_config("optimist", width=300, mode="grey", temporal=False))
    view = DisplayView(reprojection=True, camera_source=source)
    inputs = FrameInputs(color=ramp(), camera=K, stamp=1.0)
    captured = sim.levels(inputs)
    view.add_frame(DisplayFrame(1.0, inputs, captured, 1))
    view.tracker.add_head(0.9, head_q(0.0))
    view.tracker.add_head(1.0, head_q(0.0))
    view.tracker.add_head(1.01, head_q(20.0))                 # the viewer drags 20° to the left
    levels, _ = view.levels_at(sim, 1, 1.02)
    if head_turns_camera(source):
        assert (levels != captured).mean() > 0.3
    else:
        assert levels is captured
    view.configure(True, 0.0, "recording")                    # switched at run time: off at once
    assert view.levels_at(sim, 1, 1.04)[0] is captured
