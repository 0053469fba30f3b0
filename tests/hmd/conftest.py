"""Fixtures of the headset tests: a running HeadsetServer on free ports with recording callbacks."""
from __future__ import annotations

import threading
import time
from typing import Any, Callable

import pytest

from raspv_hmd.server import Callbacks, HeadsetServer, ServerConfig


class Recorder:
    """Collects what the server hands to its owner (thread-safe) and waits for it."""

    def __init__(self) -> None:
        self.heads: list[tuple] = []
        self.gazes: list[tuple] = []          # (client id, direction or None, client time, arrival)
        self.twists: list[tuple[float, float]] = []
        self.keys: list[tuple[int, str]] = []
        self.params: list[tuple[int, str, Any]] = []
        self.events: list[str] = []
        self.presented: list[tuple[float, float | None]] = []   # (composited fps, refresh Hz) of the controller's page
        self._cond = threading.Condition()

    def _add(self, where: list, item: Any) -> None:
        with self._cond:
            where.append(item)
            self._cond.notify_all()

    def callbacks(self) -> Callbacks:
        return Callbacks(on_head_orientation=lambda q, t: self._add(self.heads, (q, t, time.time())),
                         on_cmd_vel=lambda v, w: self._add(self.twists, (v, w)),
                         on_gaze=lambda c, d, t, r: self._add(self.gazes, (c, d, t, r)),
                         on_key=lambda c, k: self._add(self.keys, (c, k)),
                         on_param=lambda c, n, v: self._add(self.params, (c, n, v)),
                         on_event=lambda text: self._add(self.events, text),
                         on_presented=lambda fps, hz: self._add(self.presented, (fps, hz)))

    def wait(self, predicate: Callable[["Recorder"], bool], timeout: float = 10.0) -> None:
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate(self):
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"condition not met within {timeout} s; events: {self.events[-5:]}")
                self._cond.wait(min(left, 0.1))


@pytest.fixture
def recorder() -> Recorder:
    return Recorder()


@pytest.fixture
def start_server(recorder):
    started: list[HeadsetServer] = []

    def start(**config: Any) -> HeadsetServer:
        config.setdefault("host", "127.0.0.1")
        config.setdefault("port", 0)
        config.setdefault("tcp_port", 0)
        server = HeadsetServer(ServerConfig(**config), recorder.callbacks()).start()
        started.append(server)
        return server

    yield start
    for s in started:
        s.stop()


def _wait_until(predicate: Callable[[], bool], timeout: float = 10.0, what: str = "condition") -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what} not reached within {timeout} s")
        time.sleep(0.01)


@pytest.fixture
def wait_until():
    """Poll a predicate until true (waiting for another thread, never timing anything)."""
    return _wait_until
