#!/usr/bin/env python
"""The paper's Fig. 8 and Fig. 12: the navigation assistant in the sim ``office``, find the bin.

A scripted subject (head 20° down) starts at the office's spawn point and walks as the DWA
suggests, while the assistant (the cores the ``planner`` node runs) keeps the costmaps from the
640×480 depth frames and replans with A* at 4 Hz; the office's walker is in the corridor.

- Fig. 8 (``docs/figures/fig08_navigation_costmap.png``): top view when the path bends most
  around the walking person: the global costmap (inflated building map), the live obstacle layer
  and its inflation, the path, the shortest path without the person, the subject and camera.
- Fig. 12 (``docs/figures/fig12_navigation_phosphenes.png``): four instants of the walk, camera
  image with the path and the prosthesis field (top) and the phosphenes (bottom: Wall-Obstacles
  with the path overlay and the guidance marker, ``optimist`` device).

    .venv/bin/python tools/figures/fig08_fig12_navigation.py
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

from raspv_nav.assistant import AssistantConfig, NavigationAssistant  # noqa: E402
from raspv_nav.costmap import inflate_obstacles  # noqa: E402
from raspv_nav.global_planner import path_length  # noqa: E402
from raspv_nav.motion import planar_pose  # noqa: E402
from raspv_nav.obstacle_layer import ObstacleLayerConfig  # noqa: E402
from raspv_perception.scene_perception import ScenePerception  # noqa: E402
from raspv_sim.avatar import head_quaternion  # noqa: E402
from raspv_sim.occupancy_export import world_occupancy  # noqa: E402
from raspv_sim.simulator import SimConfig, Simulation  # noqa: E402
from raspv_spv.config import spv_config  # noqa: E402
from raspv_spv.frame_inputs import FrameInputs  # noqa: E402
from raspv_spv.modes.projected_lines import visible_in_depth  # noqa: E402
from raspv_spv.simulator import PhospheneSimulator  # noqa: E402

CAMERA = SimConfig(width=640, height=480, hfov_deg=60.0)
DEVICE = "optimist"
HEAD_PITCH = math.radians(20.0)
DT = 0.05


def walk(max_s: float = 60.0):
    """Run the scripted subject to the bin; returns the building grid and per-step records."""
    records = []
    with Simulation("office", CAMERA) as sim:
        sim.set_head(head_quaternion(0.0, HEAD_PITCH, 0.0))
        grid = world_occupancy(sim.world, 0.05, structure_only=True)
        goal = np.array(sim.spec.goals[0].position)
        nav = NavigationAssistant(grid, goal, AssistantConfig(obstacles=ObstacleLayerConfig(max_range=6.0)))
        v = w = 0.0
        status = None
        for i in range(int(max_s / DT)):
            report = sim.step(DT, v, w)
            frame = sim.render()
            nav.add_depth(frame.depth, frame.intrinsics, frame.world_from_camera, frame.t)
            nav.set_subject(frame.t, *planar_pose(sim.avatar.world_from_base(), 0))
            if i % 5 == 0:
                status = nav.replan()
            if i % 2 == 0:
                nav.costmap_state()
                hint = nav.velocity_hint((sim.linear, sim.angular))
                v, w = hint.linear, hint.angular
            walker = sim.world.people[0].loop.pose_at(sim.t)
            records.append({"t": sim.t, "frame": frame, "path": None if status.path is None else status.path.copy(),
                            "live": nav.costmap.obstacle_layer.occupied().copy(), "walker": walker[:2],
                            "subject": (sim.avatar.x, sim.avatar.y, sim.avatar.yaw), "plan": status.plan,
                            "guidance": nav.guidance()})
            if report.goals_reached:
                break
        collisions = sim.monitor.count
    return grid, goal, nav, records, collisions


def fig8(grid, goal, nav, records, out: Path) -> None:
    costmap = nav.costmap
    # the replan whose path bends most around the person within 5 m of the subject (detours
    # through other rooms, when the person and the printer close the corridor, are left out)
    def bend(r):
        p = r["path"]
        if p is None or len(p) < 2:
            return -1.0
        shortest = nav.planner.plan(r["subject"][:2], goal, costmap.static).path
        if path_length(p) > path_length(shortest) + 1.0:
            return -1.0
        dense = np.concatenate([np.linspace(a, b, 40) for a, b in zip(p, p[1:])])
        near = dense[np.linalg.norm(dense - r["subject"][:2], axis=1) < 5.0]
        ref = np.concatenate([np.linspace(a, b, 40) for a, b in zip(shortest, shortest[1:])])
        return float(np.min(np.linalg.norm(near[:, None] - ref[None], axis=2), axis=1).max()) if len(near) else -1.0
    def person_ahead(r):
        rel = np.asarray(r["walker"]) - r["subject"][:2]
        ahead = rel @ [math.cos(r["subject"][2]), math.sin(r["subject"][2])]
        return 1.0 < ahead < 4.5 and np.linalg.norm(rel) < 4.5
    candidates = [r for r in records[::5] if person_ahead(r)]
    best = max(candidates, key=bend)
    static_path = nav.planner.plan(best["subject"][:2], goal, costmap.static).path
    state = inflate_obstacles(costmap.static_obstacles | best["live"], grid.resolution, costmap.config,
                              costmap.unknown)
    values = state.occupancy_values().astype(float)
    rgb = np.ones(grid.shape + (3,))
    cost = np.where(values > 0, values / 100.0, 0.0)
    rgb[...] = (1.0 - 0.55 * cost)[..., None]                              # inflation: darker grey
    rgb[values == -1] = (0.82, 0.82, 0.88)
    rgb[costmap.static_obstacles & (values != -1)] = (0.1, 0.1, 0.1)
    live_only = state.obstacles & ~costmap.static_obstacles
    ring = (~state.traversable) & ~costmap.static.obstacles & (costmap.static.traversable)
    rgb[ring] = (1.0, 0.75, 0.45)                                          # inscribed around live obstacles
    rgb[live_only] = (0.85, 0.1, 0.1)
    x0, y0 = grid.origin
    extent = (x0, x0 + grid.shape[1] * grid.resolution, y0, y0 + grid.shape[0] * grid.resolution)
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), gridspec_kw={"width_ratios": [1.75, 1]})
    for ax, zoom in zip(axes, (False, True)):
        ax.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
        ax.plot(*static_path.T, "--", color=(0.2, 0.35, 0.9), lw=1.6, label="shortest path, nobody about")
        ax.plot(*best["path"].T, "-", color=(0.0, 0.65, 0.1), lw=2.6, label="path (A*), replanned")
        sx, sy, syaw = best["subject"]
        ax.plot(sx, sy, "o", color=(0.1, 0.3, 0.9), ms=8, label="subject")
        cam = best["frame"].world_from_camera
        _, _, cyaw = planar_pose(cam, axis=2)
        for s in (-1, 1):                                                  # the camera's 60° field, 6 m
            a = cyaw + s * math.radians(30)
            ax.plot([sx, sx + 6 * math.cos(a)], [sy, sy + 6 * math.sin(a)], ":", color=(0.1, 0.3, 0.9), lw=1)
        ax.plot(*best["walker"], "x", color=(0.6, 0.0, 0.6), ms=10, mew=2.5, label="walking person (truth)")
        ax.plot(*goal, "*", color=(0.9, 0.6, 0.0), ms=14, label="goal: the bin")
        if zoom:
            ax.set_xlim(sx - 1.0, sx + 7.0)
            ax.set_ylim(sy - 2.2, sy + 2.2)
            ax.set_title("near the subject: camera obstacles (red), not traversable (orange)", fontsize=9)
        else:
            ax.set_title(f"t = {best['t']:.1f} s: global costmap (building map, inflated) + camera obstacles", fontsize=9)
            ax.legend(loc="upper left", fontsize=7, framealpha=0.9, bbox_to_anchor=(0.0, 0.72))
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal")
    fig.suptitle("Fig. 8 reproduced: the path bends around a walking person (office, A* on the layered costmap)",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"fig 8: t = {best['t']:.1f} s, path {path_length(best['path']):.2f} m vs shortest "
          f"{path_length(static_path):.2f} m; wrote {out}")


def square(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    x0 = (w - h) // 2
    return img[:, x0:x0 + h]


def camera_view(record, sim: PhospheneSimulator) -> np.ndarray:
    """The camera image with the path (green) and the phosphenes' field (their outermost rays)."""
    frame = record["frame"]
    img = frame.rgb.copy()
    path = record["path"]
    if path is not None and len(path) >= 2:
        from raspv_spv.modes.path_overlay import densify

        pts, _ = densify(np.column_stack([path, np.zeros(len(path))]), 0.05)
        T = frame.world_from_camera
        pc = (pts - T[:3, 3]) @ T[:3, :3]
        u, v, z = frame.intrinsics.project(pc)
        ok = visible_in_depth(pc, FrameInputs(depth=frame.depth, camera=frame.intrinsics), 0.15)   # occluded: not drawn
        for a, b in zip(np.flatnonzero(ok)[:-1], np.flatnonzero(ok)[1:]):
            if b == a + 1:
                cv2.line(img, (int(u[a]), int(v[a])), (int(u[b]), int(v[b])), (0, 220, 0), 4, cv2.LINE_AA)
    s = sim.sampling(frame.intrinsics)
    hull = cv2.convexHull(s.uv[s.inside].astype(np.float32)).astype(np.int32)
    cv2.polylines(img, [hull], True, (255, 255, 0), 2, cv2.LINE_AA)
    return square(img)


def fig12(records, out: Path) -> None:
    n = len(records)
    picks = [records[int(round(f * (n - 1)))] for f in (0.04, 0.3, 0.55, 0.85)]
    perception = ScenePerception()
    sim = PhospheneSimulator(spv_config(DEVICE, temporal=False, mode="wall_obstacles", width=400,
                                        overlays=("path", "guidance")))
    fig, axes = plt.subplots(2, 4, figsize=(11, 5.9), gridspec_kw={"hspace": 0.08, "wspace": 0.04})
    fig.subplots_adjust(left=0.05, right=0.99, top=0.9, bottom=0.02)
    for c, r in enumerate(picks):
        frame = r["frame"]
        result = perception.process(frame.depth, frame.intrinsics, frame.world_from_camera)
        path = r["path"] if r["path"] is not None else np.empty((0, 2))
        inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics,
                             camera_pose=frame.world_from_camera, scene=result.structure,
                             scene_labels=result.labels, extras={"nav_path": path, "nav_guidance": r["guidance"]})
        phosphenes = sim.render(sim.brightness(sim.levels(inputs)))
        axes[0, c].imshow(camera_view(r, sim))
        axes[0, c].set_title(f"t = {r['t']:.1f} s, ({r['subject'][0]:.1f}, {r['subject'][1]:.1f}) m", fontsize=9)
        axes[1, c].imshow(phosphenes, cmap="gray", vmin=0, vmax=255)
        for ax in axes[:, c]:
            ax.set_xticks([])
            ax.set_yticks([])
    axes[0, 0].set_ylabel("camera, visible path (green),\nprosthesis field (yellow)", fontsize=9)
    axes[1, 0].set_ylabel("phosphenes: Wall-Obstacles\n+ path + guidance", fontsize=9)
    fig.suptitle(f"Fig. 12 reproduced: find the bin in the office ({DEVICE}: 1000 phosphenes, 45° field; "
                 "the subject walks as DWA suggests)", fontsize=10)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"fig 12: instants {[round(r['t'], 1) for r in picks]}; wrote {out}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=ROOT / "docs" / "figures")
    args = parser.parse_args(argv)
    grid, goal, nav, records, collisions = walk()
    reached = np.linalg.norm(np.array(records[-1]["subject"][:2]) - goal) < 1.0
    print(f"walk: {records[-1]['t']:.1f} s, goal {'reached' if reached else 'NOT reached'}, {collisions} collisions")
    args.out_dir.mkdir(parents=True, exist_ok=True)
    fig8(grid, goal, nav, records, args.out_dir / "fig08_navigation_costmap.png")
    fig12(records, args.out_dir / "fig12_navigation_phosphenes.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
