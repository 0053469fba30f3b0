"""Demonstrations for the learned virtual patient (no rclpy, no torch): an expert walks tasks in
:func:`~raspv_experiments.quick_trial.quick_trial` (one process, the same cores as a session)
and every frame becomes one example — what a subject would perceive (the phosphene image, the
goal it was told about relative to its path-integrated pose: :mod:`raspv_experiments.learned_policy`)
and what the expert did there.

The **expert** sees the ground truth: the planner's shortest path (``raspv_nav`` global planner on
the world's occupancy map, for a body of ``EXPERT_RADIUS`` so it keeps a margin) from where the
body really is, replanned when the body is more than ``REPLAN_OFF_M`` off it, followed by pure
pursuit ``LOOKAHEAD_M`` ahead. Its label is its clean command; the command carried out has a
slowly varying perturbation added (an Ornstein–Uhlenbeck process on the turning rate, DART-style
noise injection: Laskey et al. 2017), so the examples include the states off the expert's path
that the learner will drift into, labelled with the way back.

Examples are written as ``.npz`` shards (``image`` (N, G, G) float16, ``goal`` (N, 3), ``command``
(N, 2) in −1..1, ``episode`` (N,)) with a ``recipe.json`` (tasks, spv parameters, seed).
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from raspv_common import shipped
from raspv_experiments.learned_policy import GRID, goal_features
from raspv_experiments.navigate_policy import Navigate, _wrap
from raspv_experiments.policies import PhospheneLayout, PolicyConfig

EXPERT_RADIUS = 0.4        # m: the expert plans for a body this wide (the avatar's is 0.25: a 15 cm margin)
REPLAN_OFF_M = 0.4         # m off its path: the expert plans again from where it is
LOOKAHEAD_M = 0.6          # m ahead on the path: the pure-pursuit point (short: it cuts no box corner)
OU_SIGMA = 0.6             # rad/s / sqrt(s): the perturbation's diffusion
OU_TAU_S = 1.0             # s: its time constant (stationary std. dev. sigma * sqrt(tau / 2) ≈ 0.42 rad/s)


@dataclass(frozen=True)
class DemoTask:
    world: str
    start: tuple[float, float, float]            # x, y [m], yaw [rad] (W)
    goal: tuple[float, float, float]             # x, y, radius [m] (W)
    time_limit: float


@dataclass
class DemoRecipe:
    tasks: list[DemoTask]
    spv: dict[str, Any]
    episodes_per_task: int = 4
    start_jitter: tuple[float, float, float] = (0.3, 0.5, 0.4)   # ± x, y [m], yaw [rad] around each start
    seed: int = 1
    rate: float = 10.0
    size: tuple[int, int] = (160, 120)
    grid: int = GRID
    extra: dict[str, Any] = field(default_factory=dict)


# The representation the shipped learned patient is trained on: the obstacle course protocol's
# (experiments/obstacle_course.yaml: depth, 26 x 26 phosphenes requested on a rectangular grid in 35 deg).
DEFAULT_SPV = {"device": "default", "mode": "depth", "temporal": False, "max_depth": 3.0, "fov_deg": 35.0,
               "grid": "rectangular", "field": "rectangular", "num_phosphenes": 676, "headless": True}


def default_recipe(episodes_per_task: int = 12, seed: int = 1) -> DemoRecipe:
    """The shipped tasks' worlds, from their protocols' starts to their goals: the obstacle course,
    the example's hallway past the crate, the office corridor to the bin in the meeting room."""
    worlds = shipped.EXPERIMENTS_DIR / "worlds"
    tasks = [DemoTask(str(worlds / "obstacle_course.yaml"), (1.0, 1.5, 0.0), (24.0, 1.5, 1.6), 90.0),
             DemoTask(str(worlds / "hallway.yaml"), (1.0, 2.1, 0.0), (8.6, 1.5, 0.8), 40.0),
             DemoTask("office", (10.5, 6.0, 0.0), (19.6, 11.6, 1.3), 60.0)]
    return DemoRecipe(tasks, dict(DEFAULT_SPV), episodes_per_task=episodes_per_task, seed=seed, size=(128, 96))


class _ExpertPlanner:
    """Shortest paths with a margin on a world's occupancy map (built once per world)."""

    def __init__(self, world: str) -> None:
        from raspv_experiments.world_geometry import world_geometry
        from raspv_nav.costmap import CostmapConfig
        from raspv_nav.global_planner import GlobalPlanner

        self.geometry = world_geometry(world)
        self.planner = GlobalPlanner(self.geometry.grid, CostmapConfig(robot_radius=EXPERT_RADIUS, cost_weight=0.0))

    def plan(self, xy: np.ndarray, goal: tuple[float, float, float]) -> np.ndarray:
        from raspv_nav.global_planner import NoPathError

        target = self.geometry.reachable_point(np.asarray(goal[:2], float), goal[2])
        try:
            path = self.planner.plan(np.asarray(xy, float), goal[:2] if target is None else target).path
        except NoPathError:
            return np.empty((0, 2))
        return densify(path, 0.05)


def densify(path: np.ndarray, step: float) -> np.ndarray:
    """The polyline ``path`` (N, 2) resampled every ``step`` m (the planner returns its corners)."""
    if len(path) < 2:
        return path
    seg = np.hypot(*np.diff(path, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = np.linspace(0.0, s[-1], max(2, int(math.ceil(s[-1] / step)) + 1))
    return np.column_stack([np.interp(at, s, path[:, 0]), np.interp(at, s, path[:, 1])])


class Expert(Navigate):
    """Walks the planner's path from the ground truth (set by :meth:`see` before each frame),
    recording (phosphene image, goal features, clean command) per frame."""

    name = "expert"

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None,
                 goal: tuple[float, float] | None = None, planner: _ExpertPlanner | None = None,
                 world_goal: tuple[float, float, float] = (0.0, 0.0, 1.0), grid: int = GRID, **_) -> None:
        super().__init__(layout, config, goal=goal)
        self.planner, self.world_goal, self.grid = planner, world_goal, grid
        self.truth = np.zeros(3)
        self.path = np.empty((0, 2))
        self.ou = 0.0
        self.images: list[np.ndarray] = []
        self.goals: list[np.ndarray] = []
        self.commands: list[np.ndarray] = []
        col = np.clip((layout.x / max(layout.width, 1) * grid).astype(int), 0, grid - 1)
        row = np.clip((layout.y / max(layout.height, 1) * grid).astype(int), 0, grid - 1)
        self.cells = row * grid + col

    def see(self, sim) -> None:
        self.truth = np.array([sim.avatar.x, sim.avatar.y, sim.avatar.yaw])

    def expert_command(self) -> tuple[float, float]:
        c = self.config
        x, y, yaw = self.truth
        if len(self.path) == 0 or np.min(np.hypot(*(self.path - [x, y]).T)) > REPLAN_OFF_M:
            self.path = self.planner.plan(np.array([x, y]), self.world_goal)
        if len(self.path) == 0:
            return 0.0, 0.0
        d = np.hypot(*(self.path - [x, y]).T)
        i = int(np.argmin(d))
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.path[i:], axis=0).T))])
        j = i + int(np.searchsorted(along, LOOKAHEAD_M))         # the path is resampled every 5 cm
        px, py = self.path[min(j, len(self.path) - 1)]
        bearing = float(_wrap(math.atan2(py - y, px - x) - yaw))
        if abs(bearing) > math.radians(50):
            return 0.0, c.max_angular * math.copysign(1.0, bearing)
        v = c.max_linear * max(0.2, math.cos(bearing) ** 2)
        return v, float(np.clip(2.0 * v * math.sin(bearing) / max(math.hypot(px - x, py - y), 0.3),
                                -c.max_angular, c.max_angular))

    def decide(self, b: np.ndarray) -> tuple[float, float]:
        v, w = self.expert_command()
        img = np.zeros(self.grid * self.grid, np.float32)
        np.maximum.at(img, self.cells, b.astype(np.float32))
        c = self.config
        self.images.append(img.reshape(self.grid, self.grid).astype(np.float16))
        self.goals.append(goal_features(self.pose, self.goal))
        self.commands.append(np.array([v / c.max_linear, w / c.max_angular], np.float32))
        dt = self.dt or c.frame_period_s
        self.ou += -self.ou * dt / OU_TAU_S + OU_SIGMA * math.sqrt(dt) * float(self.rng.standard_normal())
        return v, w + self.ou


def collect(recipe: DemoRecipe, folder: str | Path, progress: Callable[[str], None] | None = print) -> dict[str, Any]:
    """Every episode of ``recipe`` (tasks × episodes, starts jittered, seeded): one shard per
    episode in ``folder`` (written as it ends, so a killed collection keeps what it has)."""
    from raspv_experiments.quick_trial import quick_trial

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "recipe.json").write_text(json.dumps(asdict(recipe), indent=1))
    rng = np.random.default_rng(recipe.seed)
    planners: dict[str, _ExpertPlanner] = {}
    frames, successes, started = 0, 0, time.monotonic()
    total = len(recipe.tasks) * recipe.episodes_per_task
    episode = 0
    for task in recipe.tasks:
        planner = planners.setdefault(task.world, _ExpertPlanner(task.world))
        for _ in range(recipe.episodes_per_task):
            episode += 1
            jx, jy, jyaw = recipe.start_jitter
            start = (task.start[0] + rng.uniform(-jx, jx), task.start[1] + rng.uniform(-jy, jy),
                     task.start[2] + rng.uniform(-jyaw, jyaw))
            from raspv_experiments.world_geometry import start_problem

            if start_problem(task.world, *start):
                start = task.start
            shard = folder / f"episode_{episode:04d}.npz"
            if shard.exists():                     # resumed: this episode is on disk
                continue
            holder: dict[str, Expert] = {}

            def make(layout, config, goal, **kw):
                holder["e"] = Expert(layout, config, goal=goal, planner=planner, world_goal=task.goal, grid=recipe.grid)
                return holder["e"]

            config = PolicyConfig(seed=recipe.seed * 100_003 + episode, reaction_time_s=0.0, noise=0.0,
                                  perception_noise=0.0)
            res = quick_trial(task.world, start, task.goal, task.time_limit, spv=recipe.spv, policy=make,
                              config=config, rate=recipe.rate, size=recipe.size,
                              on_frame=lambda sim: holder["e"].see(sim))
            e = holder["e"]
            n = len(e.commands)
            tmp = shard.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, image=np.stack(e.images), goal=np.stack(e.goals), command=np.stack(e.commands),
                                episode=np.full(n, episode, np.int32))
            tmp.replace(shard)
            frames += n
            successes += int(res.success)
            if progress is not None:
                el = time.monotonic() - started
                progress(f"[{episode}/{total}] {Path(task.world).stem}: {n} frames, "
                         f"{'goal' if res.success else 'time limit'}, {res.collisions} collisions "
                         f"(elapsed {el / 60:.1f} min)")
    return {"episodes": total, "frames": frames, "expert_successes": successes}


def load_demonstrations(folder: str | Path) -> dict[str, np.ndarray]:
    """Every shard in ``folder``, concatenated (image, goal, command, episode)."""
    shards = sorted(Path(folder).glob("episode_*.npz"))
    shards = [s for s in shards if not s.name.endswith(".tmp.npz")]
    if not shards:
        raise FileNotFoundError(f"{folder}: no demonstrations (episode_*.npz); collect them first")
    parts = [np.load(s) for s in shards]
    return {k: np.concatenate([p[k] for p in parts]) for k in ("image", "goal", "command", "episode")}
