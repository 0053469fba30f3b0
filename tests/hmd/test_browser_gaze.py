"""Eye gaze in a real browser (Debian's chromium, Playwright): the mouse drives the gaze while
dragging still turns the head, the fixation-target calibration corrects a biased gaze, and in a
graph (spv gaze_mode locked + bridge) the page draws the field where the mouse looks."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from raspv_hmd import protocol as P
from raspv_spv.gaze import angle_between_deg, direction_from_angles, field_offset_px, shift_image

from .test_gaze_native_client import start_gaze_graph
from .test_browser_client import (browser_context, canvas_pixels, page, pytestmark, streaming_server,  # noqa: F401
                                  wait_shown)

FOCAL = 500.0


def move_to(page, yaw, pitch, dx=0.0, dy=0.0):
    x, y = page.evaluate(f"() => window.raspvGaze.clientPoint({yaw}, {pitch})")
    page.mouse.move(x + dx, y + dy)


def last_gaze_deg(recorder):
    d = recorder.gazes[-1][1]
    return math.degrees(math.atan2(d[1], d[0])), math.degrees(math.atan2(-d[2], math.hypot(d[0], d[1])))


@pytest.mark.slow
def test_mouse_gaze_head_drag_and_calibration(page, streaming_server, recorder):
    server = streaming_server()
    server.show_view(width=640, height=480, focal_px=FOCAL, spacing_px=20.0, fov_deg=65.2)
    page.goto(f"http://127.0.0.1:{server.port}/?gaze=mouse")
    wait_shown(page)
    page.wait_for_function("() => window.raspvClient.view && window.raspvClient.view.focal_px === 500")
    # the eye looks where the pointer is
    move_to(page, 8.0, -5.0)
    recorder.wait(lambda r: r.gazes and angle_between_deg(r.gazes[-1][1], direction_from_angles(8, -5)) < 0.3)
    assert recorder.gazes[-1][2] == pytest.approx(time.time(), abs=5.0)        # the page's clock in t
    # dragging turns the head and sends no gaze
    sent = len(recorder.gazes)
    box = page.locator("#view").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    recorder.wait(lambda r: len(r.gazes) > sent)
    sent = len(recorder.gazes)
    page.mouse.down()
    page.mouse.move(x + 80, y, steps=5)
    page.mouse.up()
    recorder.wait(lambda r: r.heads and P.quaternion_to_rpy(r.heads[-1][0])[2] < -math.radians(15))
    assert len(recorder.gazes) == sent
    # calibration: this "eye" lands 2° left and 1° up of every target (a tracker's bias)
    page.keyboard.press("k")
    page.wait_for_function("() => window.raspvGaze.calibrating")
    while page.evaluate("() => window.raspvGaze.calibrating"):
        target = page.evaluate("() => window.raspvGaze.target")
        if target:
            move_to(page, target[0] + 2.0, target[1] - 1.0)
        page.wait_for_timeout(30)
    cal = page.evaluate("() => window.raspvGaze.calibration")
    assert cal is not None and cal["points"] == 5 and cal["rmsDeg"] < 0.3
    move_to(page, 3.0 + 2.0, 2.0 - 1.0)               # looks at (3°, 2°) through the same biased "eye"
    recorder.wait(lambda r: angle_between_deg(r.gazes[-1][1], direction_from_angles(3, 2)) < 0.3, timeout=10)
    # gaze off: the eyes straight ahead again
    page.keyboard.press("e")
    recorder.wait(lambda r: angle_between_deg(r.gazes[-1][1], (1, 0, 0)) < 1e-6)


@pytest.mark.slow
def test_the_mouse_moves_the_field_in_a_graph(graph, probe, page):
    g, frames, the_map, _, _, _ = start_gaze_graph(graph, probe, tcp_port=-1)
    url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=60).group(1)
    page.goto(f"{url}?gaze=mouse&overlay=0")
    wait_shown(page)
    page.wait_for_function("() => window.raspvClient.view && window.raspvClient.drawer === 'cpu'")
    yaw, pitch = -6.0, 4.0                              # right and down
    move_to(page, yaw, pitch)
    expected = tuple(int(v) for v in np.round(field_offset_px(direction_from_angles(yaw, pitch), the_map.focal_px)))
    page.wait_for_function(f"() => window.raspvClient.fieldOffset[0] === {expected[0]} && "
                           f"window.raspvClient.fieldOffset[1] === {expected[1]}", timeout=30_000)
    # the field's centre is drawn where the pointer is, within one phosphene spacing
    pointer = np.array([the_map.width / 2 + expected[0], the_map.height / 2 + expected[1]])
    x, y = page.evaluate(f"() => window.raspvGaze.clientPoint({yaw}, {pitch})")
    box = page.evaluate(f"() => {{ const r = document.getElementById('view').getBoundingClientRect(); "
                        f"return [r.left, r.top, r.width, r.height]; }}")
    scale = min(box[2] / the_map.width, box[3] / the_map.height)
    at = np.array([(x - box[0] - (box[2] - the_map.width * scale) / 2) / scale,
                   (y - box[1] - (box[3] - the_map.height * scale) / 2) / scale])
    assert np.linalg.norm(at - pointer) < the_map.spacing_x_px
    # what the page shows is its levels image moved by the offset (the server's /spv/frame agrees)
    page.wait_for_function("() => { const s = window.raspvClient.readShown(); return s && s.pixels.some(v => v > 0); }")
    shown = page.evaluate("() => window.raspvClient.readShown()")
    drawn = page.evaluate("() => window.raspvClient.readImage()")
    w, h = shown["width"], shown["height"]
    img = np.array(drawn["pixels"], np.uint8).reshape(h, w)
    assert np.array_equal(np.array(shown["pixels"], np.uint8).reshape(h, w), shift_image(img, *expected))
    frames.wait(1, timeout=30, predicate=lambda f: (round(f.field_offset_x_px), round(f.field_offset_y_px)) == expected)


def _grey_view(page) -> np.ndarray:
    """The view canvas as the compositor shows it, in grey (a screenshot: WebGL's canvas is not
    readable after its frame)."""
    x, y, w, h = (int(round(v)) for v in page.evaluate(
        "() => { const r = document.getElementById('view').getBoundingClientRect(); "
        "return [r.left, r.top, r.width, r.height]; }"))
    return canvas_pixels(page)[y:y + h, x:x + w].max(axis=2).astype(float)


@pytest.mark.slow
def test_the_webgl_drawer_moves_the_field_with_the_gaze(graph, probe, page):
    """The WebGL drawer (as a headset's browser with a graphics processor draws; here SwiftShader)
    shifts the field by the same offset as the page's own drawer: what it shows after a gaze
    step is what it showed before, moved by the offset (scaled to the screen), within the
    resampling of a fractional shift."""
    g, _, the_map, _, _, _ = start_gaze_graph(graph, probe, tcp_port=-1)
    url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=60).group(1)
    page.goto(f"{url}?gaze=mouse&overlay=0&draw=webgl")
    wait_shown(page)
    page.wait_for_function("() => window.raspvClient.view && window.raspvClient.drawer === 'webgl'")

    def settle(offset):
        page.wait_for_function(f"() => window.raspvClient.fieldOffset[0] === {offset[0]} && "
                               f"window.raspvClient.fieldOffset[1] === {offset[1]}", timeout=30_000)
        n = page.evaluate("() => window.raspvClient.framesShown")
        page.wait_for_function(f"() => window.raspvClient.framesShown >= {n + 3}", timeout=30_000)
        return _grey_view(page)

    move_to(page, 0.0, 0.0)
    before = settle((0, 0))
    yaw, pitch = -6.0, 4.0
    move_to(page, yaw, pitch)
    expected = tuple(int(v) for v in np.round(field_offset_px(direction_from_angles(yaw, pitch), the_map.focal_px)))
    after = settle(expected)
    h, w = before.shape
    scale = min(w / the_map.width, h / the_map.height)          # levels-image px → screen px (fit, centred)
    x0, y0 = (w - the_map.width * scale) / 2, (h - the_map.height * scale) / 2
    dx, dy = int(round(expected[0] * scale)), int(round(expected[1] * scale))
    # the image's box, less the strip the shift moved in from outside it
    xs = slice(int(np.ceil(x0)) + max(dx, 0) + 1, int(x0 + the_map.width * scale) + min(dx, 0) - 1)
    ys = slice(int(np.ceil(y0)) + max(dy, 0) + 1, int(y0 + the_map.height * scale) + min(dy, 0) - 1)
    moved = np.roll(before, (dy, dx), axis=(0, 1))
    assert before[ys, xs].max() > 50                               # phosphenes lit in the compared region
    err_moved = np.abs(after[ys, xs] - moved[ys, xs]).mean()
    err_still = np.abs(after[ys, xs] - before[ys, xs]).mean()
    # shifted by the offset: within resampling (< 3 grey levels on average), far from unshifted
    assert err_moved < 3.0 and err_moved < err_still / 4, (err_moved, err_still, expected, scale)
