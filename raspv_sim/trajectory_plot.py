"""Top-down trajectory of a logged run over the world's occupancy map (matplotlib, Agg; no rclpy)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from raspv_common.occupancy import FREE, OCCUPIED, OccupancyGrid  # noqa: E402
from raspv_sim.experiment_log import read_events, read_trajectory, summarize_run  # noqa: E402


def plot_trajectory(grid: OccupancyGrid, traj: dict[str, list[float]], events: list[dict], goals: list[dict],
                    out_png: str | Path, title: str = "", gaze_every_s: float = 2.0) -> Path:
    """Draw the map, the base path coloured by time, gaze arrows (base yaw + head yaw) every
    ``gaze_every_s`` s, collisions (red crosses), goals (circles, filled when reached)."""
    img = np.full(grid.cells.shape, 0.75)
    img[grid.cells == FREE] = 1.0
    img[grid.cells == OCCUPIED] = 0.15
    h, w = grid.cells.shape
    extent = (grid.origin[0], grid.origin[0] + w * grid.resolution, grid.origin[1], grid.origin[1] + h * grid.resolution)
    aspect = (extent[3] - extent[2]) / (extent[1] - extent[0])
    fig, ax = plt.subplots(figsize=(9, max(3.0, 9 * aspect) + 0.8), dpi=110)
    ax.imshow(img, cmap="gray", vmin=0, vmax=1, origin="lower", extent=extent, interpolation="nearest")
    t = np.asarray(traj["t"])
    x, y = np.asarray(traj["x"]), np.asarray(traj["y"])
    if t.size >= 2:
        segs = np.stack([np.column_stack([x[:-1], y[:-1]]), np.column_stack([x[1:], y[1:]])], axis=1)
        lc = LineCollection(segs, cmap="viridis", linewidths=2.2)
        lc.set_array(t[:-1])
        ax.add_collection(lc)
        fig.colorbar(lc, ax=ax, fraction=0.03, pad=0.01, label="time [s]")
        gaze = np.asarray(traj["yaw"]) + np.asarray(traj["head_yaw"])
        step = max(1, int(round(gaze_every_s / max(np.median(np.diff(t)), 1e-3))))
        idx = np.arange(0, t.size, step)
        ax.quiver(x[idx], y[idx], np.cos(gaze[idx]), np.sin(gaze[idx]), color="tab:orange", scale=30, width=0.003,
                  label="gaze (head) direction")
    if t.size:
        ax.plot(x[0], y[0], "^", color="tab:green", ms=10, label="start")
        ax.plot(x[-1], y[-1], "s", color="tab:red", ms=8, label="end")
    reached = {e["name"] for e in events if e.get("event") == "goal"}
    for g in goals:
        done = g["name"] in reached
        ax.add_patch(plt.Circle(g["position"], g["radius"], color="tab:blue", alpha=0.35 if done else 1.0,
                                fill=done, lw=1.5))
        ax.annotate(g["name"] + (" ✓" if done else ""), g["position"], color="tab:blue", fontsize=8, ha="center",
                    va="bottom", xytext=(0, 6 + 30 * g["radius"]), textcoords="offset points")
    hits = [e for e in events if e.get("event") == "collision"]
    if hits:
        ax.plot([e["position"][0] for e in hits], [e["position"][1] for e in hits], "x", color="red", ms=9, mew=2,
                label=f"collisions ({len(hits)})")
        for e in hits:
            ax.annotate(e["name"], e["position"][:2], color="red", fontsize=7, xytext=(4, 4), textcoords="offset points")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper left", fontsize=7, framealpha=0.85)
    fig.tight_layout()
    out_png = Path(out_png)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png


def plot_run(run_dir: str | Path, grid: OccupancyGrid, out_png: str | Path | None = None) -> Path:
    """Plot a run directory written by :class:`ExperimentLog` over ``grid``; default output
    ``<run_dir>/trajectory.png``."""
    import json

    run_dir = Path(run_dir)
    meta = json.loads((run_dir / "meta.json").read_text())
    summary = summarize_run(run_dir)
    title = (f"{meta.get('world')} — {summary['duration_s']:.1f} s, path {summary['path_length_m']:.1f} m, "
             f"{summary['collisions']} collision{'s' if summary['collisions'] != 1 else ''}, "
             f"goals {len(summary['goals_reached'])}/{len(summary['goals_reached']) + len(summary['goals_missed'])}")
    return plot_trajectory(grid, read_trajectory(run_dir), read_events(run_dir), meta.get("goals", []),
                           out_png or run_dir / "trajectory.png", title)

