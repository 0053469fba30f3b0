"""The levels stream in a real browser (issue 21): chromium draws the phosphenes from one weight per
phosphene and the sprite atlas, and its image equals the spv node's own rendering of the same frame
(matched by stamp) for Gaussian, axon-map and biphasic axon-map sprites, switched at run time.
Then the wearer never sees a frozen frame: the spv node killed → the bridge's no-data ring; the
bridge killed too → the page blinks the ring itself (issue 27, items 1–2)."""
from __future__ import annotations

import os
import re
import signal
import tempfile
import time

import numpy as np
import pytest
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_common.qos import LATCHED_QOS
from raspv_msgs.msg import PhospheneMap

CHROMIUM = "/usr/bin/chromium"
pytestmark = [
    pytest.mark.integration, pytest.mark.browser, pytest.mark.slow,
    pytest.mark.skipif(not os.path.exists(CHROMIUM),
                       reason=f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)"),
]
sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright Python package is not installed")

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
# Tolerance: the atlas travels as half floats and the page sums in a float (or half-float)
# framebuffer, so a pixel near a rounding boundary may come out one grey level off; none more.
MAX_DIFF, MAX_OFF_SHARE = 1, 0.02
DEVICES = ("optimist", "argus_ii_axon", "argus_ii_biphasic")   # Gaussian, axon map, one sprite per level


def test_the_page_draws_what_the_spv_node_renders(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv", "restart": True, "spare": False},
                                    {"kind": "bridge"}]},
               "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"device": DEVICES[0], "mode": "depth", "max_depth": 4.0, "width": 320,
                                           "rate": 20.0}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}})
    url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=60).group(1)
    report = []
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        context = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                       viewport={"width": 640, "height": 480})
        try:
            page = context.new_page()
            page.goto(url + "?overlay=0")
            for i, device in enumerate(DEVICES):
                if i:
                    [(_, ok, why)] = probe.set_params("spv", {"device": device})
                    assert ok, why
                try:
                    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=180, qos=LATCHED_QOS,
                                               predicate=lambda m, d=device: m.device == d)
                except TimeoutError:
                    raise AssertionError(f"no map of {device}: {g.output[-3000:]}") from None
                page.wait_for_function(f"() => window.raspvClient.spritesMapId === {m.map_id} && "
                                       f"window.raspvClient.framesShown > 3 && !window.raspvClient.lastNoData",
                                       timeout=120_000)
                assert page.evaluate("() => window.raspvClient.drawsLevels")
                # the server's rendering of the same frames (a collector per device: it keeps every image)
                images = probe.subscribe(topics.SPV_IMAGE, Image, wait_for_publishers=1)
                images.wait(2, timeout=60)                   # the spv node renders images now
                compared = 0
                for _ in range(60):                          # three frames with phosphenes lit
                    drawn = page.evaluate("() => window.raspvClient.readImage()")
                    try:                                     # (drawn before the images started: skip it)
                        server = images.wait(1, timeout=5, predicate=lambda im, t=drawn["stamp"]:
                                             abs(stamp_to_seconds(im.header.stamp) - t) < 1e-6)[0]
                    except TimeoutError:
                        continue
                    ours = np.array(drawn["pixels"], np.uint8).reshape(drawn["height"], drawn["width"])
                    theirs = np.frombuffer(bytes(server.data), np.uint8).reshape(server.height, server.width, -1)
                    theirs = theirs[..., 0 if server.encoding == "mono8" else 1]
                    diff = np.abs(ours.astype(int) - theirs)
                    assert diff.max() <= MAX_DIFF and (diff > 0).mean() <= MAX_OFF_SHARE, (device, diff.max(), report)
                    if theirs.max() > 0:
                        compared += 1
                        report.append(f"{device}: max {diff.max()}, {100 * (diff > 0).mean():.2f} % of pixels off, "
                                      f"peak {int(theirs.max())}")
                    if compared == 3:
                        break
                    time.sleep(0.1)
                probe.unsubscribe(images)
                assert compared == 3, f"{device}: no lit frame to compare ({report})"
            accumulation = page.evaluate("() => window.raspvClient.accumulation")

            # the spv node killed (restarted cold): the bridge draws the no-data ring meanwhile
            os.kill(_pid(g, "spv"), signal.SIGKILL)
            page.wait_for_function("() => window.raspvClient.lastNoData && !window.raspvClient.localRing",
                                   timeout=10_000)
            # the bridge killed as well (the graph stops): the page blinks the ring itself
            os.kill(_pid(g, "bridge"), signal.SIGKILL)
            page.wait_for_function("() => window.raspvClient.localRing", timeout=10_000)
            ring = None
            for _ in range(40):                                   # the ring blinks: catch an "on" phase
                drawn = page.evaluate("() => window.raspvClient.readImage()")
                img = np.array(drawn["pixels"], np.uint8).reshape(drawn["height"], drawn["width"])
                if img.max() > 0:
                    ring = img
                    break
                time.sleep(0.05)
            assert ring is not None
            h, w = ring.shape
            assert ring[h // 4: 3 * h // 4, w // 4: 3 * w // 4].max() == 0      # lit only near the border
        finally:
            context.close()
    print(f"\nlevels stream vs server image (accumulation {accumulation}):\n" + "\n".join(report))



def _pid(g, name: str) -> int:
    """The newest pid of node ``name`` (started, or restarted) in the launcher's lines."""
    found = re.findall(rf"{name} \(\w+, pid (\d+)\)|node '{name}' ended .*?pid (\d+)\)", g.output)
    return int([a or b for a, b in found][-1])
