"""`make demo`'s graph: phosphene images are published within 60 s and Ctrl-C stops it cleanly."""
import re

import numpy as np
import pytest
from sensor_msgs.msg import Image

from raspv_bringup.graph import CONFIG_DIR
from raspv_common import topics
from raspv_common.conversions import image_to_array

pytestmark = pytest.mark.integration


def test_demo_publishes_phosphenes_and_stops_cleanly(graph, probe):
    g = graph(CONFIG_DIR / "demo.yaml")
    img = probe.wait_for_message(topics.SPV_IMAGE, Image, timeout=60,
                                 predicate=lambda m: image_to_array(m).max() > 0)
    arr = image_to_array(img)
    assert arr.shape == (800, 800) and arr.dtype == np.uint8
    g.wait_for_output(r"open http://127\.0\.0\.1:\d+/ in a browser")
    assert g.stop() == 0
    table = g.output[g.output.index("resources per node"):]
    peaks = {m.group(1): float(m.group(2)) for m in re.finditer(r"^(\w+)\s+\w+\s+0\s+(\d+)\s", table, re.M)}
    assert set(peaks) == {"sim", "scene", "spv", "bridge"}, g.output[-4000:]      # (a node's last words too)
    # the budget: ≤ 2.5 GB resident in total, no node above 600 MB
    assert max(peaks.values()) <= 600 and sum(peaks.values()) <= 2500, table
