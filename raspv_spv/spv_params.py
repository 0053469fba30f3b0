"""Parameters of the `spv` node (imports nothing heavy).

Device values (num_phosphenes … pulse_phase_ms) default to "the device's": 0 for numbers, ""
for names, −1 for dropout and noise; any other value overrides the ``device`` preset. Every
parameter can change while the node runs (``raspv param set spv NAME VALUE``): the simulator is
rebuilt and swapped in at once, or the change is refused with the reason.
"""
from raspv_common.params import Param
from raspv_spv.modes import MODES, OVERLAYS
from raspv_spv.camera_source import CAMERA_SOURCES
from raspv_spv.gaze import GAZE_MODES, SACCADE_DISPLAYS, SACCADE_THRESHOLD_DEG_S

PARAMS = [
    Param("device", "default", "device preset (default, argus_ii, argus_ii_axon, alpha_ims, prima, orion, ... see "
          "config/devices) or a device YAML path", file_kind="device"),
    Param("num_phosphenes", 0, "number of phosphenes N (0: the device's)", minimum=0, maximum=20000),
    Param("fov_deg", 0.0, "prosthesis horizontal field of view (0: the device's)", minimum=0.0, maximum=160.0, unit="deg"),
    Param("phosphene_fov_deg", 0.0, "phosphene diameter (0: the device's)", minimum=0.0, maximum=10.0, unit="deg"),
    Param("grid", "", "lattice ('': the device's)", choices=("", "rectangular", "hexagonal")),
    Param("field", "", "visual field shape ('': the device's)", choices=("", "rectangular", "circular")),
    Param("num_levels", 0, "luminance levels N_L, 2..256 (0: the device's)", minimum=0, maximum=256),
    Param("dropout", -1.0, "fraction of phosphenes that never light (-1: the device's)", minimum=-1.0, maximum=1.0),
    Param("noise_px", -1.0, "std. dev. of the displayed position noise (-1: the device's)", minimum=-1.0,
          maximum=200.0, unit="px"),
    Param("seed", 0, "seed of the dropout and noise draws (one simulated patient)", minimum=0, maximum=2**31 - 1),
    Param("width", 800, "phosphene image width", minimum=16, maximum=4096, unit="px"),
    Param("height", 0, "phosphene image height (0: width x the device's aspect ratio)", minimum=0, maximum=4096,
          unit="px"),
    Param("mode", "grey", "representation mode", choices=tuple(MODES)),
    Param("overlays", [], "overlays drawn over the mode, in order", choices=tuple(OVERLAYS) or None),
    Param("temporal", True, "temporal model (discretised Horsager 2009 / Nanduri 2012) on or off"),
    Param("temporal_model", "horsager2009", "continuous model of the temporal model",
          choices=("horsager2009", "nanduri2012")),
    Param("temporal_update", "recursive", "recursive: the model advanced exactly by the real time between display "
          "frames, pulses at pulse_rate, so the display can follow its input at any rate; lut: the paper's 10-frame "
          "look-up table, one pulse per display frame (frames keep the rate's clock)", choices=("recursive", "lut")),
    Param("pulse_rate", 50.0, "stimulation rate of the recursive temporal model, whatever the display rate",
          minimum=1.0, maximum=100.0, unit="Hz"),
    Param("charge_recovery_ms", 200.0, "recursive temporal model: time constant of charge-accumulation recovery "
          "(200: the same steady-state charge as the look-up table's 10-frame window; 0: never, pulse2percept's "
          "model, a phosphene held on fades within ~15 s)", minimum=0.0, maximum=1e6, unit="ms"),
    Param("temporal_sample", "mean", "look-up table: a frame shows the model's mean over the frame or its value at "
          "the frame's end (the recursive model shows its value at the display time)", choices=("mean", "end")),
    Param("pulse_amplitude_ua", 0.0, "biphasic pulse amplitude of an 'on' frame (0: the device's)", minimum=0.0,
          maximum=2000.0, unit="uA"),
    Param("pulse_phase_ms", 0.0, "duration of each pulse phase (0: the device's)", minimum=0.0, maximum=5.0, unit="ms"),
    Param("layout", "", "implant electrode layout (config/layouts name or YAML path; '': the device's)",
          file_kind="layout"),
    Param("sprite_model", "", "phosphene shape ('': the device's)",
          choices=("", "gaussian", "scoreboard", "axon_map", "biphasic_axon_map", "dynaphos")),
    Param("rho_um", 0.0, "current spread of the tissue sprite models (0: the device's)", minimum=0.0, maximum=10000.0,
          unit="um"),
    Param("axlambda_um", 0.0, "axon-map decay along the axon (0: the device's)", minimum=0.0, maximum=10000.0,
          unit="um"),
    Param("headless", False, "no display loop: publish each computed frame at once, stamped with its input, the "
          "temporal model advancing by the input's elapsed time (scripted subjects, sweeps in sim time)", dynamic=False),
    Param("rate", 50.0, "display rate (headsets: 72, 90 or 120; the look-up table's frame rate; /spv/status says what "
          "the rate costs and a rate this machine cannot keep is refused)", minimum=1.0, maximum=240.0, unit="Hz"),
    Param("reprojection", True, "re-sample the last camera frame for the newest head orientation at every display tick "
          "(only when the viewer's head turns the camera: camera_source sim or head)"),
    Param("camera_source", "unknown", "where the images come from, set by the launcher from the graph's source node: "
          "sim (the avatar's head camera), head/chest/hand/robot/custom (a live camera's mounting), recording (a bag "
          "or a camera node playing a file); only sim and head are turned by the viewer's head",
          choices=tuple(CAMERA_SOURCES)),
    Param("display_on_input", True, "show a head turn or a new camera frame at once instead of at the next display "
          "tick (at most 4 x rate frames/s), with the temporal model off or recursive; with the look-up table frames "
          "keep its rate"),
    Param("predict_pose", True, "a frame whose camera pose comes later (RGB-D odometry) is shown at once with the pose "
          "predicted at its stamp, then recomputed with its own; off: it waits for its pose (headless always waits)"),
    Param("carry_scene", True, "scene modes show each new depth frame at once with the newest scene-perception "
          "result carried into it by the camera's motion, and again with its own result when that comes; off: they "
          "wait for it (headless always waits)"),
    Param("view_memory_s", 10.0, "a head turn beyond the newest camera frame is filled at once from frames already "
          "shown in that direction (one per 10 deg, this young, the base within 5 cm of where they were taken; with "
          "odometry and reprojection, no device latency) until the camera's frame comes; 0: off (dark)",
          minimum=0.0, maximum=60.0, unit="s"),
    Param("device_latency_ms", 0.0, "simulated device latency: show the scene as captured this long before display "
          "(0: as soon as the graph can)", minimum=0.0, maximum=1000.0, unit="ms"),
    Param("gaze_mode", "ignored", "eye gaze (/gaze/direction): ignored (phosphenes fixed on the display), locked (the "
          "field drawn where the eye looks, the scene sampled straight ahead of the head camera: a retinal implant), "
          "contingent (the field drawn and the scene sampled where the eye looks: an eye-tracking device)",
          choices=GAZE_MODES),
    Param("saccade_display", "blank", "during a saccade (velocity above saccade_threshold): blank (no phosphenes, as "
          "saccadic suppression), hold (the field stays at the last fixation) or follow (every sample drawn)",
          choices=SACCADE_DISPLAYS),
    Param("saccade_threshold", SACCADE_THRESHOLD_DEG_S, "eye velocity above which a saccade is under way (I-VT)",
          minimum=5.0, maximum=1000.0, unit="deg/s"),
    Param("stale_inputs", True, "notice inputs that stop (camera, scene, path, stairs, segmentation) and show a "
          "fallback mode, or the blinking no-data ring, instead of the last frame (off: sources that publish "
          "single frames)"),
    Param("output_format", "mono8", "/spv/image encoding: mono8, or green (rgb8, green channel only, for headsets)",
          choices=("mono8", "green")),
    Param("max_depth", 3.0, "depth mapped to level 0 (depth, edges_depth modes)", minimum=0.1, maximum=20.0, unit="m"),
    Param("edge_low", 50.0, "Canny lower threshold (edges modes)", minimum=1.0, maximum=1000.0),
    Param("edge_high", 150.0, "Canny upper threshold (edges modes)", minimum=1.0, maximum=1000.0),
    Param("learned_model", "", "ONNX encoder of the learned mode, from raspv learn ('': the shipped one for the "
          "device, else optimist's)", file_kind="learned_model"),
    Param("chess_tile", 0.5, "checkerboard tile size (chess modes)", minimum=0.05, maximum=5.0, unit="m"),
    Param("highlight.classes", ["person"], "classes the highlight overlay lights (names or synonyms of the "
          "segmentation's classes)"),
    Param("highlight.pick", "all", "highlight every pixel of the classes, or one instance: the largest or the nearest",
          choices=("all", "largest", "nearest")),
    Param("highlight.dim", 0.5, "level factor of the phosphenes the highlight overlay does not light", minimum=0.0,
          maximum=1.0),
    Param("highlight.max_age", 0.2, "use segmentation labels at most this far from the frame's stamp", minimum=0.0,
          maximum=5.0, unit="s"),
]
