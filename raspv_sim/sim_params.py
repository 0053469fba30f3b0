"""Parameters of the `sim` node (the virtual world as an RGB-D source)."""
from raspv_common.params import Param

PARAMS = [
    Param("world", "apartment", "shipped world name (apartment, stairs, office, grocery) or path of a world YAML file", dynamic=False,
          file_kind="world"),
    Param("width", 320, "image width", minimum=16, maximum=1920, dynamic=False, unit="px"),
    Param("height", 240, "image height", minimum=16, maximum=1080, dynamic=False, unit="px"),
    Param("hfov_deg", 60.0, "horizontal field of view", minimum=10.0, maximum=150.0, dynamic=False, unit="deg"),
    Param("margin_deg", 0.0, "field of view rendered beyond hfov_deg on every side at the same focal length (the "
          "image grows), so the spv node's display-time reprojection keeps head turns inside the image; the "
          "headset graphs use 10", minimum=0.0, maximum=40.0, dynamic=False, unit="deg"),
    Param("near", 0.05, "near clipping plane", minimum=0.01, maximum=1.0, dynamic=False, unit="m"),
    Param("far", 8.0, "depth range (farther depth is NaN; colour is rendered beyond)", minimum=0.5, maximum=50.0,
          dynamic=False, unit="m"),
    Param("rate", 20.0, "frames per second (step + render + publish)", minimum=1.0, maximum=60.0, dynamic=False, unit="Hz"),
    Param("renderer", "auto", "auto: EGL when it loads, else TinyRenderer", choices=("auto", "egl", "tiny"), dynamic=False),
    Param("frame_id", "camera_color_optical_frame", "frame_id of the images and camera info", dynamic=False),
    Param("eye_height", 1.6, "camera height above the feet with the head level", minimum=0.5, maximum=2.2, unit="m"),
    Param("max_linear", 1.5, "largest forward/backward speed", minimum=0.0, maximum=3.0, unit="m/s"),
    Param("max_angular", 1.5, "largest turning speed", minimum=0.0, maximum=6.0, unit="rad/s"),
    Param("body_radius", 0.25, "radius of the avatar's collision body", minimum=0.1, maximum=0.5, dynamic=False, unit="m"),
    Param("max_step", 0.2, "highest step the avatar walks up or down (0: flat floor only)", minimum=0.0, maximum=0.3,
          dynamic=False, unit="m"),
    Param("slide", True, "slide along obstacles instead of stopping dead"),
    Param("cmd_timeout", 0.5, "stop when no /cmd_vel arrived for this long (0: never)", minimum=0.0, maximum=10.0, unit="s"),
    Param("collision_debounce", 0.5, "contacts with the same object closer in time than this are one collision",
          minimum=0.0, maximum=10.0, unit="s"),
    Param("publish_labels", True, "publish ground-truth class ids on /sim/labels (rendered only while someone subscribes)"),
    Param("depth_noise", False, "degrade depth like a real sensor (noise, quantisation, missing pixels)"),
    Param("textures", False, "surface texture on walls (plaster, notices), floor (tiles) and furniture instead of flat "
          "colour: what feature-based localisation (the slam node) needs; labels unchanged", dynamic=False),
    Param("depth_noise_at_1m", 0.0014, "axial depth noise sigma at 1 m (grows with z squared)", minimum=0.0,
          maximum=0.05, unit="m"),
    Param("depth_subpixel", 8.0, "disparity quantisation steps per pixel (0: off)", minimum=0.0, maximum=64.0),
    Param("depth_edge_jump", 0.04, "relative depth jump that makes an edge pixel missing (0: off)", minimum=0.0, maximum=1.0),
    Param("depth_dark_dropout", 0.6, "probability that a dark pixel has no depth", minimum=0.0, maximum=1.0),
    Param("depth_specular_dropout", 0.7, "probability that a pixel on a specular object has no depth", minimum=0.0,
          maximum=1.0),
    Param("depth_max_range", 6.0, "sensor range with depth_noise on", minimum=0.5, maximum=50.0, unit="m"),
    Param("seed", 0, "random seed of the depth-sensor model", minimum=0, maximum=2**31 - 1, dynamic=False),
    Param("log_dir", "", "experiment logs go to <log_dir>/<world>-<time>/ (empty: no log)", dynamic=False,
          file_kind="output_dir"),
    Param("step_mode", "realtime", "realtime: step with the wall clock at 'rate'; lockstep: step 1/rate s of sim time "
          "each time a controller answers the last frame on /sim/lockstep (scripted subjects, sweeps)",
          choices=("realtime", "lockstep"), dynamic=False),
    Param("lockstep_timeout", 2.0, "lockstep: step anyway when no answer came for this long (with lockstep_hold "
          "never: the world waits for every answer, with a warning after this long)", minimum=0.05,
          maximum=60.0, dynamic=False, unit="s"),
    Param("lockstep_hold", False, "lockstep: the world steps only while a trial runs — from /sim/start_trial with a "
          "log until its goal is reached or its time limit has passed — and holds before, between and after trials, "
          "so every node sees the same frames each time a session runs (scripted subjects, sweeps)", dynamic=False),
    Param("lockstep_participants", [], "lockstep: further nodes that answer every frame on /sim/lockstep "
          "(frame_id = their name) before the world steps, e.g. planner", dynamic=False),
    Param("paused", False, "hold the world: no time passes and nothing moves (realtime: frames keep coming)"),
    Param("log_rate", 10.0, "trajectory samples per second in the log", minimum=0.5, maximum=100.0, dynamic=False, unit="Hz"),
]
