"""Training data from the shipped worlds: RGB, depth, ground-truth classes, scene perception's
classes and camera poses, rendered headless with the simulator core (no ROS, nothing downloaded).

A :class:`DataRecipe` says everything a dataset depends on (worlds for training and for the
held-out test, frames per world, camera, head poses, seed); ``raspv learn dataset CONFIG``
renders it into a folder of shards ``<world>-<k>.npz`` (``shard_frames`` frames each, written
atomically, each from its own seed, so a killed run resumes where it stopped and gives the
same frames) plus ``recipe.yaml``. Per frame:

- a pose: a free cell of the world's occupancy map at least ``clearance_m`` from anything
  static, where the avatar can stand, facing a uniform direction, head pitched down
  U(``pitch_deg``), turned U(±``head_yaw_deg``), rolled N(0, ``roll_sd_deg``); people are put
  where their walks are at a uniform time in [0, 60) s;
- ``rgb`` (H, W, 3) uint8, ``depth_mm`` (H, W) uint16 (0: no reading), ``world_from_camera``
  4×4 (optical frame), ``gt`` (H, W) uint8 walker classes from the simulator's ground-truth
  labels (:data:`WALKER_CLASSES`: floor — floor and rugs —, wall, obstacle — everything else
  a body can bump into, people, doors and stairs included —, none);
- what the live graph's scene node would publish for that depth frame (scene perception core,
  pose prior as the ``scene`` node uses it, a fresh floor track per frame): ``scene_labels``
  (H, W) and the floor and Manhattan axes the Chess-Floor mode needs.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

NONE, FLOOR, WALL, OBSTACLE = 0, 1, 2, 3
WALKER_CLASSES = ("none", "floor", "wall", "obstacle")
FLOOR_NAMES = frozenset({"floor", "rug"})
WALL_NAMES = frozenset({"wall"})
FORMAT_VERSION = 1


class DataError(ValueError):
    """A dataset or recipe that cannot be used (one line)."""


@dataclass(frozen=True)
class DataRecipe:
    """What a dataset depends on. Angles in degrees, lengths in metres, sizes in px."""

    train_worlds: tuple[str, ...] = ("apartment", "stairs")
    test_worlds: tuple[str, ...] = ("office",)
    frames_per_world: int = 1200
    test_frames_per_world: int = 600
    width: int = 320
    height: int = 240
    hfov_deg: float = 60.0
    renderer: str = "auto"
    pitch_deg: tuple[float, float] = (0.0, 45.0)
    head_yaw_deg: float = 30.0
    roll_sd_deg: float = 3.0
    clearance_m: float = 0.35
    min_free_ahead_m: float = 1.0
    shard_frames: int = 100
    seed: int = 0
    # the depth camera's realism (raspv_sim.depth_sensor.DepthSensorConfig settings); None: the
    # simulator's perfect depth. With it, ``depth_mm`` is what the sensor reads (noise, holes) and
    # ``true_depth_mm`` the perfect depth the targets are drawn with
    depth_sensor: Mapping[str, float] | None = None

    def values(self) -> dict:
        """The recipe as plain values (``depth_sensor`` left out when None: recipes from before it
        keep their keys)."""
        out = asdict(self)
        if out["depth_sensor"] is None:
            out.pop("depth_sensor")
        else:
            out["depth_sensor"] = dict(sorted(out["depth_sensor"].items()))
        return out

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], where: str = "data") -> "DataRecipe":
        known = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(values) - known)
        if unknown:
            raise DataError(f"{where}: unknown key(s) {', '.join(unknown)} (allowed: {', '.join(sorted(known))})")
        kw = dict(values)
        for k in ("train_worlds", "test_worlds", "pitch_deg"):
            if k in kw:
                kw[k] = tuple(kw[k]) if isinstance(kw[k], (list, tuple)) else (kw[k],)
        try:
            recipe = cls(**kw)
        except TypeError as exc:
            raise DataError(f"{where}: {exc}") from None
        recipe.check(where)
        return recipe

    def check(self, where: str = "data") -> None:
        problems = []
        if not self.train_worlds or not self.test_worlds:
            problems.append("needs at least one training world and one held-out test world")
        if set(self.train_worlds) & set(self.test_worlds):
            problems.append(f"world(s) {sorted(set(self.train_worlds) & set(self.test_worlds))} are both training "
                            "and held-out test worlds")
        for name in ("frames_per_world", "test_frames_per_world", "shard_frames", "width", "height"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                problems.append(f"{name} must be a positive integer, got {v!r}")
        if not 0 < self.hfov_deg < 170:
            problems.append(f"hfov_deg must be in (0, 170), got {self.hfov_deg}")
        if len(self.pitch_deg) != 2 or not -80 <= self.pitch_deg[0] <= self.pitch_deg[1] <= 80:
            problems.append(f"pitch_deg must be [low, high] within [-80, 80], got {list(self.pitch_deg)}")
        if self.depth_sensor is not None:
            from raspv_sim.depth_sensor import DepthSensorConfig

            try:
                DepthSensorConfig(**self.depth_sensor)
            except (TypeError, ValueError) as exc:
                problems.append(f"depth_sensor: {exc}")
        if problems:
            raise DataError(f"{where}: " + "; ".join(problems))

    @property
    def camera(self) -> CameraIntrinsics:
        return CameraIntrinsics.from_hfov(self.width, self.height, self.hfov_deg)

    def frames_of(self, world: str) -> int:
        return self.test_frames_per_world if world in self.test_worlds else self.frames_per_world

    def shards(self, world: str) -> list[tuple[int, int]]:
        """(index, frames) of each shard of ``world``."""
        n, size = self.frames_of(world), self.shard_frames
        return [(k, min(size, n - k * size)) for k in range(-(-n // size))]

    def key(self) -> str:
        return hashlib.sha256(json.dumps({"version": FORMAT_VERSION, **self.values()}, sort_keys=True).encode()).hexdigest()[:16]


def walker_class_lut(class_names: tuple[str, ...]) -> np.ndarray:
    """(256,) uint8: sim class id → walker class."""
    lut = np.full(256, OBSTACLE, np.uint8)
    for i, name in enumerate(class_names):
        lut[i] = FLOOR if name in FLOOR_NAMES else WALL if name in WALL_NAMES else NONE if name == "none" else OBSTACLE
    return lut


def shard_path(folder: Path, world: str, index: int) -> Path:
    return Path(folder) / f"{world}-{index:03d}.npz"


# -- rendering ------------------------------------------------------------------------------------
class WorldRenderer:
    """One world's simulation, its free cells and scene perception, for rendering shards."""

    def __init__(self, world: str, recipe: DataRecipe) -> None:
        from scipy.ndimage import distance_transform_edt

        from raspv_common.occupancy import FREE
        from raspv_perception.scene_perception import ScenePerception
        from raspv_sim.occupancy_export import world_occupancy
        from raspv_sim.simulator import SimConfig, Simulation

        self.recipe = recipe
        self.sim = Simulation(world, SimConfig(width=recipe.width, height=recipe.height, hfov_deg=recipe.hfov_deg,
                                               renderer=recipe.renderer, far=8.0))
        grid = world_occupancy(self.sim.world)
        self.grid = grid
        self.free = grid.cells == FREE
        clear = distance_transform_edt(self.free) * grid.resolution
        self.cells = grid.cell_to_world(np.argwhere(clear >= recipe.clearance_m))
        if len(self.cells) == 0:
            raise DataError(f"world {world}: no free place {recipe.clearance_m} m from every object")
        self.lut = walker_class_lut(self.sim.classes)
        self.perception = ScenePerception()
        self.sensor = None
        if recipe.depth_sensor is not None:
            from raspv_sim.depth_sensor import DepthSensorConfig

            self.sensor = DepthSensorConfig(**recipe.depth_sensor)

    def close(self) -> None:
        self.sim.close()

    def free_ahead(self, x: float, y: float, yaw: float, reach_m: float = 4.0) -> float:
        """Free floor [m] from (x, y) along ``yaw`` on the occupancy map (up to ``reach_m``)."""
        step = self.grid.resolution
        d = np.arange(step, reach_m + step, step)
        rc = self.grid.world_to_cell(np.stack([x + d * math.cos(yaw), y + d * math.sin(yaw)], axis=1))
        inside = self.grid.inside(rc)
        ok = inside.copy()
        ok[inside] = self.free[rc[inside, 0], rc[inside, 1]]
        return float(d[np.argmin(ok)] - step) if not ok.all() else reach_m

    def frame(self, rng: np.random.Generator, sensor=None) -> dict[str, np.ndarray]:
        """One frame drawn with ``rng`` (pose, people); ``sensor`` (a
        :class:`~raspv_sim.depth_sensor.DepthSensorModel` with its own generator, so the poses are
        those of the perfect-depth recipe) degrades the depth when the recipe has a depth sensor."""
        from raspv_sim.avatar import head_quaternion

        r, sim = self.recipe, self.sim
        sim.world.update_people(float(rng.uniform(0.0, 60.0)))
        for _ in range(1000):
            x, y = self.cells[rng.integers(len(self.cells))] + rng.uniform(-0.025, 0.025, 2)
            yaw = float(rng.uniform(-math.pi, math.pi))
            if self.free_ahead(x, y, yaw) < r.min_free_ahead_m:
                continue
            sim.avatar.teleport(x, y, yaw)
            if sim.avatar.placement_problem() is None:
                break
        else:
            raise DataError(f"world {sim.spec.name}: no place found where the avatar can stand")
        sim.set_head(head_quaternion(math.radians(rng.normal(0.0, r.roll_sd_deg)),
                                     math.radians(rng.uniform(*r.pitch_deg)),
                                     math.radians(rng.uniform(-r.head_yaw_deg, r.head_yaw_deg))))
        T = sim.avatar.world_from_camera()
        raw = sim.camera.render(T, body=True)               # as Simulation.render, keeping the bodies
        body = np.clip(raw.body + 1, 0, len(sim.world.class_lut) - 1)
        true_depth = np.asarray(raw.depth, np.float32)
        depth = true_depth
        if sensor is not None:
            depth = sensor.apply(true_depth, raw.rgb, sim.world.specular_lut[body])
        labels, intrinsics = sim.world.class_lut[body], sim.camera.intrinsics
        self.perception.reset()
        result = self.perception.process(depth, intrinsics, T)
        s = result.structure
        out = {"depth_mm": to_mm(depth)}
        if sensor is not None:
            out["true_depth_mm"] = to_mm(true_depth)
        return {**out, "rgb": raw.rgb,
                "gt": self.lut[labels], "scene_labels": result.labels.astype(np.uint8),
                "world_from_camera": np.asarray(T, np.float32),
                "floor_found": np.bool_(s.floor_found), "floor_plane": np.asarray(s.floor_plane, np.float32),
                "camera_to_floor": np.asarray(s.camera_to_floor, np.float32),
                "manhattan_found": np.bool_(s.manhattan_found),
                "manhattan_x": np.asarray(s.manhattan_x, np.float32), "manhattan_z": np.asarray(s.manhattan_z, np.float32)}


def to_mm(depth: np.ndarray) -> np.ndarray:
    """(H, W) float metres (NaN or <= 0: no reading) → uint16 mm (0: no reading)."""
    ok = np.isfinite(depth) & (depth > 0)
    return np.where(ok, np.rint(np.where(ok, depth, 0) * 1000), 0).astype(np.uint16)


def shard_seed(recipe: DataRecipe, world: str, index: int) -> np.random.SeedSequence:
    digest = int(hashlib.sha256(f"{world}/{index}".encode()).hexdigest()[:8], 16)
    return np.random.SeedSequence([recipe.seed, digest])


def render_dataset(recipe: DataRecipe, folder: str | Path, progress: bool = True) -> Path:
    """Render the shards of ``recipe`` missing in ``folder`` (resumes a killed run); returns
    the folder. Raises :class:`DataError` when the folder holds another recipe's data."""
    from tqdm import tqdm

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    recipe_file = folder / "recipe.yaml"
    if recipe_file.exists():
        existing = read_recipe(folder)
        if existing != recipe:
            raise DataError(f"{folder}: holds a dataset of another recipe ({existing.key()} vs {recipe.key()}); "
                            "choose another folder or delete it")
    else:
        _write_recipe(folder, recipe)
    todo = [(w, k, n) for w in (*recipe.train_worlds, *recipe.test_worlds) for k, n in recipe.shards(w)
            if not shard_path(folder, w, k).exists()]
    total = sum(n for _, _, n in todo)
    bar = tqdm(total=total, unit="frame", desc="rendering", disable=not progress, dynamic_ncols=True)
    renderers: dict[str, WorldRenderer] = {}
    try:
        for world, k, n in todo:
            if world not in renderers:
                for other in list(renderers):
                    renderers.pop(other).close()
                renderers[world] = WorldRenderer(world, recipe)
            bar.set_postfix_str(f"{world} shard {k}")
            seed = shard_seed(recipe, world, k)
            rng = np.random.default_rng(seed)
            sensor = None
            if renderers[world].sensor is not None:
                from raspv_sim.depth_sensor import DepthSensorModel

                sensor = DepthSensorModel(renderers[world].sensor, recipe.camera.fx,
                                          seed=int(np.random.SeedSequence([*seed.entropy, 1]).generate_state(1)[0]))
            frames = []
            for _ in range(n):
                frames.append(renderers[world].frame(rng, sensor))
                bar.update(1)
            _write_shard(shard_path(folder, world, k), {key: np.stack([f[key] for f in frames]) for key in frames[0]})
    finally:
        bar.close()
        for r in renderers.values():
            r.close()
    return folder


def _write_shard(path: Path, arrays: dict[str, np.ndarray]) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_recipe(folder: Path, recipe: DataRecipe) -> None:
    import yaml

    values = {k: list(v) if isinstance(v, tuple) else v for k, v in recipe.values().items()}
    text = ("# written by raspv learn dataset: what this dataset was rendered from\n"
            + yaml.safe_dump({"format": FORMAT_VERSION, "key": recipe.key(), "recipe": values}, sort_keys=False))
    (folder / "recipe.yaml").write_text(text)


def read_recipe(folder: str | Path) -> DataRecipe:
    import yaml

    path = Path(folder) / "recipe.yaml"
    if not path.exists():
        raise DataError(f"{folder}: no dataset here; render it first: raspv learn dataset CONFIG")
    try:
        data = yaml.safe_load(path.read_text())
        return DataRecipe.from_mapping(data["recipe"], str(path))
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: not a dataset recipe ({type(exc).__name__}: {exc})") from None


# -- reading ----------------------------------------------------------------------------------
@dataclass
class WorldFrames:
    """All frames of one world, arrays stacked along the first axis."""

    world: str
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.arrays["rgb"])

    def depth(self, i: int) -> np.ndarray:
        """(H, W) float32 metres, NaN without a reading: what the depth camera reads."""
        d = self.arrays["depth_mm"][i].astype(np.float32) / 1000.0
        d[d == 0] = np.nan
        return d

    def true_depth(self, i: int) -> np.ndarray:
        """(H, W) float32 metres of the simulator's perfect depth (the read depth when the recipe
        had no depth sensor): what the targets' range is measured on."""
        d = self.arrays.get("true_depth_mm", self.arrays["depth_mm"])[i].astype(np.float32) / 1000.0
        d[d == 0] = np.nan
        return d

    def scene(self, i: int):
        """The scene structure a scene mode reads (floor, Manhattan axes) of frame ``i``."""
        from raspv_perception.scene_structure import SceneStructure

        a = self.arrays
        return SceneStructure(floor_found=bool(a["floor_found"][i]), floor_plane=a["floor_plane"][i].astype(np.float64),
                              camera_to_floor=a["camera_to_floor"][i].astype(np.float64),
                              manhattan_found=bool(a["manhattan_found"][i]),
                              manhattan_x=a["manhattan_x"][i].astype(np.float64),
                              manhattan_z=a["manhattan_z"][i].astype(np.float64))


def load_world(folder: str | Path, recipe: DataRecipe, world: str) -> WorldFrames:
    """Every shard of ``world``; raises :class:`DataError` naming the command when one is missing."""
    parts: dict[str, list[np.ndarray]] = {}
    for k, n in recipe.shards(world):
        path = shard_path(Path(folder), world, k)
        if not path.exists():
            raise DataError(f"{path}: missing; render the dataset first: raspv learn dataset CONFIG")
        try:
            with np.load(path, allow_pickle=False) as f:
                for key in f.files:
                    parts.setdefault(key, []).append(f[key])
        except (OSError, ValueError) as exc:
            raise DataError(f"{path}: unreadable shard ({exc}); delete it and run raspv learn dataset again") from None
    return WorldFrames(world, {k: np.concatenate(v) for k, v in parts.items()})


def iter_worlds(folder: str | Path, worlds: tuple[str, ...]) -> Iterator[WorldFrames]:
    recipe = read_recipe(folder)
    for w in worlds:
        yield load_world(folder, recipe, w)
