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


def draw_alignment(slam_grid, building, alignment, path: str | Path, title: str = "") -> None:
    """The SLAM map's floor occupancy (M) drawn on the building map (B) where ``alignment``
    (B ← M) places it: building walls black, free floor white; the SLAM map's occupied cells red,
    its free cells light blue. Axes: B's x and y [m]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, cols = building.shape
    image = np.full(building.shape, 0.75)
    image[building.cells == FREE] = 1.0
    image[building.cells == OCCUPIED] = 0.0
    T = alignment.matrix()

    def placed(value: int) -> np.ndarray:
        xy = slam_grid.cell_to_world(np.argwhere(slam_grid.cells == value))
        return xy @ T[:2, :2].T + T[:2, 3] if len(xy) else np.zeros((0, 2))

    fig, ax = plt.subplots(figsize=(9, 9 * rows / max(cols, 1) + 1))
    ax.imshow(image, cmap="gray", vmin=0, vmax=1, origin="lower", interpolation="nearest",
              extent=(building.origin[0], building.origin[0] + cols * building.resolution,
                      building.origin[1], building.origin[1] + rows * building.resolution))
    free, occ = placed(FREE), placed(OCCUPIED)
    size = max(0.5, 72 * slam_grid.resolution / max(rows, cols) * 60)
    ax.scatter(free[:, 0], free[:, 1], s=size, marker="s", color="#9ecae1", alpha=0.35, lw=0, label="SLAM map: floor")
    ax.scatter(occ[:, 0], occ[:, 1], s=size, marker="s", color="#d62728", lw=0, label="SLAM map: walls, obstacles")
    ax.scatter([alignment.x], [alignment.y], s=60, marker="o", facecolor="none", edgecolor="green",
               label="SLAM map origin")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (building map)")
    ax.set_ylabel("y [m] (building map)")
    ax.set_title(f"{title}: x {alignment.x:.2f} m, y {alignment.y:.2f} m, yaw {alignment.yaw_deg:.1f}°, "
                 f"score {alignment.score:.2f}, matched {alignment.matched:.0%}")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
