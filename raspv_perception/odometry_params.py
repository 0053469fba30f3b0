"""Parameters of the `odometry` node (RGB-D odometry publishing /camera/pose)."""
from raspv_common.params import Param

PARAMS = [
    Param("scale", 0.5, "images are resized by this before registration (1.0: full size, slower)", minimum=0.1,
          maximum=1.0, dynamic=False),
    Param("max_rate", 10.0, "register at most this many frames per second (0: every frame); the spv node predicts "
          "the poses in between. One 320x240 registration costs ~21 ms of a core", minimum=0.0, maximum=120.0,
          unit="Hz", dynamic=False),
    Param("threads", 1, "Open3D threads (1: one core, the graph's other nodes keep theirs; more: lower latency on "
          "larger machines)", minimum=1, maximum=64, dynamic=False),
    Param("max_depth", 4.0, "depth used for registration", minimum=0.5, maximum=10.0, unit="m", dynamic=False),
    Param("min_overlap", 0.3, "fraction of depth pixels that must match the previous frame", minimum=0.0,
          maximum=1.0, dynamic=False),
    Param("gravity_from_floor", True, "align the world frame with the floor from /scene/structure (needs a scene node)",
          dynamic=False),
    Param("anchor_timeout", 3.0, "without a floor after this, assume the first camera was level and start publishing",
          minimum=0.0, maximum=60.0, unit="s", dynamic=False),
]
