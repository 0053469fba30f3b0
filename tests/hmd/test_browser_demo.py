"""The issue's acceptance check in one test: sim → spv → bridge, the page opened in chromium shows
phosphenes, arrow keys move the avatar, dragging turns its head, and the view changes."""
from __future__ import annotations

import math
import os
import tempfile
import time

import cv2
import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry

from raspv_common import topics
from raspv_common.conversions import pose_to_matrix
from raspv_bringup.testing import CHROMIUM, dev_requirement
from raspv_bringup.testing import CHROMIUM_ARGS as ARGS

pytestmark = [
    pytest.mark.integration, pytest.mark.browser, pytest.mark.slow,
    pytest.mark.skipif(not os.path.exists(CHROMIUM),
                       reason=f"{CHROMIUM} is not installed (Debian: apt-get install -y chromium)"),
]
sync_api = dev_requirement("playwright.sync_api")



def view(page) -> np.ndarray:
    png = page.screenshot()
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE).astype(np.float32)


def test_walk_and_look_around_from_the_browser(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "spv"}, {"kind": "bridge"}]},
               "sim": {"ros__parameters": {"world": "apartment"}},
               "spv": {"ros__parameters": {"device": "optimist", "mode": "depth", "max_depth": 4.0, "width": 400}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}})
    url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=60).group(1)
    odom = probe.subscribe(topics.ODOM, Odometry)
    poses = probe.subscribe(topics.CAMERA_POSE, PoseStamped)
    start = odom.wait(1, timeout=60)[0].pose.pose.position
    with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
        context = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True,
                                                       viewport={"width": 800, "height": 500})
        try:
            page = context.new_page()
            page.goto(url + "?overlay=0")
            page.wait_for_function("() => window.raspvClient.framesShown > 10", timeout=90_000)
            # the first frames may be dark (spv renders before the simulator's first image reaches it
            # on a loaded machine), so wait for phosphenes to light up rather than take frame 10
            before = wait_for_view(page, lambda v: (v > 60).mean() > 0.01, timeout=60)
            assert (before > 60).mean() > 0.01                          # phosphenes on the page

            page.keyboard.down("ArrowUp")
            odom.wait(1, timeout=60, predicate=lambda m: math.dist(
                (m.pose.pose.position.x, m.pose.pose.position.y), (start.x, start.y)) > 0.3)
            page.keyboard.up("ArrowUp")

            poses.wait(1, timeout=30)
            yaw0 = head_yaw(poses.messages[-1])                           # the newest pose before the drag
            box = page.locator("#view").bounding_box()
            x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
            target = page.evaluate(f"() => document.elementFromPoint({x}, {y})?.id")
            drag(page, x, y)
            try:
                poses.wait(1, timeout=30, predicate=lambda m: abs(wrap(head_yaw(m) - yaw0) - math.radians(60)) < 0.2)
            except TimeoutError:
                state = page.evaluate("() => ({role: window.raspvClient.role, head: window.raspvClient.head, "
                                      "sent: window.raspvClient.headsSent})")
                state["element at the view's centre"] = target
                raise AssertionError(f"head yaw {math.degrees(wrap(head_yaw(poses.messages[-1]) - yaw0)):.1f} deg "
                                     f"from the drag's start; client {state}; bridge: {g.output[-1500:]}") from None
            page.wait_for_timeout(1000)                                   # let the phosphenes follow
            after = view(page)
            assert np.abs(after - before).mean() > 2.0                    # the view changed
        finally:
            context.close()


def drag(page, x: float, y: float) -> None:
    """Drag 240 px to the left from (x, y): 60° of head yaw at the client's 0.25°/px."""
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x - 240, y, steps=8)
    page.mouse.up()
    page.wait_for_timeout(100)


def wait_for_view(page, condition, timeout: float) -> np.ndarray:
    """Screenshots until `condition(view)` holds or `timeout` s pass; returns the last view."""
    deadline = time.monotonic() + timeout
    while True:
        v = view(page)
        if condition(v) or time.monotonic() > deadline:
            return v
        page.wait_for_timeout(200)


def head_yaw(msg: PoseStamped) -> float:
    """Heading of the camera's optical axis (z) in the world, rad."""
    z = pose_to_matrix(msg.pose)[:3, 2]
    return math.atan2(z[1], z[0])


def wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
