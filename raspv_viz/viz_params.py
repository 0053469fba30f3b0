"""Parameters of the `viz` node (markers and point cloud for RViz and Foxglove)."""
from raspv_common.params import Param

PARAMS = [
    Param("fixed_frame", "auto", "frame of the markers and the cloud: map (needs /camera/pose), camera (the "
          "depth image's optical frame; tf places it) or auto (map once a pose arrived, else camera); world is "
          "map's older name", choices=("auto", "map", "camera", "world")),
    Param("cloud_rate", 5.0, "point clouds published per second (0: none)", minimum=0.0, maximum=30.0, unit="Hz"),
    Param("cloud_stride", 8, "take every n-th depth pixel along rows and columns", minimum=1, maximum=64, unit="px"),
    Param("cloud_max_depth", 8.0, "depth beyond this is left out of the cloud", minimum=0.5, maximum=50.0, unit="m"),
    Param("cloud_color", True, "colour the cloud from the colour image of the same stamp"),
    Param("phosphene_rate", 10.0, "phosphene markers published per second (0: none)", minimum=0.0, maximum=50.0,
          unit="Hz"),
    Param("phosphene_distance", 1.0, "the phosphenes are drawn on a plane this far in front of the camera",
          minimum=0.1, maximum=20.0, unit="m"),
]
