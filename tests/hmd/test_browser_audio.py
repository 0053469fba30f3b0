"""Spatial audio cues in a real browser: Debian's chromium (Playwright) runs the client's WebAudio
graph; the test reads the graph the page exposes (AudioParam values of the real PannerNodes and
gains, the context state, the RMS of the output through an AnalyserNode) — nothing is mocked.

Chromium starts with ``--autoplay-policy=no-user-gesture-required`` (a user would press 'm' or
the Audio button, which is a gesture)."""
from __future__ import annotations

import math
import os
import tempfile
import threading

import pytest

from raspv_hmd import protocol as P
from raspv_bringup.testing import CHROMIUM, CHROMIUM_ARGS, dev_requirement

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not os.path.exists(CHROMIUM),
                       reason=f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)"),
]
sync_api = dev_requirement("playwright.sync_api")

ARGS = [*CHROMIUM_ARGS, "--autoplay-policy=no-user-gesture-required"]

CUES = {"frame": "base", "has_path": True, "goal_reached": False, "feasible": True, "proximity_range": 1.5,
        "waypoint": {"position": [2.0, -2.0, 0.0]},                      # ahead and to the right
        "obstacle": {"position": [1.0, 0.0, 0.0], "distance": 1.0},       # straight ahead, 1 m
        "stairs": {"position": [3.0, 1.0, -1.6], "distance": 3.0, "direction": "up"}}


def wa(p):
    """Protocol frame (x forward, y left, z up) → WebAudio (x right, y up, z back)."""
    return [-p[1], p[2], -p[0]]


@pytest.fixture(scope="module")
def browser_context():
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        context = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                       viewport={"width": 800, "height": 500})
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
def cue_server(start_server):
    """A headset server sending ``cues`` every 100 ms (as the bridge's relay does)."""
    stop = threading.Event()
    server = start_server()
    current = {"cues": dict(CUES)}

    def feed():
        while not stop.is_set():
            server.broadcast("cues", **current["cues"])
            stop.wait(0.1)
    threading.Thread(target=feed, daemon=True).start()
    yield server, current
    stop.set()


def graph(page):
    return page.evaluate("() => window.raspvAudio.graph()")


def wait_graph(page, condition: str, timeout=20_000):
    page.wait_for_function(f"() => {{ const g = window.raspvAudio.graph(); return {condition}; }}", timeout=timeout)


def test_cues_place_hrtf_panners_and_sound(page, cue_server):
    server, _ = cue_server
    page.goto(f"http://127.0.0.1:{server.port}/?audio=1&overlay=0")
    wait_graph(page, "g.state === 'running' && g.messages > 2")
    g = graph(page)
    assert g["enabled"] and g["frame"] == "base"
    for kind in ("waypoint", "obstacle", "stairs"):
        c = g["cues"][kind]
        assert c["active"] and c["on"] and c["switchGain"] == 1 and c["panningModel"] == "HRTF"
        assert c["position"] == pytest.approx(wa(CUES[kind]["position"]), abs=1e-6)
    assert g["cues"]["waypoint"]["type"] == "sine" and g["cues"]["obstacle"]["type"] == "triangle"
    assert g["cues"]["stairs"]["type"] == "square" and g["cues"]["stairs"]["direction"] == "up"
    assert g["cues"]["obstacle"]["period"] == pytest.approx(0.1 + 0.7 * 1.0 / 1.5, abs=1e-6)
    # the blips really play: the envelopes open and the output carries signal
    wait_graph(page, "g.cues.waypoint.envelope > 0.05")
    wait_graph(page, "g.level > 0.01")
    # listener straight ahead: WebAudio forward −z, up +y
    assert g["listener"]["forward"] == pytest.approx([0, 0, -1], abs=1e-6)
    assert g["listener"]["up"] == pytest.approx([0, 1, 0], abs=1e-6)


def test_turning_the_head_turns_the_listener_at_once(page, cue_server, recorder):
    server, _ = cue_server
    page.goto(f"http://127.0.0.1:{server.port}/?audio=1&overlay=0")
    wait_graph(page, "g.state === 'running' && g.messages > 0")
    page.wait_for_function("() => window.raspvClient.role === 'control'")
    box = page.locator("#view").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x - 120, y, steps=6)                     # drag left: look 30° to the left
    page.mouse.up()
    recorder.wait(lambda r: len(r.heads) >= 1)
    yaw = P.quaternion_to_rpy(recorder.heads[-1][0])[2]
    assert yaw == pytest.approx(math.radians(30), abs=1e-3)
    # head x axis (forward) rotated 30° left = (cos, sin, 0) in the base frame → WebAudio (−sin, 0, −cos)
    wait_graph(page, f"Math.abs(g.listener.forward[0] + {math.sin(math.radians(30))}) < 1e-3")
    forward = graph(page)["listener"]["forward"]
    assert forward == pytest.approx([-math.sin(math.radians(30)), 0, -math.cos(math.radians(30))], abs=1e-3)


def test_each_cue_and_all_audio_switch_off_and_on(page, cue_server):
    server, current = cue_server
    page.goto(f"http://127.0.0.1:{server.port}/?audio=1&cues=waypoint,stairs")
    wait_graph(page, "g.state === 'running' && g.messages > 0")
    g = graph(page)
    assert g["cues"]["obstacle"]["switchGain"] == 0 and not g["cues"]["obstacle"]["on"]   # not chosen in the URL
    page.locator("#view").focus()
    page.keyboard.press("b")
    wait_graph(page, "g.cues.waypoint.switchGain === 0")
    page.keyboard.press("p")
    wait_graph(page, "g.cues.obstacle.switchGain === 1")
    page.keyboard.press("t")
    wait_graph(page, "g.cues.stairs.switchGain === 0")
    page.keyboard.press("m")                                  # everything off
    wait_graph(page, "!g.enabled && g.master === 0")
    assert page.get_attribute("#audio", "aria-pressed") == "false"
    page.click("#audio")                                      # and on again with the button
    wait_graph(page, "g.enabled && g.master > 0.5")
    # no admissible velocity (DWA says stop): the beacon turns into a low double beep
    page.keyboard.press("b")
    current["cues"] = {**CUES, "feasible": False}
    wait_graph(page, "g.cues.waypoint.stop && g.cues.waypoint.period === 0.5")
    wait_graph(page, "g.cues.waypoint.frequency === 220 && g.cues.waypoint.envelope > 0.05")
    # a staircase going down sounds differently (falling notes); a cue that disappears falls silent
    current["cues"] = {**CUES, "stairs": {**CUES["stairs"], "direction": "down"}, "waypoint": None}
    wait_graph(page, "g.cues.stairs.direction === 'down' && !g.cues.waypoint.active")
