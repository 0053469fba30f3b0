"""Pictures of a world for checking it and for documents: the avatar's view (colour, depth,
class labels with a legend) and a bird's-eye overview (matplotlib Agg; no rclpy)."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from raspv_common.intrinsics import CameraIntrinsics  # noqa: E402
from raspv_sim.sim_camera import SimCamera  # noqa: E402
from raspv_sim.simulator import SimFrame, Simulation  # noqa: E402


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """World ← camera (optical frame) for a camera at ``eye`` looking at ``target`` (W, m)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, eye
    return T


def overview_image(sim: Simulation, width: int = 960, height: int = 720) -> np.ndarray:
    """Bird's-eye perspective of the whole floor from the south, RGB (H, W, 3) uint8."""
    fl = sim.spec.floor
    cx, cy = (fl.lo[0] + fl.hi[0]) / 2, (fl.lo[1] + fl.hi[1]) / 2
    span = max(fl.hi[0] - fl.lo[0], (fl.hi[1] - fl.lo[1]) * width / height)
    distance = 0.75 * span / math.tan(math.radians(25))
    eye = (cx, cy - 0.45 * distance, 0.89 * distance)
    cam = SimCamera(sim.client, CameraIntrinsics.from_hfov(width, height, 50.0), 0.1, 4 * distance, sim.renderer,
                    sim.spec.light_direction)
    return cam.render(look_at(eye, (cx, cy, 0.0))).rgb


def class_palette(n: int) -> np.ndarray:
    """Distinct RGB colours (n, 3) in [0, 1] for class ids; id 0 (none) is black."""
    cmap = plt.get_cmap("tab20")
    out = np.array([cmap(i % 20)[:3] for i in range(n)])
    out[0] = 0.0
    return out


def view_figure(frame: SimFrame, classes: tuple[str, ...], out_png: str | Path, title: str = "") -> Path:
    """Colour, depth [m] and labels of one frame side by side, saved as a PNG."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), dpi=100)
    axes[0].imshow(frame.rgb)
    axes[0].set_title("colour (rgb8)")
    im = axes[1].imshow(frame.depth, cmap="viridis")
    axes[1].set_title("depth (32FC1, m; white = no reading)")
    fig.colorbar(im, ax=axes[1], fraction=0.04, pad=0.01)
    palette = class_palette(len(classes))
    axes[2].imshow(palette[frame.labels])
    axes[2].set_title("labels (mono8 class ids)")
    present = [int(i) for i in np.unique(frame.labels)]
    axes[2].legend(handles=[Patch(color=palette[i], label=f"{i} {classes[i]}") for i in present], fontsize=7,
                   loc="center left", bbox_to_anchor=(1.01, 0.5))
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png


def save_rgb(rgb: np.ndarray, out_png: str | Path) -> Path:
    out_png = Path(out_png)
    plt.imsave(out_png, rgb)
    return out_png
