"""The browser client in a real browser: Debian's chromium driven by Playwright (Python).

The page is served by a HeadsetServer streaming the phosphene test pattern; the tests look at
the canvas, hold arrow keys, drag the view, press viewer keys, switch stereo/green, run a
(simulated) WebXR session and phone orientation events, and check what reaches the server.
CI installs the browser with ``apt-get install -y chromium``.
"""
from __future__ import annotations

import math
import os
import tempfile
import threading
import time

import cv2
import numpy as np
import pytest

from raspv_hmd import protocol as P
from raspv_hmd.test_pattern import PhospheneTestPattern
from raspv_bringup.testing import CHROMIUM, dev_requirement
from raspv_bringup.testing import CHROMIUM_ARGS as ARGS

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not os.path.exists(CHROMIUM),
                       reason=f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)"),
]
sync_api = dev_requirement("playwright.sync_api")


# A stand-in WebXR runtime: 'immersive-vr' is supported, and the session delivers frames every
# 10 ms whose viewer pose turns left about XR +y by 0.01 rad per frame.
FAKE_XR = """
(() => {
  let frameNo = 0, endHandler = null;
  window.XRWebGLLayer = class { constructor(session, gl) { this.framebuffer = null; }
    getViewport(v) { return v.eye === 'left' ? {x: 0, y: 0, width: 320, height: 360} : {x: 320, y: 0, width: 320, height: 360}; } };
  const session = {
    inputSources: [], renderState: {},
    updateRenderState(s) { Object.assign(this.renderState, s); },
    requestReferenceSpace: async () => ({}),
    requestAnimationFrame(cb) { setTimeout(() => { frameNo++; const a = 0.01 * frameNo;
      cb(performance.now(), { getViewerPose: () => ({ transform: { orientation: {x: 0, y: Math.sin(a / 2), z: 0, w: Math.cos(a / 2)} },
                                                    views: [{eye: 'left'}, {eye: 'right'}] }) }); }, 10); return frameNo; },
    addEventListener(type, fn) { if (type === 'end') endHandler = fn; },
    end() { if (endHandler) endHandler(); },
  };
  window.__xrFrames = () => frameNo;
  Object.defineProperty(navigator, 'xr', { configurable: true, value: {
    isSessionSupported: async (mode) => mode === 'immersive-vr', requestSession: async () => session } });
})();
"""


@pytest.fixture(scope="module")
def browser_context():
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        context = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                       viewport={"width": 960, "height": 540})
        try:
            yield context
        finally:
            context.close()


@pytest.fixture
def page(browser_context):
    pg = browser_context.new_page()
    yield pg
    pg.close()


@pytest.fixture
def streaming_server(start_server):
    stop = threading.Event()
    servers = []

    def start(green_rgb=False, **config):
        server = start_server(**config)
        pattern = PhospheneTestPattern(640, 480, count=600)
        frames = [pattern.frame(i / 30) for i in range(30)]
        if green_rgb:                     # the spv node's headset output: rgb8, green channel only
            frames = [np.stack([np.zeros_like(f), f, np.zeros_like(f)], axis=2) for f in frames]

        def feed():
            i = 0
            while not stop.is_set():
                server.submit_frame(frames[i % len(frames)], time.time())
                i += 1
                stop.wait(1 / 30)
        threading.Thread(target=feed, daemon=True).start()
        servers.append(server)
        return server

    yield start
    stop.set()


def client_state(page):
    return page.evaluate("() => ({...window.raspvClient})")


def wait_shown(page, count=5, timeout=30_000):
    page.wait_for_function(f"() => window.raspvClient.framesShown >= {count}", timeout=timeout)


def canvas_pixels(page):
    """The page as an RGB array (what the user sees)."""
    png = page.screenshot()
    return cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def test_page_shows_phosphenes_and_sends_body_and_head_motion(page, streaming_server, recorder, tmp_path):
    server = streaming_server()
    page.goto(f"http://127.0.0.1:{server.port}/")
    wait_shown(page)
    page.wait_for_function("() => window.raspvClient.rttMs !== null", timeout=10_000)
    state = client_state(page)
    # the page asks for the levels stream (it can draw it); a server without sprites sends images
    assert state["role"] == "control" and state["format"] == "levels" and state["drawsLevels"]
    assert state["size"] == "640×480"
    # the status line is rewritten at most 4×/s (raspv_hmd/client/client.js): wait for the one
    # written after the first round trip
    page.wait_for_function("() => document.getElementById('status').innerText.includes('RTT')", timeout=10_000)
    status = page.inner_text("#status")
    assert "controlling" in status and "fps" in status and "RTT" in status
    shot = tmp_path / "client.png"
    page.screenshot(path=str(shot))
    pixels = canvas_pixels(page)
    assert (pixels.max(axis=2) > 60).mean() > 0.01                   # phosphenes, not a black page

    page.keyboard.down("ArrowUp")
    recorder.wait(lambda r: any(v > 0 for v, _ in r.twists))
    page.keyboard.down("ArrowLeft")
    recorder.wait(lambda r: any(v > 0 and w > 0 for v, w in r.twists))
    page.keyboard.up("ArrowUp")
    page.keyboard.up("ArrowLeft")
    recorder.wait(lambda r: r.twists[-1] == (0.0, 0.0))             # releasing the keys stops at once
    assert max(v for v, _ in recorder.twists) == pytest.approx(0.5)

    box = page.locator("#view").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 120, y + 40, steps=6)                         # drag right and down
    page.mouse.up()
    recorder.wait(lambda r: len(r.heads) >= 3)
    roll, pitch, yaw = P.quaternion_to_rpy(recorder.heads[-1][0])
    assert yaw == pytest.approx(-math.radians(0.25 * 120), abs=1e-3)  # looks right
    assert pitch == pytest.approx(math.radians(0.25 * 40), abs=1e-3)  # and down
    page.keyboard.press("r")                                           # look ahead again
    recorder.wait(lambda r: P.quaternion_to_rpy(r.heads[-1][0]) == pytest.approx((0, 0, 0), abs=1e-9))

    page.keyboard.press("+")
    page.keyboard.press("3")
    recorder.wait(lambda r: [k for _, k in r.keys] == ["+", "3"])
    server.notify("spv num_phosphenes 1000 → 1100")
    page.wait_for_function("() => window.raspvClient.lastStatus.includes('1100')")
    stats = server.stats().clients[0]
    assert stats.frames_sent >= 5 and stats.ack_rtt_ms is not None and stats.refused == {}


@pytest.mark.parametrize("fmt", ["raw", "png"])
def test_stereo_side_by_side_and_green_only(page, streaming_server, fmt):
    server = streaming_server()
    page.goto(f"http://127.0.0.1:{server.port}/?format={fmt}&overlay=0")
    wait_shown(page)
    assert client_state(page)["format"] == fmt
    page.keyboard.press("x")
    page.keyboard.press("g")
    shown = client_state(page)["framesShown"]
    wait_shown(page, shown + 3)
    rgb = canvas_pixels(page).astype(int)
    lit = rgb.max(axis=2) > 60
    assert lit.mean() > 0.005
    assert rgb[..., 0][lit].max() < 20 and rgb[..., 2][lit].max() < 20   # green channel only
    w = rgb.shape[1]
    left, right = rgb[:, : w // 2], rgb[:, w // 2:]
    assert (left.max(axis=2) > 60).mean() > 0.005
    assert np.abs(left - right).mean() < 1.0                              # the same image for each eye


@pytest.mark.parametrize("fmt", ["raw", "png"])
def test_green_rgb_frames_arrive_as_one_channel_and_show_green(page, streaming_server, fmt):
    server = streaming_server(green_rgb=True)
    page.goto(f"http://127.0.0.1:{server.port}/?format={fmt}&overlay=0")
    wait_shown(page, 5)
    rgb = canvas_pixels(page).astype(int)
    lit = rgb.max(axis=2) > 60
    assert lit.mean() > 0.005 and rgb[..., 0][lit].max() < 20 and rgb[..., 2][lit].max() < 20
    assert server.stats().clients[0].format == fmt


def test_watcher_page_gets_frames_but_does_not_control(browser_context, streaming_server, recorder):
    server = streaming_server()
    controller = browser_context.new_page()
    watcher = browser_context.new_page()
    try:
        controller.goto(f"http://127.0.0.1:{server.port}/")
        wait_shown(controller)
        watcher.goto(f"http://127.0.0.1:{server.port}/?role=watch")
        wait_shown(watcher)
        assert "watching" in watcher.inner_text("#state")
        watcher.keyboard.down("ArrowUp")
        watcher.keyboard.press("+")
        watcher.wait_for_function("() => window.raspvClient.lastStatus.includes('watching')")
        watcher.keyboard.up("ArrowUp")
        assert recorder.twists == [] and recorder.keys == []
        controller.close()                                        # the watcher asked to watch: nobody controls
        watcher.keyboard.press("c")                               # … until it asks for control
        watcher.wait_for_function("() => window.raspvClient.role === 'control'")
    finally:
        watcher.close()


def test_webxr_session_sends_the_pose_every_frame(page, streaming_server, recorder):
    server = streaming_server()
    page.add_init_script(FAKE_XR)
    page.goto(f"http://127.0.0.1:{server.port}/")
    wait_shown(page)
    page.wait_for_selector("#vr:not([hidden])")
    page.click("#vr")
    page.wait_for_function("() => window.raspvClient.xr && window.__xrFrames() > 30")
    shown = client_state(page)["framesShown"]
    wait_shown(page, shown + 3)                                   # frames keep coming in the session
    recorder.wait(lambda r: len(r.heads) >= 30)
    heads = list(recorder.heads)
    yaws = [P.quaternion_to_rpy(q)[2] for q, _, _ in heads]
    # XR frame k has yaw 0.01·k (turning left): exactly one pose per XR frame, in order, none missing
    assert yaws == pytest.approx([0.01 * (k + 1) for k in range(len(yaws))], abs=1e-6)
    assert all(abs(P.quaternion_to_rpy(q)[1]) < 1e-9 for q, _, _ in heads)


def test_phone_orientation_turns_the_head(page, streaming_server, recorder):
    server = streaming_server()
    page.goto(f"http://127.0.0.1:{server.port}/?orientation=1")
    wait_shown(page)

    def orient(alpha, beta, gamma):
        page.evaluate(f"() => window.dispatchEvent(new DeviceOrientationEvent('deviceorientation', "
                      f"{{alpha: {alpha}, beta: {beta}, gamma: {gamma}}}))")

    orient(0, 90, 0)                      # upright, looking at the horizon: straight ahead
    recorder.wait(lambda r: len(r.heads) == 1)
    assert P.quaternion_to_rpy(recorder.heads[0][0]) == pytest.approx((0, 0, 0), abs=1e-6)
    orient(30, 90, 0)                     # turned 30° to the left about the vertical
    recorder.wait(lambda r: len(r.heads) == 2)
    assert P.quaternion_to_rpy(recorder.heads[1][0]) == pytest.approx((0, 0, math.radians(30)), abs=1e-6)
    orient(30, 70, 0)                     # and tilted 20° down
    recorder.wait(lambda r: len(r.heads) == 3)
    assert P.quaternion_to_rpy(recorder.heads[2][0]) == pytest.approx((0, math.radians(20), math.radians(30)),
                                                                      abs=1e-6)
