"""Real RGB-D frames (tests/data/rgbd, provenance in its README) and synthetic scenes for the
perception tests."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import read_color, read_depth_scaled, read_nyu_disparity
from raspv_bringup.testing import dev_requirement

DATA = Path(__file__).resolve().parents[1] / "data" / "rgbd"
KINECT_DEFAULT = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
PCL_KINECT = CameraIntrinsics(640, 480, 525.0, 525.0, 320.0, 240.0)


@pytest.fixture(scope="session")
def tum_frame():
    return read_color(DATA / "tum_color.png"), read_depth_scaled(DATA / "tum_depth.png", 1 / 5000), KINECT_DEFAULT


@pytest.fixture(scope="session")
def nyu_frame():
    return read_color(DATA / "nyu_color.ppm"), read_nyu_disparity(DATA / "nyu_depth.pgm"), KINECT_DEFAULT


@pytest.fixture(scope="session")
def kinect_frames():
    """The three consecutive PCL Kinect frames: [(rgb, depth m, intrinsics), ...] in time order."""
    out = []
    for depth_path in sorted((DATA / "kinect_table").glob("*_depth.tiff")):
        rgb_path = depth_path.with_name(depth_path.name.replace("_depth", "_rgb"))
        out.append((read_color(rgb_path), read_depth_scaled(depth_path, 0.001), PCL_KINECT))
    return out


def plane_depth(intrinsics: CameraIntrinsics, normal, d) -> np.ndarray:
    """Depth [m] of the plane n·p + d = 0 (camera frame) seen by ``intrinsics``; NaN where the
    ray misses it (behind the camera)."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = intrinsics.rays(u, v)                      # z = 1
    n = np.asarray(normal, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = -d / (rays @ n)
    z[~(z > 0)] = np.nan
    return z.reshape(intrinsics.height, intrinsics.width).astype(np.float32)


# -- a user's own segmentation model, built and exported as docs/perception.md tells users -------
CLASSES = ["background", "red thing;crimson", "blue thing"]


def red_blue_net():
    """Deterministic, hand-weighted (not trained): a 2×2 stride-2 average (so the output is half
    the input size, as real networks' are), then per-pixel logits: background 0, red
    3r − 1.5g − 1.5b − 0.5, blue 3b − 1.5r − 1.5g − 0.5 on pixels in [0, 1]."""
    import torch

    down = torch.nn.Conv2d(3, 3, 2, stride=2, bias=False)
    head = torch.nn.Conv2d(3, 3, 1)
    with torch.no_grad():
        down.weight.zero_()
        for c in range(3):
            down.weight[c, c] = 0.25
        head.weight[:] = torch.tensor([[0.0, 0, 0], [3, -1.5, -1.5], [-1.5, -1.5, 3]]).reshape(3, 3, 1, 1)
        head.bias[:] = torch.tensor([0.0, -0.5, -0.5])
    return torch.nn.Sequential(down, head).eval()


def write_model(tmp: Path, kind: str = "onnx", size=(96, 64), **spec) -> Path:
    """The red/blue network exported to ``tmp`` as ONNX (``kind`` onnx) or TorchScript (pt), with
    its model YAML (``spec`` overrides keys)."""
    import torch
    import yaml

    net = red_blue_net()
    x = torch.zeros(1, 3, size[1], size[0])
    if kind == "onnx":
        path = tmp / "redblue.onnx"
        torch.onnx.export(net, x, str(path), dynamo=False, opset_version=17, input_names=["image"],
                          output_names=["logits"])
    else:
        path = tmp / "redblue.pt"
        torch.jit.trace(net, x).save(str(path))
    doc = {"input_size": list(size), "scale": 255.0, "mean": [0, 0, 0], "std": [1, 1, 1], "channel_order": "rgb",
           "layout": "nchw", "labels": CLASSES, **spec}
    path.with_suffix(".yaml").write_text(yaml.safe_dump(doc))
    return path


@pytest.fixture
def write_user_model():
    dev_requirement("torch")
    dev_requirement("onnx")
    return write_model
