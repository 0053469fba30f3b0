"""CameraRunner: retries, loss, end of recordings, pacing — with a scripted driver for the
runner's own logic, and through a real SDK (RealSense playback) for a recording that vanishes
and comes back."""
import shutil
import threading
import time

import numpy as np

from raspv_camera.camera_driver import CameraDriver, CameraSettings
from raspv_camera.camera_runner import CameraRunner, RunnerOptions
from raspv_camera.realsense_driver import RealSenseDriver
from raspv_camera.rgbd_frame import DeviceInfo, DeviceLost, EndOfRecording, NoDevice, RgbdFrame, SdkMissing
from raspv_common.intrinsics import CameraIntrinsics

K = CameraIntrinsics(4, 3, 3.0, 3.0, 1.5, 1.0)


class ScriptedDriver(CameraDriver):
    """Plays a script: a number of frames, then an event (lost / end), one open per script entry."""
    sdk = "scripted"

    def __init__(self, script: list, file: bool = False):
        super().__init__(CameraSettings(file="x" if file else ""))
        self.script = script

    def open(self):
        step = self.script.pop(0)
        if isinstance(step, Exception):
            raise step
        self.frames, self.then = step
        self.n = 0
        self.device = DeviceInfo("scripted", "dev0", "scripted camera")
        return self.device

    def read(self, timeout_s):
        if self.n < self.frames:
            self.n += 1
            return RgbdFrame(np.zeros((3, 4, 3), np.uint8), np.ones((3, 4), np.uint16), 0.001, K, 10.0 + self.n / 30)
        if self.then == "lost":
            raise DeviceLost("USB error")
        if self.then == "end":
            raise EndOfRecording("end")
        time.sleep(timeout_s)
        return None

    def close(self):
        pass

    @classmethod
    def list_devices(cls):
        return []

    @classmethod
    def describe(cls, settings):
        return []


def run(script, file=False, **options):
    logs, frames = [], []
    drivers = iter([ScriptedDriver(script, file)] * 20)
    runner = CameraRunner(lambda: next(drivers), file, RunnerOptions(retry_period=0.01, frame_timeout=0.2, **options),
                          lambda f, t: frames.append((f, t)), log=lambda level, msg: logs.append((level, msg)))
    outcome = runner.run()
    return outcome, frames, logs, runner


def test_a_missing_device_is_reported_once_and_retried_until_it_comes():
    outcome, frames, logs, runner = run([NoDevice("no camera"), NoDevice("no camera"), (3, "end")], file=True,
                                        at_end="exit")
    assert outcome == "end" and len(frames) == 3
    assert [m for _, m in logs].count("no camera; retrying every 0.01 s") == 1
    assert any("camera back" in m for _, m in logs)


def test_a_lost_device_is_reported_and_reopened():
    script = [(2, "lost"), NoDevice("unplugged"), (2, "silent"), (1, "silent")]
    logs, frames = [], []
    drivers = iter([ScriptedDriver(script)] * 20)
    runner = CameraRunner(lambda: next(drivers), False, RunnerOptions(retry_period=0.01, frame_timeout=0.2),
                          lambda f, t: frames.append(t), log=lambda level, msg: logs.append((level, msg)))
    thread = threading.Thread(target=runner.run)
    thread.start()
    deadline = time.monotonic() + 20
    while len(frames) < 5 and time.monotonic() < deadline:     # 2, lost, 2, silent for frame_timeout, 1
        time.sleep(0.01)
    runner.stop()
    thread.join(10)
    messages = [m for _, m in logs]
    assert runner.losses >= 2 and len(frames) == 5
    assert any("camera lost: USB error" in m for m in messages)
    assert any("no frame from dev0 for 0.2 s" in m for m in messages)
    assert sum("camera back" in m for m in messages) >= 2


def test_give_up_and_missing_sdk_end_the_run():
    outcome, *_ = run([NoDevice("no camera")] * 10, give_up_after=0.03)
    assert outcome == "gave up"
    outcome, _, logs, _ = run([SdkMissing("pip install pyrealsense2")])
    assert outcome == "no sdk" and logs == [("error", "pip install pyrealsense2")]


def test_recordings_loop_and_are_paced_by_their_stamps():
    frames = []
    drivers = iter([ScriptedDriver([(3, "end"), (3, "end")], file=True)] * 5)
    runner = CameraRunner(lambda: next(drivers), True, RunnerOptions(at_end="loop", rate=2.0, retry_period=0.01),
                          lambda f, t: (frames.append(t), len(frames) == 6 and runner.stop()))
    t0 = time.time()
    runner.run()
    stamps = np.array(frames)
    assert len(stamps) == 6
    # within a pass the stamps are the recording's spacing (1/30 s) over the rate; each pass starts anew
    assert np.allclose(np.diff(stamps[:3]), 1 / 60) and np.allclose(np.diff(stamps[3:]), 1 / 60)
    assert stamps[0] >= t0 and stamps[3] >= stamps[2]


def test_a_recording_that_vanishes_is_retried_through_the_sdk_until_it_is_back(realsense_recording, tmp_path):
    """The real RealSense player: the file is moved away while it plays; at its end the runner
    reopens it, the SDK cannot, the runner reports it and retries; the file comes back and
    frames flow again."""
    path = tmp_path / "walk.db3"
    shutil.copy(realsense_recording.path, path)
    logs, stamps = [], []
    moved = threading.Event()

    def on_frame(frame, stamp):
        stamps.append(stamp)
        if not moved.is_set():
            path.rename(tmp_path / "away.db3")            # the recording vanishes mid-run
            moved.set()

    runner = CameraRunner(lambda: RealSenseDriver(CameraSettings(file=str(path))), True,
                          RunnerOptions(at_end="loop", retry_period=0.05, rate=4.0), on_frame,
                          log=lambda level, msg: logs.append((level, msg)))
    thread = threading.Thread(target=runner.run)
    thread.start()
    try:
        deadline = time.monotonic() + 60
        while not any("no such recording" in m for _, m in logs) and time.monotonic() < deadline:
            time.sleep(0.02)
        during = len(stamps)
        (tmp_path / "away.db3").rename(path)               # … and comes back
        while len(stamps) < during + 5 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        runner.stop()
        thread.join(20)
    messages = [m for _, m in logs]
    assert any(m.startswith(f"{path}: no such recording; retrying every 0.05 s") for m in messages), messages
    assert any("camera back" in m for m in messages) and len(stamps) >= during + 5
