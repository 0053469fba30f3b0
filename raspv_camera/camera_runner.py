"""Running a camera driver: connect, stream, stamp, pace recordings, reconnect (no ROS).

:class:`CameraRunner` owns one driver at a time (made by a factory, so every reconnection gets a
fresh SDK object) and calls back with each frame and its host-time stamp:

- a live device is stamped with :class:`~raspv_camera.sensor_clock.SensorClock` (device time
  mapped to host time); a recording with :class:`~raspv_camera.sensor_clock.PlaybackClock`,
  waiting until each frame is due (``rate`` × real time);
- a device that cannot be opened, or stops delivering (an SDK error, or no frame for
  ``frame_timeout`` seconds), is reported once and retried every ``retry_period`` seconds
  until it is back ("camera back" is reported), or for ``give_up_after`` seconds if that is
  set (then :meth:`run` returns ``"gave up"`` and the node exits non-zero — a graph entry with
  ``restart: true`` starts it again);
- at the end of a recording: ``loop`` (play it again; the source announces ``paused`` while the
  SDK reopens it — hundreds of ms on a loaded machine — so consumers hold its last frame
  rather than call it stale), ``hold`` (publish nothing more) or ``exit``.

A missing SDK or system library is not retried: it cannot fix itself (``"no sdk"``).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

from raspv_camera.camera_driver import CameraDriver
from raspv_camera.rgbd_frame import (CameraError, DeviceLost, EndOfRecording, ImuSample, NoDevice, RgbdFrame,
                                     SdkMissing)
from raspv_camera.sensor_clock import PlaybackClock, SensorClock

AT_END = ("loop", "hold", "exit")


@dataclass
class RunnerOptions:
    rate: float = 1.0              # recordings: playback speed factor
    at_end: str = "loop"           # recordings: loop | hold | exit
    retry_period: float = 1.0      # seconds between attempts to (re)open [s]
    give_up_after: float = 0.0     # stop after this long without a device (0: never) [s]
    frame_timeout: float = 2.0     # an open device silent this long is lost [s]

    def __post_init__(self) -> None:
        if self.at_end not in AT_END:
            raise ValueError(f"at_end must be one of {', '.join(AT_END)}, got {self.at_end!r}")
        if not self.rate > 0 or not self.retry_period > 0 or not self.frame_timeout > 0 or self.give_up_after < 0:
            raise ValueError("rate, retry_period and frame_timeout must be positive, give_up_after >= 0")


FrameCallback = Callable[[RgbdFrame, float], None]
ImuCallback = Callable[[ImuSample, float], None]
LogCallback = Callable[[str, str], None]        # (level: info | warning | error, message)


class CameraRunner:
    """Drives one camera until :meth:`stop`; see the module docstring."""

    def __init__(self, make_driver: Callable[[], CameraDriver], is_file: bool, options: RunnerOptions,
                 on_frame: FrameCallback, on_imu: ImuCallback | None = None, log: LogCallback | None = None,
                 now: Callable[[], float] = time.time, on_state: Callable[[str], None] | None = None) -> None:
        self.make_driver = make_driver
        self.is_file = is_file
        self.options = options
        self.on_frame = on_frame
        self.on_imu = on_imu
        self.log = log or (lambda level, msg: None)
        self.on_state = on_state or (lambda state: None)   # "delivering" / "paused" / "down" (raspv_common.liveliness)
        self.now = now
        self.driver: CameraDriver | None = None
        self.frames = 0
        self.connections = 0
        self.losses = 0
        self.last_error = ""
        self._stop = threading.Event()
        self.sensor_clock = SensorClock()
        self.playback_clock = PlaybackClock(options.rate)

    def stop(self) -> None:
        self._stop.set()

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    def set_rate(self, rate: float) -> None:
        """Change the playback speed of a recording (from the next frame)."""
        self.options.rate = rate
        self.playback_clock = PlaybackClock(rate)

    # -----------------------------------------------------------------------------------------
    def run(self) -> str:
        """Stream until stopped. Returns why it ended: ``stopped``, ``end`` (a recording with
        ``at_end: exit``), ``gave up`` or ``no sdk``."""
        down_since: float | None = None
        try:
            while not self._stop.is_set():
                try:
                    self._connect()
                except SdkMissing as exc:
                    self.log("error", str(exc))
                    return "no sdk"
                except CameraError as exc:
                    if down_since is None:
                        down_since = time.monotonic()
                    self._report_down(str(exc))
                    if self.options.give_up_after and time.monotonic() - down_since >= self.options.give_up_after:
                        self.log("error", f"giving up after {self.options.give_up_after:g} s without the camera")
                        return "gave up"
                    self._stop.wait(self.options.retry_period)
                    continue
                if down_since is not None:
                    self.log("info", f"camera back: {self.driver.device.line().strip()}")
                down_since = None
                self.last_error = ""
                outcome = self._stream()
                if outcome == "end" and self.options.at_end == "loop":
                    self.on_state("paused")         # reopening the recording: a known pause, not a stale camera
                self._disconnect()
                if outcome == "end":
                    if self.options.at_end == "exit":
                        return "end"
                    if self.options.at_end == "hold":
                        self.on_state("down")
                        self.log("info", "end of the recording; holding (at_end: hold)")
                        self._stop.wait()
                        return "stopped"
                    self.playback_clock.reset()
                    continue                        # loop: open it again (still delivering: not a stop)
                if outcome == "lost":
                    down_since = time.monotonic()
                    self._stop.wait(self.options.retry_period)
            return "stopped"
        finally:
            self._disconnect()

    def _report_down(self, reason: str) -> None:
        self.on_state("down")
        if reason != self.last_error:
            self.log("error" if self.connections else "warning",
                     f"{reason}; retrying every {self.options.retry_period:g} s")
            self.last_error = reason

    def _connect(self) -> None:
        driver = self.make_driver()
        try:
            driver.open()
        except CameraError:
            driver.close()
            raise
        except Exception as exc:       # an SDK raising something unexpected is still a failed open
            driver.close()
            raise NoDevice(f"{driver.sdk}: {exc}") from None
        self.driver = driver
        self.on_state("delivering")
        self.connections += 1
        self.sensor_clock.reset()
        if self.connections == 1:
            imu = ", IMU" if driver.has_imu else ""
            self.log("info", f"streaming from {driver.device.line().strip()}{imu}")

    def _disconnect(self) -> None:
        if self.driver is not None:
            try:
                self.driver.close()
            except Exception:
                pass
            self.driver = None

    def _stream(self) -> str:
        """Read until stopped (``stopped``), the recording ends (``end``) or the device is lost
        (``lost``)."""
        driver = self.driver
        last_frame = time.monotonic()
        while not self._stop.is_set():
            try:
                frame = driver.read(min(0.5, self.options.frame_timeout))
            except EndOfRecording:
                return "end"
            except (DeviceLost, CameraError) as exc:
                return self._lost(str(exc))
            except Exception as exc:       # an SDK failure we do not know: the device is gone
                return self._lost(f"{driver.sdk}: {exc}")
            imu = driver.imu_samples()
            if frame is None:
                if time.monotonic() - last_frame > self.options.frame_timeout:
                    return self._lost(f"no frame from {driver.device.id} for {self.options.frame_timeout:g} s")
                continue
            last_frame = time.monotonic()
            stamp = self._stamp(frame)
            if stamp is None:
                return "stopped"
            if self.on_imu is not None:
                clock = self.playback_clock if self.is_file else self.sensor_clock
                for sample in imu:
                    t = clock.at(sample.sensor_time)
                    self.on_imu(sample, stamp if t is None else t)
            self.frames += 1
            self.on_frame(frame, stamp)
        return "stopped"

    def _lost(self, reason: str) -> str:
        self.on_state("down")
        self.losses += 1
        self.last_error = reason
        self.log("error", f"camera lost: {reason}; reconnecting every {self.options.retry_period:g} s")
        return "lost"

    def _stamp(self, frame: RgbdFrame) -> float | None:
        """Host time of ``frame``; for a recording, after waiting until it is due (None when
        stopped meanwhile)."""
        now = self.now()
        if not self.is_file:
            return self.sensor_clock.host_time(frame.sensor_time, now)
        due = self.playback_clock.due(frame.sensor_time, now)
        if due - now > 5.0:                 # a gap in the recording: do not stall for it
            self.playback_clock.reset()
            due = self.playback_clock.due(frame.sensor_time, now)
        if due > now and self._stop.wait(due - now):
            return None
        return due
