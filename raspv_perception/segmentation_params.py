"""Parameters of the `segmentation` node (imports nothing heavy)."""
from raspv_common.params import Param

PARAMS = [
    Param("backend", "person", "person (shipped MediaPipe model), onnx, torchscript (a model file of yours) or sim "
          "(the virtual world's ground truth)", choices=("person", "onnx", "torchscript", "sim"), dynamic=False),
    Param("model", "", "model file for onnx/torchscript (person: '' = the shipped model)", dynamic=False,
          file_kind="segmentation_model"),
    Param("labels", "", "model file (YAML: input size, normalisation, labels); '' = the model path with .yaml",
          dynamic=False),
    Param("threads", 1, "inference threads", minimum=1, maximum=16, dynamic=False),
    Param("threshold", 0.5, "person probability from which a pixel is person", minimum=0.01, maximum=1.0),
    Param("depth_fusion", True, "person model: make masks whole and drop false positives with /scene/labels + depth"),
    Param("cluster_support", 0.25, "mean person probability over a depth cluster from which it all is person",
          minimum=0.01, maximum=1.0),
    Param("min_area", 0.002, "smaller mask pieces are dropped (fraction of the image)", minimum=0.0, maximum=0.5),
    Param("depth_jump", 0.05, "relative depth step that separates two clusters", minimum=0.005, maximum=1.0),
    Param("keep_without_depth", False, "keep network pixels where depth has no reading (not only next to a cluster)"),
    Param("scene_max_age", 0.15, "wait this long for the scene labels of a colour frame, and use ones at most this "
          "far from its stamp", minimum=0.0, maximum=2.0, unit="s"),
]
