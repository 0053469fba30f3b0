#!/usr/bin/env python
"""Fig. 9's iconic modes on real sensor frames: TUM desk, NYU basement, PCL Kinect table.

    .venv/bin/python tools/figures/fig9_real_frames.py [--out PNG]

Columns: colour image, the scene classes found by scene perception (with floor height and
tilt), Chess-Floor and Wall-Obstacles (``optimist`` device). These frames have no pose, so
Chess-Floor's tiles are laid in the floor frame, turned to the Manhattan axes. The Kinect table
frame has no floor within the first-floor limits (camera 0.72 m above a floor-level surface,
looking 46° down): its Chess-Floor stays dark and the surface is the support plane.
Output: docs/figures/fig9_real_frames.png.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_common.intrinsics import CameraIntrinsics  # noqa: E402
from raspv_common.rgbd_files import read_color, read_depth_scaled, read_nyu_disparity  # noqa: E402
from raspv_perception import scene_labels as L  # noqa: E402
from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

DATA = ROOT / "tests" / "data" / "rgbd"
PRIMESENSE = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
PCL_KINECT = CameraIntrinsics(640, 480, 525.0, 525.0, 320.0, 240.0)


def frames():
    kinect = sorted((DATA / "kinect_table").glob("*_depth.tiff"))[0]
    return [("TUM desk", read_color(DATA / "tum_color.png"), read_depth_scaled(DATA / "tum_depth.png", 1 / 5000), PRIMESENSE),
            ("NYU basement", read_color(DATA / "nyu_color.ppm"), read_nyu_disparity(DATA / "nyu_depth.pgm"), PRIMESENSE),
            ("Kinect table", read_color(kinect.with_name(kinect.name.replace("_depth", "_rgb"))),
             read_depth_scaled(kinect, 0.001), PCL_KINECT)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "fig9_real_frames.png")
    args = parser.parse_args(argv)
    rows = frames()
    fig, axes = plt.subplots(len(rows), 4, figsize=(12.4, 2.75 * len(rows) + 0.4),
                             gridspec_kw={"width_ratios": [4 / 3, 4 / 3, 1, 1], "hspace": 0.12, "wspace": 0.04})
    fig.subplots_adjust(left=0.07, right=0.995, top=0.93, bottom=0.06)
    for r, (name, rgb, depth, K) in enumerate(rows):
        result = ScenePerception().process(depth, K)
        s = result.structure
        inputs = FrameInputs(color=rgb, depth=depth, camera=K, scene=s, scene_labels=result.labels)
        panels = [rgb, L.colorize(result.labels)]
        for mode in ("chess_floor", "wall_obstacles"):
            sim = PhospheneSimulator(spv_config("optimist", temporal=False, mode=mode, width=300))
            panels.append(sim.render(sim.brightness(sim.levels(inputs))))
        floor = (f"floor {s.camera_height:.2f} m below, pitch {s.camera_pitch_deg:.0f}°, roll {s.camera_roll_deg:.0f}°"
                 if s.floor_found else "no floor (support plane)")
        titles = [name, f"{floor}; {len(s.obstacles)} obstacles", "Chess-Floor", "Wall-Obstacles"]
        for c, (img, title) in enumerate(zip(panels, titles)):
            ax = axes[r, c]
            ax.imshow(img, cmap="gray", vmin=0, vmax=255)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0 or c < 2:
                ax.set_title(title, fontsize=8.5)
        print(f"{name}: {floor}, {len(s.planes)} planes, {len(s.obstacles)} obstacles, {s.processing_ms:.0f} ms")
    handles = [plt.Rectangle((0, 0), 1, 1, color=np.array(L.COLORS[k]) / 255) for k in
               (L.FLOOR, L.FLOOR_BLOCKED, L.WALL, L.HORIZONTAL, L.OBSTACLE, L.OTHER)]
    fig.legend(handles, ["free floor", "blocked floor", "wall", "horizontal", "obstacle", "other"],
               loc="lower center", ncol=6, fontsize=8, frameon=False)
    fig.suptitle("Scene perception and the iconic modes on real RGB-D frames (no pose: tiles in the floor frame)",
                 fontsize=10)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    plt.close(fig)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
