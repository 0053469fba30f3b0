#!/usr/bin/env python
"""The paper's Fig. 9: four frames of a walk through the sim ``apartment`` (corridor → living
room) as RGB with the phosphene positions, downsampling, depth, Chess-Floor and Wall-Obstacles,
plus the scene classes the two iconic modes are drawn from.

    .venv/bin/python tools/figures/fig9_apartment.py                  # scripted walk, then the figure
    .venv/bin/python tools/figures/fig9_apartment.py --run RUN_DIR    # from a recorded sim run
    .venv/bin/python tools/figures/fig9_apartment.py --run RUN_DIR --times 2 5 8 11

The figure is always rendered from a recorded run (a ``raspv_sim`` experiment log: the
avatar's base and head at each instant): without ``--run`` the script first walks the avatar
down the corridor into the living room with the head 15° down and logs that run. Every logged
sample is re-rendered (640×480, 60° camera like the paper's Xtion) and goes through scene
perception with the ground-truth pose as prior, as the ``scene`` node would; the four chosen
instants (evenly spread by default) are drawn with the ``optimist`` device (1000 phosphenes,
45° field, close to the paper's 47°). Output: docs/figures/fig9_apartment.png (``--out``).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import cv2  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_perception import scene_labels as L  # noqa: E402
from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_sim.avatar import head_quaternion  # noqa: E402
from raspv_sim.experiment_log import read_trajectory  # noqa: E402
from raspv_sim.simulator import SimConfig, Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

CAMERA = SimConfig(width=640, height=480, hfov_deg=60.0)
DEVICE = "optimist"
ROWS = [("RGB + phosphenes", None), ("downsampling", "grey"), ("depth (≤ 4 m)", "depth"),
        ("Chess-Floor", "chess_floor"), ("Wall-Obstacles", "wall_obstacles"), ("scene classes", None)]


def scripted_walk(log_dir: Path) -> Path:
    """Walk the apartment's corridor into the living room and log it; returns the run dir."""
    with Simulation("apartment", CAMERA) as sim:
        sim.set_head(head_quaternion(0.0, math.radians(15.0), 0.0))
        log = sim.start_log(log_dir, rate=20.0)
        for i in range(240):                              # 12 s at 20 Hz
            x = sim.avatar.x
            sim.step(0.05, 0.7, 0.3 if x > 7.2 else 0.0)    # straight down the corridor, then turn left
        sim.finish_log(plot=False)
        return log.dir


def replay(run_dir: Path, times: list[float] | None):
    """Re-render every logged sample, run scene perception along, keep the chosen instants."""
    meta = json.loads((run_dir / "meta.json").read_text())
    world = meta.get("world_file") or "apartment"
    traj = read_trajectory(run_dir)
    t = np.asarray(traj["t"])
    if len(t) < 4:
        raise SystemExit(f"{run_dir}: the run has {len(t)} trajectory samples, the figure needs at least 4")
    if times is None:
        picks = [int(round(i)) for i in np.linspace(0.08 * (len(t) - 1), len(t) - 1, 4)]
    else:
        picks = [int(np.argmin(np.abs(t - x))) for x in times]
    perception = ScenePerception()
    kept = []
    with Simulation(world, CAMERA) as sim:
        for i in range(max(picks) + 1):
            frame = sim.render_from(traj["x"][i], traj["y"][i], traj["yaw"][i],
                                    traj["head_roll"][i], traj["head_pitch"][i], traj["head_yaw"][i])
            result = perception.process(frame.depth, frame.intrinsics, frame.world_from_camera)
            if i in picks:
                kept.append((float(t[i]), frame, result))
    return kept


def phosphene_panels(kept) -> dict[str, list[np.ndarray]]:
    sims = {mode: PhospheneSimulator(spv_config(DEVICE, temporal=False, mode=mode, width=400,
                                                mode_settings={"max_depth": 4.0, "chess_tile": 0.5}))
            for _, mode in ROWS if mode}
    out: dict[str, list[np.ndarray]] = {m: [] for m in sims}
    for _, frame, result in kept:                      # in time order: Chess-Floor keeps its world axes
        inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                             camera_pose=frame.world_from_camera, scene=result.structure, scene_labels=result.labels)
        for mode, sim in sims.items():
            out[mode].append(sim.render(sim.brightness(sim.levels(inputs))))
    return out


def square(img: np.ndarray) -> np.ndarray:
    """The central H×H part of a camera image: the 45° prosthesis field fits in the 60° camera's
    46.8° × 46.8° centre, so these panels line up with the phosphene images."""
    h, w = img.shape[:2]
    x0 = (w - h) // 2
    return img[:, x0:x0 + h]


def rgb_with_phosphenes(frame) -> np.ndarray:
    sim = PhospheneSimulator(spv_config(DEVICE, temporal=False, mode="grey", width=400))
    s = sim.sampling(frame.intrinsics)
    img = frame.rgb.copy()
    for u, v in s.uv[s.inside]:
        cv2.circle(img, (int(round(u)), int(round(v))), 4, (30, 255, 30), 1, lineType=cv2.LINE_AA)
    return square(img)


def draw(kept, panels, out: Path) -> None:
    n = len(kept)
    fig, axes = plt.subplots(len(ROWS), n, figsize=(2.3 * n + 0.4, 2.3 * len(ROWS) + 0.5),
                             gridspec_kw={"hspace": 0.04, "wspace": 0.04})
    fig.subplots_adjust(left=0.06, right=0.99, top=0.955, bottom=0.035)
    for c, (t, frame, result) in enumerate(kept):
        pos = frame.world_from_camera[:3, 3]
        for r, (title, mode) in enumerate(ROWS):
            ax = axes[r, c]
            if r == 0:
                img = rgb_with_phosphenes(frame)
                ax.set_title(f"t = {t:.1f} s, x = {pos[0]:.1f} m", fontsize=9)
            elif mode:
                img = panels[mode][c]
            else:
                img = square(L.colorize(result.labels))
            ax.imshow(img, cmap="gray", vmin=0, vmax=255, interpolation="antialiased")
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(title, fontsize=9)
    handles = [plt.Rectangle((0, 0), 1, 1, color=np.array(L.COLORS[k]) / 255) for k in
               (L.FLOOR, L.FLOOR_BLOCKED, L.WALL, L.HORIZONTAL, L.OBSTACLE, L.OTHER)]
    fig.legend(handles, ["free floor", "blocked floor", "wall", "horizontal", "obstacle", "other"],
               loc="lower center", ncol=6, fontsize=8, frameon=False, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(f"Walk through the apartment: corridor → living room ({DEVICE}: 1000 phosphenes, 45° field)",
                 fontsize=10, y=0.99)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, help="a recorded sim run directory (experiment log); default: walk and log one")
    parser.add_argument("--times", type=float, nargs=4, metavar="T", help="the four instants to show [s since the run's start]")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "fig9_apartment.png")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        run = args.run
        if run is None:
            run = scripted_walk(Path(tmp))
        elif not (run / "trajectory.csv").is_file():
            print(f"{run}: not a sim run directory (no trajectory.csv)", file=sys.stderr)
            return 2
        kept = replay(run, args.times)
    draw(kept, phosphene_panels(kept), args.out)
    for t, _, result in kept:
        s = result.structure
        print(f"t = {t:5.1f} s: floor {'%.2f m below' % s.camera_height if s.floor_found else 'not found'}, "
              f"{len(s.planes)} planes, {len(s.obstacles)} obstacles, {s.processing_ms:.0f} ms")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
