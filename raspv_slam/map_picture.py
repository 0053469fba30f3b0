"""A top-down picture of a SLAM map: floor-projected occupancy, keyframe trajectory, loop and
covisibility edges (no ROS). Axes are the map frame's x and y in metres (gravity-aligned once
the map is anchored to a floor; otherwise the level first camera's frame)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from raspv_common.occupancy import FREE, OCCUPIED
from raspv_slam.slam_map import SlamMap


def draw_map(slam_map: SlamMap, path: str | Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from raspv_slam.floor_occupancy import floor_occupancy

    poses = {k: slam_map.world_from_slam @ p for k, p in slam_map.poses().items()}
    xy = {k: p[:2, 3] for k, p in poses.items()}
    fig, ax = plt.subplots(figsize=(8, 8))
    if slam_map.anchored:
        grid = floor_occupancy(slam_map)
        image = np.full(grid.shape, 0.75)
        image[grid.cells == FREE] = 1.0
        image[grid.cells == OCCUPIED] = 0.0
        rows, cols = grid.shape
        ax.imshow(image, cmap="gray", vmin=0, vmax=1, origin="lower", interpolation="nearest",
                  extent=(grid.origin[0], grid.origin[0] + cols * grid.resolution,
                          grid.origin[1], grid.origin[1] + rows * grid.resolution))
    for e in slam_map.edges:
        if e.kind == "covisibility" and e.a in xy and e.b in xy:
            ax.plot(*np.stack([xy[e.a], xy[e.b]]).T, "-", color="#8fb3d9", lw=0.5, zorder=2)
    for e in slam_map.edges:
        if e.kind == "loop" and e.a in xy and e.b in xy:
            ax.plot(*np.stack([xy[e.a], xy[e.b]]).T, "-", color="#d62728", lw=1.2, zorder=3)
    ids = sorted(xy)
    if ids:
        path_xy = np.array([xy[k] for k in ids])
        ax.plot(path_xy[:, 0], path_xy[:, 1], "-", color="#1f77b4", lw=1.5, zorder=4, label="keyframes")
        ax.scatter(path_xy[:, 0], path_xy[:, 1], s=10, color="#1f77b4", zorder=5)
        heading = np.array([poses[k][:2, 2] for k in ids])          # optical axis on the floor
        norm = np.maximum(np.linalg.norm(heading, axis=1, keepdims=True), 1e-9)
        ax.quiver(path_xy[:, 0], path_xy[:, 1], *(heading / norm).T, angles="xy", scale_units="xy", scale=8,
                  width=0.002, color="#1f77b4", zorder=5)
        ax.scatter(*path_xy[0], s=60, marker="o", facecolor="none", edgecolor="green", zorder=6, label="first keyframe")
    ax.plot([], [], "-", color="#d62728", label="loop edges")
    ax.plot([], [], "-", color="#8fb3d9", label="covisibility edges")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (map)")
    ax.set_ylabel("y [m] (map)")
    n_loops = sum(e.kind == "loop" for e in slam_map.edges)
    ax.set_title(f"{title}: {len(slam_map)} keyframes, {n_loops} loop edges"
                 + ("" if slam_map.anchored else " (not anchored: no occupancy)"))
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
