"""Parameters of the `slam` node (RGB-D SLAM publishing /camera/pose in the map frame and tf)."""
from raspv_common.params import Param

PARAMS = [
    Param("map", "", "a saved map to load (a name in the maps folder or a path); empty: start a new map",
          dynamic=False, file_kind="slam_map"),
    Param("mode", "mapping", "mapping: build the map (a loaded one is continued); localisation: localise in the "
          "loaded map without changing it (needs 'map')", choices=("mapping", "localisation"), dynamic=False,
          needs=("map",), needs_when=("localisation",)),
    Param("save_to", "", "where mapping saves the map (a name in the maps folder or a path); empty: back to 'map', "
          "or a new name from the date when 'map' is empty too", dynamic=False),
    Param("save_on_exit", True, "mapping: save the map when the node stops (Ctrl-C, SIGTERM)", dynamic=False),
    Param("autosave_period", 60.0, "mapping: save the map this often while running, so a killed node loses at "
          "most this much (0: only at exit and on /slam/save_map)", minimum=0.0, maximum=3600.0, unit="s"),
    Param("new_map_after", 1.0, "mapping: lost this long (relocalisation failing) in a place the map does not know, "
          "start a new map in a frame of its own (map_id in /slam/state); it is merged into the older map when one of "
          "its places is recognised (0: wait for a mapped place instead)", minimum=0.0, maximum=600.0, unit="s",
          dynamic=False),
    Param("max_rate", 10.0, "process at most this many frames per second, by their stamps (0: every frame the "
          "worker can take). As the odometry node: on 2 cores the graph's other nodes keep their share (one 640x480 "
          "frame costs ~30-60 ms of a core); a slow frame drops the frames that came meanwhile, never queues them",
          minimum=0.0, maximum=120.0, unit="Hz"),
    Param("flow_between", True, "give the frames max_rate leaves out a pose too: sparse optical flow from the last "
          "frame the core tracked, then PnP (~3 ms a frame), so a display between the core's frames does not guess "
          "the camera's motion (false: those frames get no pose; the spv node predicts them at constant velocity)"),
    Param("rolling_shutter_readout", 0.0, "the colour camera's rolling shutter: first to last row read out in this "
          "long (0: a global shutter). Fast turns skew such an image; frames are tracked at their mid-row time. "
          "ROS camera info has no field for it: a replay of a bag that carries one (raspv bag from-frames "
          "--camera tum-fr1|tum-fr2: 0.025) gets it from the launcher unless it is set here",
          minimum=0.0, maximum=0.09, unit="s", dynamic=False),
    Param("threads", 1, "threads of the SLAM core's OpenCV and Open3D work", minimum=1, maximum=64, dynamic=False),
    Param("gravity_from_floor", True, "align a new map with the floor from /scene/structure (needs a scene node)",
          dynamic=False),
    Param("anchor_timeout", 3.0, "without a floor after this, poses are published in the first camera's axes "
          "(assumed level); a floor seen later still aligns the map (one jump)", minimum=0.0, maximum=60.0, unit="s",
          dynamic=False),
    Param("marker_period", 1.0, "keyframes, landmarks and loop edges on /slam/markers this often, while someone "
          "subscribes (0: never)", minimum=0.0, maximum=60.0, unit="s"),
]
