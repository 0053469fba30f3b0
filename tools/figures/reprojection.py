#!/usr/bin/env python
"""Figure of display-time reprojection: Chess-Floor in the PyBullet apartment when the head turns.

    .venv/bin/python tools/figures/reprojection.py          # → docs/figures/reprojection_chess.png

Four phosphene images (optimist preset, Chess-Floor on real scene perception of the simulated
depth): the camera frame at head yaw 0; what the display showed at head yaw 12° until the next
camera frame before reprojection (the same image: the tiles swim with the head); the same frame
re-projected to the turned head (raspv_spv.reprojection, what the spv node shows now); and the
frame rendered at the turned head, for comparison. The 12° turn stays inside the camera's 10°
margin plus the part of its 60° the 45° prosthesis field does not use.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_sim.avatar import head_quaternion  # noqa: E402
from raspv_sim.simulator import SimConfig, Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.reprojection import ViewTracker  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

PITCH_DEG, TURN_DEG = 35.0, 12.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    args = parser.parse_args()
    spv = PhospheneSimulator(spv_config("optimist", width=400, mode="chess_floor", temporal=False))
    with Simulation("apartment", SimConfig(margin_deg=10.0)) as sim:
        x, y = sim.spec.spawn_position
        frames = []
        for yaw in (0.0, TURN_DEG):
            f = sim.render_from(x, y, math.radians(sim.spec.spawn_yaw), head_pitch=math.radians(PITCH_DEG),
                                head_yaw=math.radians(yaw))
            scene = ScenePerception().process(f.depth, f.intrinsics)
            frames.append((f, FrameInputs(color=f.rgb, depth=f.depth, camera=f.intrinsics,
                                          camera_pose=f.world_from_camera, scene=scene.structure,
                                          scene_labels=scene.labels, stamp=1.0)))
        tracker = ViewTracker()
        tracker.add_camera_pose(1.0, frames[0][0].world_from_camera)
        tracker.add_odometry(1.0, sim.avatar.world_from_base(), 0.0)
        tracker.add_head(0.5, head_quaternion(0.0, math.radians(PITCH_DEG), 0.0))
        tracker.add_head(1.01, head_quaternion(0.0, math.radians(PITCH_DEG), math.radians(TURN_DEG)))
        R = tracker.capture_from_display(1.0, 1.02)
    captured = spv.step(frames[0][1]).image
    turned = spv.render(spv.brightness(spv.levels(frames[0][1], capture_from_display=R)))
    truth = spv.render(spv.brightness(spv.levels(frames[1][1])))
    fig, axes = plt.subplots(1, 4, figsize=(16, 5.0))
    panels = [(captured, "camera frame, head yaw 0°"),
              (captured, f"head at {TURN_DEG:g}°, before: the frame as it was\n(tiles swim with the head)"),
              (turned, f"head at {TURN_DEG:g}°, re-projected to it\n(tiles stay on the floor)"),
              (truth, f"next camera frame, rendered at {TURN_DEG:g}°")]
    for ax, (img, title) in zip(axes, panels):
        ax.imshow(img, cmap="gray", vmin=0, vmax=255)
        ax.set_title(title, fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle("Display-time reprojection, Chess-Floor in the apartment (optimist preset)", fontsize=12)
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    out = Path(args.out) / "reprojection_chess.png"
    fig.savefig(out, dpi=80)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
