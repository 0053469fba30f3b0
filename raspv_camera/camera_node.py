"""`camera` node: a real RGB-D camera (RealSense, OpenNI2, DepthAI) or its SDK's recording as the
graph's source.

Publishes the standard source topics — colour ``rgb8``, depth registered to colour (``32FC1``
metres or ``16UC1`` millimetres), ``camera_info`` for both — stamped with the sensor's own
timestamps mapped to ROS time, and ``/camera/imu`` (``sensor_msgs/Imu``, accelerometer and
gyroscope in the colour optical frame, orientation unknown) when the device has an IMU, and its
mounting on ``/tf_static`` (``base_link → camera_link → frame_id``, :mod:`raspv_common.frames`). The
camera itself is run by :class:`~raspv_camera.camera_runner.CameraRunner` in a thread:
unplugged or missing devices are reported and retried, recordings are paced and looped.
"""
from __future__ import annotations

import threading

import numpy as np
from sensor_msgs.msg import CameraInfo, Image, Imu

from raspv_camera.camera_driver import CameraSettings
from raspv_camera.camera_params import PARAMS
from raspv_camera.camera_runner import CameraRunner, RunnerOptions
from raspv_camera.drivers import driver_for_file, list_all_devices, make_driver
from raspv_camera.rgbd_frame import CameraError, ImuSample, NoDevice, RgbdFrame
from raspv_camera.sdk_imports import SDKS
from raspv_common import frames, topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, seconds_to_stamp
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import IMU_QOS, SENSOR_QOS
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_common.tf_messages import StaticTfBroadcaster


def depth_for_encoding(frame: RgbdFrame, encoding: str) -> np.ndarray:
    """The frame's depth as the array a ``32FC1`` (metres, NaN holes) or ``16UC1`` (mm, 0 holes)
    image carries."""
    if encoding == "32FC1":
        return frame.depth_metres()
    if abs(frame.depth_units - 0.001) < 1e-9:
        return frame.depth
    mm = np.rint(frame.depth.astype(np.float32) * np.float32(frame.depth_units * 1000.0))
    return np.clip(mm, 0, 65535).astype(np.uint16)


def choose_driver(driver: str, file: str) -> str | None:
    """The driver named, or the one a recording needs (None: decide per connection attempt)."""
    if driver != "auto":
        return driver
    if file:
        found = driver_for_file(file)
        if found is None:
            raise ConfigurationError(f"file {file!r}: cannot tell which SDK recorded it (.db3/.bag RealSense, "
                                     f".oni OpenNI2, a directory of .mcap DepthAI); set 'driver'")
        return found
    return None


class CameraNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("camera", PARAMS)
        p = self.params
        self.driver_name = choose_driver(p["driver"], p["file"])
        self.settings = CameraSettings(device=p["device"], file=p["file"], width=p["width"], height=p["height"],
                                       fps=p["fps"], imu=p["imu"], search_timeout=p["search_timeout"])
        if self.driver_name is not None:
            try:
                SDKS[self.driver_name]()          # load the SDK now: a missing one is one line, not a retry loop
            except CameraError as exc:
                raise ConfigurationError(str(exc)) from None
        try:
            options = RunnerOptions(rate=p["rate"], at_end=p["at_end"], retry_period=p["retry_period"],
                                    give_up_after=p["give_up_after"], frame_timeout=p["frame_timeout"])
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.pub_color = self.create_publisher(Image, topics.COLOR, SENSOR_QOS)
        self.pub_depth = self.create_publisher(Image, topics.DEPTH, SENSOR_QOS)
        self.pub_info = self.create_publisher(CameraInfo, topics.CAMERA_INFO, SENSOR_QOS)
        self.pub_depth_info = self.create_publisher(CameraInfo, topics.DEPTH_INFO, SENSOR_QOS)
        self.pub_imu = self.create_publisher(Imu, topics.IMU, IMU_QOS) if p["imu"] else None
        if len(p["mounting_xyz"]) != 3 or len(p["mounting_rpy"]) != 3:
            raise ConfigurationError(f"mounting_xyz and mounting_rpy take three numbers each, got "
                                     f"{p['mounting_xyz']} and {p['mounting_rpy']}")
        StaticTfBroadcaster(self).send(frames.camera_mounting_edges(
            p["frame_id"], frames.mounting_transform(p["mounting_xyz"], p["mounting_rpy"])))
        self.runner = CameraRunner(self._make_driver, bool(p["file"]), options, self._publish_frame,
                                   self._publish_imu if p["imu"] else None, self._log, on_state=self.announce_source)
        self._info_cache: tuple | None = None
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    # -- camera thread -------------------------------------------------------------------------
    def _make_driver(self):
        if self.driver_name is not None:
            return make_driver(self.driver_name, self.settings)
        for found in list_all_devices():
            if found.devices:
                return make_driver(found.sdk, self.settings)
        raise NoDevice("no camera connected (searched: RealSense, OpenNI2, DepthAI)")

    def _run(self) -> None:
        try:
            outcome = self.runner.run()
        except SHUTDOWN_ERRORS as exc:    # Ctrl-C or SIGTERM shut the context down while a frame was published
            outcome = "stopped"
            if not during_shutdown(exc, self.context):
                self.get_logger().fatal(f"camera thread failed: {exc!r}")
                outcome = "failed"
        except Exception as exc:          # a bug must not leave a node that publishes nothing
            self.get_logger().fatal(f"camera thread failed: {exc!r}")
            outcome = "failed"
        if outcome == "failed":
            self.exit_code = 1
        if outcome in ("gave up", "no sdk"):
            self.exit_code = 1
        if outcome != "stopped":
            if outcome == "end":
                self.get_logger().info("end of the recording (at_end: exit)")
            self.context.try_shutdown()

    def _log(self, level: str, message: str) -> None:
        logger = self.get_logger()      # rclpy wants one severity per call site
        if level == "error":
            logger.error(message)
        elif level == "warning":
            logger.warning(message)
        else:
            logger.info(message)

    def _camera_info(self, frame: RgbdFrame, header) -> CameraInfo:
        key = (frame.intrinsics, frame.distortion, self.params["frame_id"])
        if self._info_cache is None or self._info_cache[0] != key:
            self._info_cache = (key, intrinsics_to_camera_info(frame.intrinsics, distortion=frame.distortion))
        info = self._info_cache[1]
        info.header = header
        return info

    def _publish_frame(self, frame: RgbdFrame, stamp: float) -> None:
        enc = self.params["depth_encoding"]
        msg_color = array_to_image(frame.color, "rgb8")
        msg_color.header.stamp = seconds_to_stamp(stamp)
        msg_color.header.frame_id = self.params["frame_id"]
        header = msg_color.header
        msg_depth = array_to_image(depth_for_encoding(frame, enc), enc, header)
        info = self._camera_info(frame, header)
        self.pub_color.publish(msg_color)
        self.pub_depth.publish(msg_depth)
        self.pub_info.publish(info)
        self.pub_depth_info.publish(info)

    def _publish_imu(self, sample: ImuSample, stamp: float) -> None:
        msg = Imu()
        msg.header.stamp = seconds_to_stamp(stamp)
        msg.header.frame_id = self.params["frame_id"]
        msg.orientation_covariance[0] = -1.0             # REP 145: no orientation estimate
        a = sample.accel
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = (float(v) for v in a)
        if sample.gyro is not None:
            g = sample.gyro
            msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = (float(v) for v in g)
        else:
            msg.angular_velocity_covariance[0] = -1.0
        self.pub_imu.publish(msg)

    # -- parameters and shutdown ---------------------------------------------------------------
    def on_parameters(self, changes):
        if "rate" in changes:
            self.runner.set_rate(changes["rate"])
        return None

    def close(self) -> None:
        self.runner.stop()
        self._thread.join(timeout=5.0)


def main(argv=None) -> None:
    run_node(CameraNode, argv, priority="source")


if __name__ == "__main__":
    main()
