#!/usr/bin/env python
"""The paper's Figs. 14 and 15 (§IV-D): highlighting an object and a person.

Fig. 14 — "find the laptop" in the sim ``office``: RGB with the phosphene positions, the
segmentation (the sim backend's ground-truth classes), downsampling, and downsampling with the
laptop highlighted (``pick: nearest``).
Fig. 15 — turning the head past a walking person in the office corridor: per frame, the RGB,
the person mask of the shipped network with depth fusion, the highlight without temporal
dynamics and with them (the trails).

    .venv/bin/python tools/figures/fig14_15_highlight.py   # → docs/figures/fig14_find_laptop.png, fig15_person_trails.png

Views are rendered at 640×480 (60° camera) and drawn with the ``optimist`` device.
"""
from __future__ import annotations

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

from raspv_perception.class_table import ClassTable  # noqa: E402
from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_perception.segmentation import Segmenter  # noqa: E402
from raspv_perception.segmentation_models import PersonModel  # noqa: E402
from raspv_sim.simulator import SimConfig, Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

OUT = ROOT / "docs" / "figures"
DEVICE = "optimist"
CAMERA = SimConfig(width=640, height=480, hfov_deg=60.0)


def simulator(overlay: bool, temporal: bool, classes: list[str], pick: str = "all") -> PhospheneSimulator:
    return PhospheneSimulator(spv_config(DEVICE, mode="grey", overlays=["highlight"] if overlay else [],
                                         temporal=temporal, width=400,
                                         mode_settings={"highlight.classes": classes, "highlight.pick": pick}))


def with_grid(rgb: np.ndarray, sim: PhospheneSimulator, camera) -> np.ndarray:
    img = rgb.copy()
    s = sim.sampling(camera)
    for u, v in s.uv[s.inside]:
        cv2.circle(img, (int(round(u)), int(round(v))), 4, (30, 255, 30), 1, lineType=cv2.LINE_AA)
    return img


def fig14() -> Path:
    with Simulation("office", CAMERA) as sim:
        frame = sim.render_from(3.0, 6.2, math.radians(80), head_pitch=math.radians(15))
        table = ClassTable.for_world(sim.classes)
    plain, lit = simulator(False, False, ["laptop"]), simulator(True, False, ["laptop"], "nearest")
    inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                         extras={"segmentation": frame.labels, "segmentation_classes": table})
    panels = [("RGB + phosphene positions", with_grid(frame.rgb, plain, frame.intrinsics)),
              ("segmentation (sim ground truth)", table.colorize(frame.labels)),
              ("downsampling", plain.step(inputs).image),
              ("downsampling + laptop highlighted", lit.step(inputs).image)]
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
    for ax, (title, img) in zip(axes, panels):
        ax.imshow(img, cmap="gray", vmin=0, vmax=255)
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    path = OUT / "fig14_find_laptop.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def fig15(frames_shown: int = 5) -> Path:
    segmenter = Segmenter(PersonModel())
    table = segmenter.classes
    flat, dynamic = simulator(True, False, ["person"]), simulator(True, True, ["person"])
    rows = [[], [], [], []]
    with Simulation("office", CAMERA) as sim:
        perception = ScenePerception()
        sim.step(1.0)                                   # the walker is ~2.5 m ahead in the corridor
        n = 40
        show = set(np.linspace(12, n - 1, frames_shown).astype(int))
        for k in range(n):                              # 50 Hz display; a camera frame every 2 ticks
            yaw = math.radians(25.0 - 50.0 * k / (n - 1))   # the head turns from left to right
            frame = sim.render_from(1.0, 6.0, 0.0, head_yaw=yaw)
            scene = perception.process(frame.depth, frame.intrinsics, frame.world_from_camera)
            labels = segmenter.segment(frame.rgb, scene.labels, frame.depth).labels
            inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                                 extras={"segmentation": labels, "segmentation_classes": table})
            a, b = flat.step(inputs), dynamic.step(inputs)
            if k in show:
                mask = np.dstack([labels * 255] * 3).astype(np.uint8)
                for row, img in zip(rows, (frame.rgb, mask, a.image, b.image)):
                    row.append(img)
    titles = ["RGB", "person mask (network + depth)", "highlight, no temporal model", "highlight + temporal model"]
    fig, axes = plt.subplots(4, frames_shown, figsize=(3.2 * frames_shown, 10.5))
    for r, (row, title) in enumerate(zip(rows, titles)):
        for c, img in enumerate(row):
            ax = axes[r, c]
            ax.imshow(img, cmap="gray", vmin=0, vmax=255)
            ax.axis("off")
            if c == 0:
                ax.set_title(title, fontsize=10, loc="left")
    fig.tight_layout()
    path = OUT / "fig15_person_trails.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    print(fig14())
    print(fig15())
