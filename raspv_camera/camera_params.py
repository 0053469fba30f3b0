"""Parameters of the `camera` node (a real RGB-D camera, or its SDK's recording)."""
from raspv_common.params import Param

PARAMS = [
    Param("driver", "auto", "SDK: realsense, openni2, depthai; auto: from the file's suffix, else the first SDK "
          "with a connected device", choices=("auto", "realsense", "openni2", "depthai"), dynamic=False),
    Param("device", "", "serial number (RealSense), URI (OpenNI2; 'Dummy' is the library's synthetic device) or "
          "device id (DepthAI); empty: the first found", dynamic=False),
    Param("file", "", "play this recording instead of a device: RealSense .db3/.bag, OpenNI2 .oni, DepthAI "
          "directory of .mcap files", dynamic=False, file_kind="camera_recording"),
    Param("width", 640, "colour (and registered depth) width asked of a live device", minimum=16, maximum=4096,
          dynamic=False, unit="px"),
    Param("height", 480, "colour (and registered depth) height asked of a live device", minimum=16, maximum=4096,
          dynamic=False, unit="px"),
    Param("fps", 30.0, "frame rate asked of a live device", minimum=1.0, maximum=120.0, dynamic=False, unit="Hz"),
    Param("imu", True, "publish /camera/imu when the device has an IMU", dynamic=False),
    Param("depth_encoding", "32FC1", "depth image encoding (REP 118): 32FC1 metres or 16UC1 millimetres",
          choices=("32FC1", "16UC1"), dynamic=False),
    Param("frame_id", "camera_color_optical_frame", "frame_id of images, camera info and IMU", dynamic=False),
    Param("mounting_xyz", [0.0, 0.0, 0.0], "where the camera body (camera_link) sits in base_link, x y z: the "
          "static tf base_link → camera_link (zeros: the camera is the body, hand-held or worn)", dynamic=False,
          unit="m"),
    Param("mounting_rpy", [0.0, 0.0, 0.0], "the camera body's roll pitch yaw in base_link (fixed axes x, y, z)",
          dynamic=False, unit="deg"),
    Param("rate", 1.0, "recording playback speed factor", minimum=0.05, maximum=20.0),
    Param("at_end", "loop", "at the end of a recording: loop, hold (publish nothing more) or exit",
          choices=("loop", "hold", "exit"), dynamic=False),
    Param("retry_period", 1.0, "seconds between attempts to (re)open a missing or lost camera", minimum=0.05,
          maximum=60.0, dynamic=False, unit="s"),
    Param("give_up_after", 0.0, "exit (code 1) after this long without a camera; 0 retries forever", minimum=0.0,
          maximum=86400.0, dynamic=False, unit="s"),
    Param("frame_timeout", 2.0, "an open device that sends nothing for this long is lost", minimum=0.1,
          maximum=60.0, dynamic=False, unit="s"),
    Param("search_timeout", 2.0, "how long an SDK may search for a device when opening it (DepthAI)", minimum=0.1,
          maximum=60.0, dynamic=False, unit="s"),
]
