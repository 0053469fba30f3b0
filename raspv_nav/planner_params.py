"""Parameters of the `planner` node (navigation assistant)."""
from raspv_common.params import Param

PARAMS = [
    Param("map", "", "map_server YAML of the building (e.g. from `raspv sim map`); or use 'world'", dynamic=False,
          file_kind="map"),
    Param("world", "", "simulator world (name or file): its structural map (walls, doors, stairs) is the building map",
          dynamic=False, file_kind="world"),
    Param("goal", [0.0, 0.0], "goal position (x, y) in the world frame (unless goal_name is set)", unit="m"),
    Param("goal_name", "", "name of a goal of the simulator world (overrides 'goal')"),
    Param("robot_radius", 0.3, "clearance kept from obstacles", minimum=0.05, maximum=1.5, unit="m"),
    Param("inflation_radius", 1.0, "obstacles raise the path cost up to this distance", minimum=0.1, maximum=5.0, unit="m"),
    Param("replan_rate", 2.0, "global replanning rate", minimum=0.1, maximum=20.0, unit="Hz"),
    Param("control_rate", 10.0, "local planner (velocity hint) rate", minimum=1.0, maximum=50.0, unit="Hz"),
    Param("use_camera_obstacles", True, "add obstacles seen in the depth image to the costmaps"),
    Param("obstacle_min_height", 0.10, "lowest obstacle point above the floor", minimum=0.0, maximum=1.0, unit="m"),
    Param("obstacle_max_height", 1.80, "highest obstacle point above the floor", minimum=0.2, maximum=3.0, unit="m"),
    Param("obstacle_range", 4.0, "ignore depth beyond this", minimum=0.5, maximum=10.0, unit="m"),
    Param("obstacle_memory", 2.0, "seen obstacles are forgotten after this", minimum=0.0, maximum=60.0, unit="s"),
    Param("max_speed", 0.8, "fastest suggested walking speed", minimum=0.1, maximum=3.0, unit="m/s"),
    Param("goal_tolerance", 0.4, "distance at which the goal counts as reached", minimum=0.05, maximum=3.0, unit="m"),
]
