"""Experiment instructions in the browser client (Debian's chromium, Playwright): shown with a Start
button, Enter starts, Esc aborts the running trial; late clients get them too."""
from __future__ import annotations

import os
import tempfile
import threading

import pytest

from raspv_hmd import protocol as P
from raspv_hmd.server import Callbacks, HeadsetServer, ServerConfig
from raspv_bringup.testing import CHROMIUM, dev_requirement
from raspv_bringup.testing import CHROMIUM_ARGS as ARGS

pytestmark = [pytest.mark.browser,
              pytest.mark.skipif(not os.path.exists(CHROMIUM), reason=f"{CHROMIUM} is not installed")]
sync_api = dev_requirement("playwright.sync_api")


def test_protocol_messages():
    assert P.parse_client_message('{"type": "experiment", "action": "start", "id": "S01-3-1"}') == \
        P.Experiment("start", "S01-3-1")
    with pytest.raises(P.ProtocolError, match="'action' must be one of start, abort"):
        P.parse_client_message('{"type": "experiment", "action": "finish"}')


def test_instructions_start_and_abort_in_the_browser():
    got: list[tuple[int, str, str]] = []
    cond = threading.Condition()

    def on_experiment(client, action, ident):
        with cond:
            got.append((client, action, ident))
            cond.notify_all()

    def wait(n):
        with cond:
            assert cond.wait_for(lambda: len(got) >= n, timeout=15), got

    server = HeadsetServer(ServerConfig(host="127.0.0.1", port=0, tcp_port=None),
                           Callbacks(on_experiment=on_experiment)).start()
    try:
        server.show_instructions({"id": "S01-1-1", "title": "Trial 1 of 6", "text": "Walk to the far end.",
                                  "waiting": True})
        with sync_api.sync_playwright() as p, tempfile.TemporaryDirectory(prefix="raspv-chromium-") as profile:
            ctx = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=ARGS, headless=True)
            try:
                page = ctx.new_page()
                page.goto(f"http://127.0.0.1:{server.port}/")
                page.wait_for_function("window.raspvClient && window.raspvClient.role === 'control'", timeout=15_000)
                page.wait_for_selector("#instructions:not([hidden])", timeout=10_000)   # shown to a late client
                assert page.inner_text("#instructions-text") == "Walk to the far end."
                assert page.is_visible("#instructions-start")
                page.keyboard.press("Enter")
                wait(1)
                assert got[0][1:] == ("start", "S01-1-1")
                server.show_instructions({"id": "S01-1-1", "title": "", "text": "", "waiting": False})
                page.wait_for_selector("#instructions", state="hidden", timeout=10_000)
                page.keyboard.press("Escape")
                wait(2)
                assert got[1][1:] == ("abort", "S01-1-1")
                server.show_instructions({"id": "S01-2-1", "title": "Trial 2", "text": "Again.", "waiting": True})
                page.wait_for_selector("#instructions-start:not([hidden])", timeout=10_000)
                page.click("#instructions-start")                                  # the button works like Enter
                wait(3)
                assert got[2][1:] == ("start", "S01-2-1")
            finally:
                ctx.close()
    finally:
        server.stop()
