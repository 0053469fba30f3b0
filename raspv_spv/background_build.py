"""Build expensive objects off the caller's thread, newest request wins (no ROS).

A node that must keep running at its rate while a setting that takes seconds to build is
applied (new sprites, a new temporal table) submits the build here and keeps using the old
object until the new one is ready; :class:`BackgroundBuilder` calls ``on_ready`` from its
worker thread with the result, and the caller swaps it in under its own lock.

One worker thread, started on demand, at a lower CPU priority than the rest of the process
(Linux per-thread nice) so a display loop sharing the machine keeps its deadlines. Requests
submitted while a build runs replace each other: only the newest pending one is built next,
and a finished build that a newer request already made obsolete is dropped, never delivered.
"""
from __future__ import annotations

import threading
from typing import Any, Callable, Generic, TypeVar

from raspv_common.thread_priority import lower_thread_priority

T = TypeVar("T")

BUILD_NICENESS = 10


class BackgroundBuilder(Generic[T]):
    """``build(request) -> T`` in a worker thread; ``on_ready(request, result)`` or
    ``on_error(request, exception)`` when done, unless a newer request came in meanwhile."""

    def __init__(self, build: Callable[[Any], T], on_ready: Callable[[Any, T], None],
                 on_error: Callable[[Any, Exception], None], name: str = "builder") -> None:
        self._build = build
        self._on_ready = on_ready
        self._on_error = on_error
        self._name = name
        self._lock = threading.Condition()
        self._pending: tuple[int, Any] | None = None
        self._generation = 0
        self._running = False
        self._closed = False
        self._thread: threading.Thread | None = None

    def submit(self, request: Any) -> int:
        """Queue ``request`` (replacing any request not started yet); returns its generation."""
        with self._lock:
            if self._closed:
                raise RuntimeError("builder is closed")
            self._generation += 1
            self._pending = (self._generation, request)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._work, name=self._name, daemon=True)
                self._thread.start()
            self._lock.notify_all()
            return self._generation

    @property
    def busy(self) -> bool:
        """A build is running or waiting."""
        with self._lock:
            return self._running or self._pending is not None

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until nothing is running or waiting; False on timeout."""
        with self._lock:
            return self._lock.wait_for(lambda: not self._running and self._pending is None, timeout)

    def close(self, timeout: float = 5.0) -> None:
        """Stop after the build in progress (pending requests are dropped)."""
        with self._lock:
            self._closed = True
            self._pending = None
            self._lock.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _work(self) -> None:
        lower_thread_priority(BUILD_NICENESS)       # not Linux, or not allowed: as it was
        while True:
            with self._lock:
                if self._closed or self._pending is None:
                    self._running = False
                    self._lock.notify_all()
                    return
                generation, request = self._pending
                self._pending = None
                self._running = True
            try:
                result, error = self._build(request), None
            except Exception as exc:               # reported to the caller, the worker goes on
                result, error = None, exc
            with self._lock:
                current = generation == self._generation and not self._closed
            if current:
                if error is None:
                    self._on_ready(request, result)
                else:
                    self._on_error(request, error)
