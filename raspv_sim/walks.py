"""Simulated hand-held RGB-D walks with ground truth, in the TUM RGB-D layout (no rclpy).

Real sequences (TUM, ETH3D) measure localisation on what a camera sees; a simulator adds what
real data cannot show on demand: loops of known length, a camera covered and carried
elsewhere (a kidnap), and a building map that is exactly the world. A :class:`WalkSpec` is a
route of floor waypoints (W, metres) walked ``loops`` times at ``speed``; the body turns at
corners at a bounded rate (people turn on the spot at a door), the head sways in yaw and looks
down at the floor ahead, as a head-mounted camera does. Kidnaps cover the camera for ``covered_s``
(black colour, no depth) while the subject is carried to another waypoint. A route whose legs
cross a wall or furniture is refused (:mod:`walk_route`): the camera would go through it.

:func:`render_walk` renders every frame (with the realistic depth-sensor model and surface
textures by default) and writes:

- ``rgb/<t>.jpg`` (quality 95: a third of the PNG's size), ``depth/<t>.png`` (uint16, metres ×
  5000, 0 = no reading), ``rgb.txt``,
  ``depth.txt`` — TUM's layout, read by ``raspv bag from-frames`` and ``raspv bench slam``;
- ``groundtruth.txt``: ``t tx ty tz qx qy qz qw``, W ← camera optical, one line per frame;
- ``intrinsics.yaml`` (fx, fy, cx, cy, width, height) and ``walk.yaml`` (the spec, the world,
  the loop-closure times, the kidnaps, the path length).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from raspv_common.text_files import read_yaml_file

TURN_RATE = math.radians(90.0)      # body turn rate at corners [rad/s]


class WalkError(ValueError):
    """A walk that cannot be built; the message names the field."""


@dataclass(frozen=True)
class Kidnap:
    """At ``at_s`` [s] into the walk the camera is covered for ``covered_s`` [s] and the subject
    is carried to route waypoint ``to_waypoint``; the walk resumes from there."""

    at_s: float
    covered_s: float = 3.0
    to_waypoint: int = 0


@dataclass(frozen=True)
class WalkSpec:
    world: str
    waypoints: tuple[tuple[float, float], ...]       # W, metres; the route is closed (back to the first)
    loops: int = 2
    speed: float = 0.8                               # m/s
    rate: float = 30.0                               # frames per second
    head_yaw_deg: float = 12.0                       # amplitude of the head's yaw sway
    head_period_s: float = 5.0
    head_pitch_deg: float = 20.0                     # looking down (floor ahead in view)
    kidnaps: tuple[Kidnap, ...] = ()
    width: int = 640
    height: int = 480
    hfov_deg: float = 60.0
    realistic_depth: bool = True
    textures: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        if len(self.waypoints) < 2:
            raise WalkError("a walk needs at least two waypoints")
        if self.loops < 1 or self.speed <= 0 or self.rate <= 0:
            raise WalkError("loops must be >= 1, speed and rate > 0")
        for k in self.kidnaps:
            if not 0 <= k.to_waypoint < len(self.waypoints):
                raise WalkError(f"kidnap to waypoint {k.to_waypoint}: the route has {len(self.waypoints)} waypoints")
            if k.covered_s <= 0 or k.at_s < 0:
                raise WalkError("kidnap at_s must be >= 0 and covered_s > 0")


@dataclass
class WalkPose:
    t: float
    x: float
    y: float
    yaw: float              # body heading [rad]
    head_yaw: float         # [rad], relative to the body
    head_pitch: float       # [rad], > 0 looks down
    covered: bool = False


@dataclass
class WalkPlan:
    poses: list[WalkPose]
    length_m: float                                        # distance walked (kidnap carries excluded)
    loop_times: list[float] = field(default_factory=list)  # [s] when the walk is back at its start


def load_walk(path: str | Path) -> WalkSpec:
    """A walk from YAML (the keys of :class:`WalkSpec`; kidnaps as a list of mappings)."""
    data = read_yaml_file(path, "walk", WalkError)
    if not isinstance(data, dict):
        raise WalkError(f"{path}: expected a mapping with world and waypoints")
    try:
        kidnaps = tuple(Kidnap(**k) for k in data.pop("kidnaps", []) or [])
        waypoints = tuple((float(x), float(y)) for x, y in data.pop("waypoints"))
        return WalkSpec(waypoints=waypoints, kidnaps=kidnaps, **data)
    except (KeyError, TypeError, ValueError) as exc:
        raise WalkError(f"{path}: {exc}") from None


def plan_walk(spec: WalkSpec) -> WalkPlan:
    """Body and head poses at every frame time of the walk."""
    route = [np.asarray(p, dtype=float) for p in spec.waypoints]
    dt = 1.0 / spec.rate
    poses: list[WalkPose] = []
    t = 0.0
    length = 0.0
    loop_times: list[float] = []
    kidnaps = sorted(spec.kidnaps, key=lambda k: k.at_s)
    pos = route[0].copy()
    seg = route[1] - route[0]
    yaw = math.atan2(seg[1], seg[0])
    target = 1
    loops_done = 0
    while loops_done < spec.loops:
        if kidnaps and t >= kidnaps[0].at_s:
            k = kidnaps.pop(0)
            for _ in range(int(round(k.covered_s * spec.rate))):
                poses.append(_pose(spec, t, pos, yaw, covered=True))
                t += dt
            pos = route[k.to_waypoint].copy()
            target = (k.to_waypoint + 1) % len(route)
            seg = route[target] - pos
            yaw = math.atan2(seg[1], seg[0])
            continue
        poses.append(_pose(spec, t, pos, yaw))
        t += dt
        goal = route[target]
        delta = goal - pos
        want = math.atan2(delta[1], delta[0])
        turn = (want - yaw + math.pi) % (2 * math.pi) - math.pi
        if abs(turn) > math.radians(3.0):                   # turn (on the spot) towards the next waypoint
            yaw += max(-TURN_RATE * dt, min(TURN_RATE * dt, turn))
            continue
        yaw = want
        step = spec.speed * dt
        dist = float(np.linalg.norm(delta))
        if dist <= step:
            pos = goal.copy()
            length += dist
            target = (target + 1) % len(route)
            if target == 1:
                loops_done += 1
                loop_times.append(t)
        else:
            pos = pos + delta / dist * step
            length += step
    poses.append(_pose(spec, t, pos, yaw))
    return WalkPlan(poses, length, loop_times)


def check_route(spec: WalkSpec, grid) -> None:
    """WalkError when a leg of the route crosses a wall or furniture of ``grid`` (the world's
    occupancy map; :mod:`raspv_sim.walk_route`)."""
    from raspv_sim.walk_route import route_obstruction

    blocked = route_obstruction(spec.waypoints, grid)
    if blocked is not None:
        raise WalkError(f"walk in {spec.world}: {blocked.describe()}")


def _pose(spec: WalkSpec, t: float, pos: np.ndarray, yaw: float, covered: bool = False) -> WalkPose:
    sway = math.radians(spec.head_yaw_deg) * math.sin(2 * math.pi * t / spec.head_period_s)
    bob = math.radians(3.0) * math.sin(2 * math.pi * t / (0.5 * spec.head_period_s))
    return WalkPose(t, float(pos[0]), float(pos[1]), yaw, sway, math.radians(spec.head_pitch_deg) + bob, covered)


def render_walk(spec: WalkSpec, output: str | Path, progress=None) -> WalkPlan:
    """Render every frame of ``spec`` into the folder ``output`` (TUM layout, see the module
    docstring). Returns the plan (poses, length, loop times)."""
    from raspv_sim.depth_sensor import DepthSensorConfig
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    out = Path(output)
    plan = plan_walk(spec)
    config = SimConfig(width=spec.width, height=spec.height, hfov_deg=spec.hfov_deg, seed=spec.seed,
                       depth_sensor=DepthSensorConfig() if spec.realistic_depth else None, textures=spec.textures)
    t0 = 1_700_000_000.0                      # a fixed epoch: same walk, same file names
    rgb_lines, depth_lines, gt_lines = [], [], []
    with Simulation(spec.world, config) as sim:
        check_route(spec, world_occupancy(sim.world))
        (out / "rgb").mkdir(parents=True, exist_ok=True)
        (out / "depth").mkdir(parents=True, exist_ok=True)
        K = sim.intrinsics
        for n, p in enumerate(plan.poses):
            if progress is not None:
                progress(n, len(plan.poses))
            sim.world.update_people(p.t)
            frame = sim.render_from(p.x, p.y, p.yaw, 0.0, p.head_pitch, p.head_yaw)
            rgb, depth = frame.rgb, frame.depth
            if p.covered:
                rgb = np.full_like(rgb, 4)
                depth = np.full_like(depth, np.nan)
            stamp = f"{t0 + p.t:.6f}"
            cv2.imwrite(str(out / "rgb" / f"{stamp}.jpg"), rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
            raw = np.where(np.isfinite(depth), np.clip(depth * 5000.0, 0, 65535), 0).astype(np.uint16)
            cv2.imwrite(str(out / "depth" / f"{stamp}.png"), raw)
            rgb_lines.append(f"{stamp} rgb/{stamp}.jpg")
            depth_lines.append(f"{stamp} depth/{stamp}.png")
            T = frame.world_from_camera
            q = Rotation.from_matrix(T[:3, :3]).as_quat()
            gt_lines.append(f"{stamp} {T[0, 3]:.6f} {T[1, 3]:.6f} {T[2, 3]:.6f} {q[0]:.7f} {q[1]:.7f} {q[2]:.7f} {q[3]:.7f}")
    header = f"# simulated walk in {spec.world} (raspv sim walk)\n# timestamp filename\n"
    (out / "rgb.txt").write_text(header + "\n".join(rgb_lines) + "\n")
    (out / "depth.txt").write_text(header + "\n".join(depth_lines) + "\n")
    (out / "groundtruth.txt").write_text("# timestamp tx ty tz qx qy qz qw (world <- camera optical)\n"
                                         + "\n".join(gt_lines) + "\n")
    (out / "intrinsics.yaml").write_text(yaml.safe_dump({"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy,
                                                         "width": K.width, "height": K.height}))
    meta = asdict(spec)
    meta["waypoints"] = [list(w) for w in spec.waypoints]
    meta.update(length_m=round(plan.length_m, 3), frames=len(plan.poses),
                loop_times_s=[round(t, 3) for t in plan.loop_times], epoch_s=t0)
    (out / "walk.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    if progress is not None:
        progress(len(plan.poses), len(plan.poses))
    return plan
