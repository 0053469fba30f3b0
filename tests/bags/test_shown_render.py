"""The wearer's view re-rendered from a recording without images (issue 36, item 1): a live graph
recorded with `raspv bag record` — /spv/image too, to compare — and every recorded /spv/frame
drawn again from its brightness and the recorded /spv/sprites equals the live /spv/image of the
same stamp within one grey level (the atlas travels as half floats); `raspv render --shown`
writes them as a video."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from raspv_msgs.msg import PhospheneFrame

from raspv_bags.message_types import typestore
from raspv_bags.reader import BagReader
from raspv_bags.shown_render import shown_images
from raspv_common import topics

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_the_recorded_frames_redraw_the_live_image(graph, probe, tmp_path):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv"}]},
               "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"mode": "depth", "width": 200, "rate": 20.0}}})
    probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=120, predicate=lambda m: m.source_stamp.sec > 0)
    bag = tmp_path / "shown"
    rec = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "bag", "record", topics.SPV_IMAGE,
                          topics.SPV_FRAME, topics.SPV_SPRITES, topics.SPV_MAP, "-o", str(bag), "-d", "4"],
                         capture_output=True, text=True, timeout=120)
    assert rec.returncode == 0, rec.stderr[-2000:]
    store = typestore()
    with BagReader(bag) as reader:
        live = {}
        for m in reader.messages([topics.SPV_IMAGE]):
            im = store.deserialize_cdr(bytes(m.data), m.msgtype)
            live[(im.header.stamp.sec, im.header.stamp.nanosec)] = np.asarray(im.data, np.uint8).reshape(
                im.height, im.width, -1)[..., 0 if im.encoding == "mono8" else 1]
        compared = lit = 0
        worst = 0
        for shown in shown_images(reader):
            key = (int(shown.stamp), int(round((shown.stamp - int(shown.stamp)) * 1e9)))
            theirs = live.get(key) if key in live else next((v for k, v in live.items()
                                                             if abs(k[0] + k[1] * 1e-9 - shown.stamp) < 1e-6), None)
            if theirs is None:
                continue
            ours = shown.image if shown.image.ndim == 2 else shown.image[..., 1]
            worst = max(worst, int(np.abs(ours.astype(int) - theirs).max()))
            compared += 1
            lit += int(theirs.max() > 0)
    print(f"\n{compared} frames compared ({lit} lit), largest difference {worst} grey levels")
    assert compared >= 20 and lit >= 10 and worst <= 1, (compared, lit, worst)
    video = tmp_path / "shown.mp4"
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "render", str(bag), "--shown", "-o", str(video)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and video.stat().st_size > 0 and "frames as shown" in res.stdout, res.stderr
    assert g.running()
