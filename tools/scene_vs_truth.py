"""Scene perception's walker classes against the simulator's ground truth, per pixel within a
range, on the frames of a learn dataset — how good the classes are that Wall-Obstacles draws and
the learned encoder reads (docs/learn.md, "Argus III: +5.9 after 10 epochs, +12.9 after 20").

    .venv/bin/python tools/scene_vs_truth.py optimist [--range 3.0]

Scene classes → walker classes as Wall-Obstacles shows them: floor → floor, wall → wall,
horizontal and obstacle → obstacle; `other`, `floor_blocked` and none count as none of them.
Prints each world's IoU per class and, for the held-out worlds, what share of pixels of each
scene class is truly floor, wall or obstacle.
"""
from __future__ import annotations

import argparse

import numpy as np

from raspv_learn.config import load_config
from raspv_learn.dataset import FLOOR, OBSTACLE, WALL, load_world
from raspv_perception import scene_labels as L

CLASSES = ((FLOOR, "floor"), (WALL, "wall"), (OBSTACLE, "obstacle"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="a learn configuration (its data recipe names the dataset)")
    parser.add_argument("--data", help="dataset folder (default data/learn/<recipe key>)")
    parser.add_argument("--range", type=float, default=3.0, help="metres of depth scored (default 3.0)")
    args = parser.parse_args()
    recipe = load_config(args.config).data
    folder = args.data or f"data/learn/{recipe.key()}"
    walker = np.zeros(256, np.uint8)
    walker[L.FLOOR], walker[L.WALL], walker[L.HORIZONTAL], walker[L.OBSTACLE] = FLOOR, WALL, OBSTACLE, OBSTACLE
    for world in (*recipe.train_worlds, *recipe.test_worlds):
        a = load_world(folder, recipe, world).arrays
        depth = a["depth_mm"].astype(np.float32) / 1000.0
        scored = (depth > 0) & (depth <= args.range) & np.isin(a["gt"], [c for c, _ in CLASSES])
        truth, labels = a["gt"][scored], a["scene_labels"][scored]
        seen = walker[labels]
        ious = [f"{n} {np.sum((truth == c) & (seen == c)) / max(1, np.sum((truth == c) | (seen == c))):.3f}"
                for c, n in CLASSES]
        held = " (held out)" if world in recipe.test_worlds else ""
        print(f"{world}{held}: {len(a['gt'])} frames; scene perception vs truth within {args.range:g} m, IoU "
              + ", ".join(ious))
        if held:
            for s in np.unique(labels):
                m = labels == s
                print(f"  scene class {s}: {100 * m.mean():.1f} % of pixels; truly "
                      + ", ".join(f"{n} {100 * np.mean(truth[m] == c):.0f} %" for c, n in CLASSES))


if __name__ == "__main__":
    main()
