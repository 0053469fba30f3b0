"""Parameters of the `scene` node (scene perception); they map onto ``SceneConfig`` fields."""
from raspv_common.params import Param

PARAMS = [
    Param("stride", 4, "process every stride-th depth pixel (labels are upsampled back)", minimum=1, maximum=8, unit="px"),
    Param("min_depth", 0.2, "nearer depth readings are ignored", minimum=0.0, maximum=5.0, unit="m"),
    Param("max_depth", 8.0, "farther depth readings are ignored", minimum=0.5, maximum=20.0, unit="m"),
    Param("use_pose_prior", True, "use /camera/pose (when published) for gravity and floor tracking"),
    Param("pose_max_age", 0.2, "a pose further than this from the depth stamp is not used", minimum=0.0,
          maximum=5.0, unit="s"),
    Param("lockstep", False, "scripted sessions in a lockstep simulator: each depth frame waits for the "
          "/camera/pose of its own stamp (the simulator publishes one with every frame), so a run repeats "
          "exactly; off, a frame is processed on arrival with the nearest pose there is", dynamic=False),
    Param("mounting", "head", "where the camera is carried; sets the camera height and tilt accepted for a new "
          "floor (head 1.0-2.0 m, chest 0.7-1.6 m, hand 0.3-1.5 m, robot 0.1-1.5 m; custom: the first_floor_* "
          "limits)", choices=("head", "chest", "hand", "robot", "custom")),
    Param("use_imu", True, "use the accelerometer on /camera/imu (when published) as gravity: a new floor is then "
          "found at any camera height"),
    Param("first_floor_min_height", 1.0, "with mounting 'custom': lowest camera height accepted for a new floor",
          minimum=0.05, maximum=3.0, unit="m"),
    Param("first_floor_max_height", 2.0, "with mounting 'custom': highest camera height accepted for a new floor",
          minimum=0.2, maximum=4.0, unit="m"),
    Param("first_floor_max_angle_deg", 40.0, "with mounting 'custom': largest camera tilt accepted for a new floor",
          minimum=1.0, maximum=89.0, unit="deg"),
    Param("min_floor_area", 0.5, "visible floor needed to accept a new floor", minimum=0.0, maximum=20.0, unit="m^2"),
    Param("plane_distance", 0.02, "plane inlier distance at 0 m (grows with z^2)", minimum=0.002, maximum=0.2, unit="m"),
    Param("min_plane_area", 0.15, "smaller planar patches are not reported", minimum=0.0, maximum=10.0, unit="m^2"),
    Param("min_wall_area", 0.3, "smaller vertical planes are not walls", minimum=0.0, maximum=20.0, unit="m^2"),
    Param("min_wall_top", 1.3, "a wall reaches this high above the floor (or the top of the view)", minimum=0.0,
          maximum=5.0, unit="m"),
    Param("min_obstacle_height", 0.05, "an obstacle's top is at least this far above the floor", minimum=0.0,
          maximum=1.0, unit="m"),
    Param("max_obstacle_height", 2.0, "points higher above the floor are not obstacles", minimum=0.2, maximum=5.0, unit="m"),
    Param("cluster_tolerance", 0.035, "points closer than this join an obstacle cluster", minimum=0.005,
          maximum=0.5, unit="m"),
    Param("obstacle_margin", 0.15, "floor within this of an obstacle is not free", minimum=0.0, maximum=2.0, unit="m"),
    Param("publish_labels", True, "publish the per-pixel class image /scene/labels"),
]

# node parameter → SceneConfig field (same name); ``mounting`` then overrides the first_floor_* limits
CONFIG_FIELDS = ("stride", "min_depth", "max_depth", "first_floor_min_height", "first_floor_max_height",
                 "first_floor_max_angle_deg", "min_floor_area", "plane_distance", "min_plane_area", "min_wall_area",
                 "min_wall_top", "min_obstacle_height", "max_obstacle_height", "cluster_tolerance", "obstacle_margin")
