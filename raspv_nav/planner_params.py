"""Parameters of the `planner` node (navigation assistant)."""
from raspv_common.params import Param

PARAMS = [
    Param("map", "", "map_server YAML of the building (e.g. from `raspv sim map`); or use 'world'", dynamic=False,
          file_kind="map", excludes=("world",)),
    Param("world", "", "simulator world (name or file): its structural map (walls, doors, stairs) is the building map",
          dynamic=False, file_kind="world"),
    Param("slam_map", "", "a saved SLAM map aligned to this building (raspv slam align): its stored alignment "
          "places the pose source's map frame on the building map", dynamic=False, file_kind="aligned_slam_map"),
    Param("map_from_odom", [0.0, 0.0, 0.0], "where the pose source's world/odometry frame sits on the map: "
          "x, y [m] and yaw [deg] of its origin and x axis (e.g. the recording's start on the building map); "
          "when not [0, 0, 0] it overrides slam_map's alignment",
          dynamic=False),
    Param("goal", [0.0, 0.0], "goal position (x, y) in the map frame (unless goal_name is set)", unit="m"),
    Param("goal_name", "", "name of a goal of the simulator world (overrides 'goal')"),
    Param("pose_source", "auto", "the subject's pose: /odom (base), /camera/pose (camera heading), or auto "
          "(/odom once it arrives)", choices=("auto", "odom", "camera"), dynamic=False),
    Param("robot_radius", 0.3, "clearance kept from obstacles", minimum=0.05, maximum=1.5, unit="m", dynamic=False),
    Param("inflation_radius", 1.0, "obstacles raise the path cost up to this distance", minimum=0.1, maximum=5.0,
          unit="m", dynamic=False),
    Param("cost_weight", 4.0, "extra path cost per metre at the robot radius (0: shortest path only)", minimum=0.0,
          maximum=50.0, dynamic=False),
    Param("max_relocation", 1.5, "a start or goal in the inflated zone is moved to a free cell up to this far",
          minimum=0.0, maximum=5.0, unit="m"),
    Param("replan_rate", 4.0, "global replanning rate", minimum=0.1, maximum=20.0, unit="Hz"),
    Param("control_rate", 10.0, "local planner (velocity hint, guidance) rate", minimum=1.0, maximum=50.0, unit="Hz"),
    Param("costmap_rate", 1.0, "publishing rate of /nav/costmap and /nav/obstacle_layer (0: never)", minimum=0.0,
          maximum=20.0, unit="Hz"),
    Param("use_camera_obstacles", True, "add obstacles seen in the depth image to the costmaps"),
    Param("obstacle_min_height", 0.10, "lowest obstacle point above the floor", minimum=0.0, maximum=1.0, unit="m",
          dynamic=False),
    Param("obstacle_max_height", 1.80, "highest obstacle point above the floor", minimum=0.2, maximum=3.0, unit="m",
          dynamic=False),
    Param("obstacle_range", 4.0, "depth marks and clears the costmap up to this horizontal distance", minimum=0.5,
          maximum=10.0, unit="m", dynamic=False),
    Param("obstacle_memory", 10.0, "decay of the obstacle layer: a cell not seen again is forgotten after this "
          "(cells seen free are cleared at once)", minimum=0.0, maximum=600.0, unit="s", dynamic=False),
    Param("max_speed", 0.8, "fastest suggested walking speed", minimum=0.1, maximum=3.0, unit="m/s", dynamic=False),
    Param("goal_tolerance", 0.4, "distance at which the goal counts as reached", minimum=0.05, maximum=3.0, unit="m",
          dynamic=False),
    Param("proximity_range", 1.5, "obstacles ahead nearer than this are reported for the proximity cue", minimum=0.2,
          maximum=5.0, unit="m", dynamic=False),
    Param("lockstep", False, "scripted subjects in a lockstep simulator: no timers — each frame (its depth, camera "
          "pose, odometry and the /spv/frame made from it) updates the costmap and replans at replan_rate of frame "
          "time, then the path goes out and the frame is answered on /sim/lockstep (frame_id planner), so the "
          "phosphenes of the next frame show it in every run", dynamic=False),
]
