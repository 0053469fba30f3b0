"""Parameters of the `synthetic` RGB-D source node."""
from raspv_common.params import Param

PARAMS = [
    Param("width", 320, "image width", minimum=16, maximum=1920, dynamic=False, unit="px"),
    Param("height", 240, "image height", minimum=16, maximum=1080, dynamic=False, unit="px"),
    Param("hfov_deg", 60.0, "horizontal field of view", minimum=10.0, maximum=150.0, dynamic=False, unit="deg"),
    Param("rate", 15.0, "frames per second", minimum=0.5, maximum=120.0, dynamic=False, unit="Hz"),
    Param("eye_height", 1.6, "camera height above the floor", minimum=0.2, maximum=2.4, unit="m"),
    Param("pitch_down_deg", 15.0, "camera tilt below the horizon", minimum=-45.0, maximum=80.0, unit="deg"),
    Param("walk_speed", 0.4, "speed along the walking loop (0 stands still)", minimum=0.0, maximum=3.0, unit="m/s"),
    Param("frame_id", "camera_color_optical_frame", "frame_id of the images and camera info", dynamic=False),
]
