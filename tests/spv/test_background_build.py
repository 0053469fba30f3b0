"""BackgroundBuilder: builds off the caller's thread, the newest request wins, errors are
reported, and nothing is delivered after close."""
import threading

from raspv_spv.background_build import BackgroundBuilder


class Recorder:
    def __init__(self):
        self.built, self.ready, self.errors = [], [], []
        self.gate = threading.Event()
        self.started = threading.Event()

    def build(self, request):
        self.built.append(request)
        self.started.set()
        self.gate.wait(10)
        if request == "bad":
            raise ValueError("cannot build that")
        return f"sim-{request}"

    def on_ready(self, request, result):
        self.ready.append((request, result, threading.current_thread().name))

    def on_error(self, request, exc):
        self.errors.append((request, str(exc)))


def test_requests_made_while_building_collapse_to_the_newest():
    r = Recorder()
    b = BackgroundBuilder(r.build, r.on_ready, r.on_error, name="test-build")
    b.submit("a")
    assert r.started.wait(5)
    b.submit("b")                   # replaced by c before it starts
    b.submit("c")
    assert b.busy
    r.gate.set()
    assert b.wait_idle(10)
    assert r.built == ["a", "c"]
    assert r.ready == [("c", "sim-c", "test-build")]   # a finished after c was asked for: dropped
    assert not b.busy
    b.submit("d")
    assert b.wait_idle(10) and r.ready[-1][:2] == ("d", "sim-d")
    b.close()


def test_build_errors_are_reported_and_the_worker_goes_on():
    r = Recorder()
    r.gate.set()
    b = BackgroundBuilder(r.build, r.on_ready, r.on_error)
    b.submit("bad")
    assert b.wait_idle(10)
    assert r.errors == [("bad", "cannot build that")] and r.ready == []
    b.submit("ok")
    assert b.wait_idle(10) and r.ready[0][:2] == ("ok", "sim-ok")
    b.close()


def test_nothing_is_delivered_after_close():
    r = Recorder()
    b = BackgroundBuilder(r.build, r.on_ready, r.on_error)
    b.submit("a")
    assert r.started.wait(5)
    closer = threading.Thread(target=b.close)
    closer.start()
    r.gate.set()
    closer.join(10)
    assert r.ready == [] and not b.busy
