"""The stairs node in a real graph: sim (a world with a staircase ahead) → scene → stairs → spv
with the stairs overlay."""
from pathlib import Path

import numpy as np
import pytest
from raspv_msgs.msg import PhospheneFrame, StairDetection

from raspv_common import topics
from raspv_perception.stairs_msg import staircase_from_msg

pytestmark = pytest.mark.integration

WORLD = Path(__file__).resolve().parents[1] / "data" / "worlds" / "one_stair.yaml"


def test_stairs_node_finds_the_staircase_ahead_and_spv_draws_it(graph, probe):
    graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "scene"}, {"kind": "stairs"}, {"kind": "spv"}]},
           "sim": {"ros__parameters": {"world": str(WORLD), "rate": 10.0}},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "grey", "overlays": ["stairs"], "width": 400}}})
    detections = probe.subscribe(topics.STAIRS, StairDetection)
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    msg = detections.wait(1, timeout=120, predicate=lambda m: m.detected)[0]
    stair = staircase_from_msg(msg)
    assert msg.header.frame_id == "camera_color_optical_frame"
    assert stair.direction.name == "ASCENDING"
    assert stair.riser == pytest.approx(0.17, abs=0.015) and stair.tread == pytest.approx(0.29, abs=0.03)
    assert stair.distance == pytest.approx(3.5, abs=0.3)

    def stair_drawn(f: PhospheneFrame) -> bool:
        # the overlay puts the wireframe at the top level and halves the rest of the grey image
        levels = np.frombuffer(bytes(f.levels), np.uint8)
        top = int(levels.max())
        return top > 0 and (levels == top).sum() > 10 and levels[levels < top].max(initial=0) <= (top + 1) // 2

    frame = frames.wait(1, timeout=60, predicate=lambda f: list(f.overlays) == ["stairs"] and stair_drawn(f))[0]
    assert frame.mode == "grey"


def test_stairs_node_refuses_impossible_settings_in_one_line(graph):
    g = graph({"launch": {"nodes": [{"kind": "stairs"}]},
               "stairs": {"ros__parameters": {"h_min": 0.3, "h_max": 0.2}}})
    g.wait_for_output(r"configuration error: h_min \(0.3\) must be below h_max \(0.2\)")
    g.proc.wait(timeout=30)
    assert g.stop() == 1 and "Traceback" not in g.output
