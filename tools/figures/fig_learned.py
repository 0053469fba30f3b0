#!/usr/bin/env python
"""The learned encoders on the held-out office, next to Wall-Obstacles (the best hand-designed mode
in the comparison) and the ground truth the decoder must recover.

    .venv/bin/python tools/figures/fig_learned.py           # → docs/figures/fig_learned.png

Views of the office rendered as ``raspv learn dataset`` renders them (its seed for the test
world), with scene perception; each phosphene image from the live simulator (temporal model
off: the steady state) at the width the encoders were trained at (160 px), for Argus III (240
phosphenes) and Optimist (1260 at this width). The target: the walker classes within 3 m.
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from raspv_bench.learned import office_frames  # noqa: E402
from raspv_learn.dataset import DataRecipe, WorldRenderer  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

VIEWS = 4
DEVICES = ("argus_iii", "optimist")
WALKER_COLOURS = np.array([[0, 0, 0], [60, 170, 60], [230, 200, 40], [220, 40, 40]], np.uint8)


def ground_truth(count: int) -> list[np.ndarray]:
    """The walker classes of the same views (same seed as office_frames)."""
    renderer = WorldRenderer("office", DataRecipe(train_worlds=("apartment",), test_worlds=("office",)))
    try:
        rng = np.random.default_rng(0)
        return [renderer.frame(rng)["gt"] for _ in range(count)]
    finally:
        renderer.close()


def main() -> None:
    inputs, _ = office_frames(VIEWS)
    truth = ground_truth(VIEWS)
    columns = [("camera", None, None), ("walker classes (target)", None, None)]
    for device in DEVICES:
        for mode in ("wall_obstacles", "learned"):
            columns.append((f"{device}: {mode}", device, mode))
    sims = {(d, m): PhospheneSimulator(spv_config(d, width=160, mode=m, temporal=False,
                                                  mode_settings={"device": d}))
            for _, d, m in columns if d is not None}
    fig, axes = plt.subplots(VIEWS, len(columns), figsize=(2.2 * len(columns), 1.9 * VIEWS))
    for row in range(VIEWS):
        frame = inputs(row)
        for col, (title, device, mode) in enumerate(columns):
            ax = axes[row, col]
            if device is None:
                near = np.nan_to_num(frame.depth, nan=np.inf) <= 3.0
                image = frame.color if col == 0 else WALKER_COLOURS[np.where(near, truth[row], 0)]
                ax.imshow(image)
            else:
                ax.imshow(sims[(device, mode)].step(frame).image, cmap="gray", vmin=0, vmax=255)
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(title, fontsize=8)
    fig.suptitle("Held-out office; target within 3 m: floor green, wall yellow, obstacle red", fontsize=9)
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "fig_learned.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
