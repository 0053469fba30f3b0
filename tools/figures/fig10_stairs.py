#!/usr/bin/env python
"""The paper's Fig. 10: an ascending and a descending staircase of the sim ``stairs`` world,
detected from depth and drawn as augmented reality — RGB with the phosphene positions and the
detected wireframe, then Chess-Floor and downsampling, each without and with the stairs overlay.

    .venv/bin/python tools/figures/fig10_stairs.py        # → docs/figures/fig10_stairs.png

Each view is rendered at 640×480 (60° camera), goes through scene perception (ground-truth pose
as prior, as the ``scene`` node) and stair detection (as the ``stairs`` node), and is drawn with
the ``optimist`` device (1000 phosphenes, 45° field).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import cv2  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fig9_apartment import CAMERA, DEVICE, rgb_with_phosphenes  # noqa: E402
from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_perception.stairs import StairDetector  # noqa: E402
from raspv_sim.simulator import Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

# (title, avatar x, y [m], yaw [deg], head pitch down [deg])
VIEWS = [("ascending, 2.5 m before the first step", 5.5, 2.5, 85, 25),
         ("descending, 1 m before the top edge", 10.2, 4.0, 90, 40)]
ROWS = [("RGB + phosphenes\n+ detected stair", None, False), ("Chess-Floor", "chess_floor", False),
        ("Chess-Floor + stairs", "chess_floor", True), ("downsampling", "grey", False),
        ("downsampling + stairs", "grey", True)]


def render_views():
    out = []
    with Simulation("stairs", CAMERA) as sim:
        for title, x, y, yaw, pitch in VIEWS:
            frame = sim.render_from(x, y, math.radians(yaw), head_pitch=math.radians(pitch))
            result = ScenePerception().process(frame.depth, frame.intrinsics, frame.world_from_camera)
            stair = StairDetector().detect(frame.depth, frame.intrinsics, result.structure)
            out.append((title, frame, result, stair))
    return out


def wireframe_on_rgb(frame, stair) -> np.ndarray:
    img = rgb_with_phosphenes(frame).copy()
    if stair is None:
        return img
    K = frame.intrinsics
    x0 = (K.width - K.height) // 2                                  # rgb_with_phosphenes crops the centre
    segs = stair.segments()
    u, v, z = K.project(segs.reshape(-1, 3))
    ends = np.stack([u - x0, v], axis=1).astype(int).reshape(-1, 2, 2)
    for (pa, pb), depth in zip(ends, z.reshape(-1, 2)):
        if (depth > 0.05).all():
            cv2.line(img, tuple(int(c) for c in pa), tuple(int(c) for c in pb), (255, 60, 200), 2, lineType=cv2.LINE_AA)
    return img


def phosphene_image(frame, result, stair, mode: str, overlay: bool) -> np.ndarray:
    sim = PhospheneSimulator(spv_config(DEVICE, temporal=False, mode=mode, width=400,
                                        overlays=["stairs"] if overlay else [], mode_settings={"chess_tile": 0.5}))
    inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                         camera_pose=frame.world_from_camera, scene=result.structure, scene_labels=result.labels,
                         extras={"stairs": [] if stair is None else [stair]})
    return sim.render(sim.brightness(sim.levels(inputs)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "fig10_stairs.png")
    args = parser.parse_args(argv)
    views = render_views()
    fig, axes = plt.subplots(len(ROWS), len(views), figsize=(2.6 * len(views) + 0.9, 2.6 * len(ROWS) + 0.4),
                             gridspec_kw={"hspace": 0.05, "wspace": 0.04})
    fig.subplots_adjust(left=0.2, right=0.99, top=0.93, bottom=0.01)
    for c, (title, frame, result, stair) in enumerate(views):
        for r, (label, mode, overlay) in enumerate(ROWS):
            ax = axes[r, c]
            img = wireframe_on_rgb(frame, stair) if mode is None else phosphene_image(frame, result, stair, mode, overlay)
            ax.imshow(img, cmap="gray", vmin=0, vmax=255, interpolation="antialiased")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(title, fontsize=8)
            if c == 0:
                ax.set_ylabel(label, fontsize=8)
    fig.suptitle(f"Stair detection and augmentation ({DEVICE}: 1000 phosphenes, 45° field)", fontsize=10)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    for title, _, _, stair in views:
        text = "no staircase" if stair is None else (
            f"{stair.direction.name.lower()}, {len(stair.steps)} steps, riser {stair.riser:.3f} m, "
            f"tread {stair.tread:.3f} m, width {stair.width:.2f} m, {stair.distance:.2f} m away")
        print(f"{title}: {text}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
