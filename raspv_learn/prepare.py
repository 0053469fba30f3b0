"""A dataset made ready for one device: encoder inputs, targets and the hand-designed modes' levels.

Everything here depends only on the dataset and the configuration, so it is computed once per
run with the live code (numpy): the encoder's input grid with
:func:`raspv_spv.modes.learned.encoder_inputs` (what the live mode feeds the network), the
phosphenes' camera pixels with :class:`raspv_spv.sampling.Sampling` (what every live mode
samples at), the levels of each hand-designed mode with the live
:class:`~raspv_spv.simulator.PhospheneSimulator` and the frame's scene perception (as the
``scene`` node would publish it), and the targets: per cell of ``stride_px`` phosphene-image
pixels, the ground-truth walker class of the cell centre's ray within ``range_m`` (of the
simulator's perfect depth: with a depth-sensor recipe the inputs and the modes see the sensor's
depth, the targets stay the truth).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from raspv_learn.config import LearnConfig
from raspv_learn.dataset import FLOOR, NONE, OBSTACLE, WALL, WorldFrames, load_world, read_recipe
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.learned import encoder_inputs, input_size
from raspv_spv.sampling import Sampling
from raspv_spv.simulator import PhospheneSimulator


# the stimulation a phosphene starts from in training: floor off, walls half, obstacles full
CLASS_CODE = {FLOOR: 0.0, WALL: 0.5, OBSTACLE: 1.0}


@dataclass
class Split:
    """Frames of one part of the data (train, val or test)."""

    inputs: np.ndarray                 # (n, C, h, w) float16 encoder inputs
    targets: np.ndarray                # (n, th, tw) uint8: walker class 1..3, 0 not scored
    codes: np.ndarray                  # (n, N) float16: CLASS_CODE of each phosphene's ray, NaN not scored
    levels: dict[str, np.ndarray] = field(default_factory=dict)   # mode → (n, N) uint8

    def __len__(self) -> int:
        return len(self.targets)


@dataclass
class Prepared:
    """The splits and the geometry shared by every frame (one camera for the whole dataset)."""

    train: Split
    val: Split
    test: Split
    grid: np.ndarray                   # (N, 2) phosphene camera pixels, normalised for grid_sample
    inside: np.ndarray                 # (N,) bool: the phosphene's ray is inside the camera
    count: int


def target_map(gt: np.ndarray, depth: np.ndarray, sim: PhospheneSimulator, camera, stride: int,
               range_m: float) -> np.ndarray:
    """(th, tw) uint8 walker classes of one frame on the target grid (0: not scored)."""
    m = sim.map
    th, tw = m.height // stride, m.width // stride
    px, py = np.meshgrid((np.arange(tw) + 0.5) * stride, (np.arange(th) + 0.5) * stride)
    u = (px - m.width / 2.0) / m.focal_px * camera.fx + camera.cx
    v = (py - m.height / 2.0) / m.focal_px * camera.fy + camera.cy
    inside = (u >= -0.5) & (u < camera.width - 0.5) & (v >= -0.5) & (v < camera.height - 0.5)
    cols = np.clip(np.rint(u), 0, camera.width - 1).astype(np.intp)
    rows = np.clip(np.rint(v), 0, camera.height - 1).astype(np.intp)
    d = depth[rows, cols]
    scored = inside & np.isfinite(d) & (d <= range_m)
    return np.where(scored, gt[rows, cols], NONE).astype(np.uint8)


def phosphene_codes(gt: np.ndarray, depth: np.ndarray, sampling: Sampling, range_m: float) -> np.ndarray:
    """(N,) float16 :data:`CLASS_CODE` of the walker class at each phosphene's camera pixel; NaN
    outside the camera, without depth or beyond ``range_m``."""
    code = np.full(256, np.nan, np.float32)
    for cls, value in CLASS_CODE.items():
        code[cls] = value
    d = depth[sampling.rows, sampling.cols]
    scored = sampling.inside & np.isfinite(d) & (d <= range_m)
    return np.where(scored, code[gt[sampling.rows, sampling.cols]], np.nan).astype(np.float16)


def phosphene_grid(sim: PhospheneSimulator, camera) -> tuple[np.ndarray, np.ndarray]:
    """((N, 2) normalised grid_sample coordinates of the phosphenes' camera pixels, (N,) inside)."""
    s = Sampling.build(sim.map, camera)
    grid = np.stack([2.0 * (s.uv[:, 0] + 0.5) / camera.width - 1.0, 2.0 * (s.uv[:, 1] + 0.5) / camera.height - 1.0], 1)
    return np.nan_to_num(grid).astype(np.float32), s.inside.copy()


def _world_part(config: LearnConfig, frames: WorldFrames, camera, sim: PhospheneSimulator, modes: tuple[str, ...],
                bar) -> Split:
    size = input_size(camera, config.encoder.focal_px)
    n = len(frames)
    a = frames.arrays
    inputs = np.empty((n, len(config.encoder.channels), size[1], size[0]), np.float16)
    sampling = Sampling.build(sim.map, camera)
    codes = np.empty((n, sim.count), np.float16)
    targets = []
    mode_sims = {m: sim.variant(m, ()) for m in modes}         # fresh mode state (Chess-Floor's axes) per world
    levels = {m: np.empty((n, sim.count), np.uint8) for m in modes}
    for i in range(n):
        depth, true_depth = frames.depth(i), frames.true_depth(i)       # read by the camera; perfect
        inputs[i] = encoder_inputs(a["rgb"][i], depth, a["scene_labels"][i], size, config.encoder.channels)
        targets.append(target_map(a["gt"][i], true_depth, sim, camera, config.target.stride_px,
                                  config.target.range_m))
        codes[i] = phosphene_codes(a["gt"][i], true_depth, sampling, config.target.range_m)
        if modes:
            frame = FrameInputs(color=a["rgb"][i], depth=depth, camera=camera,
                                camera_pose=a["world_from_camera"][i].astype(np.float64), scene=frames.scene(i),
                                scene_labels=a["scene_labels"][i])
            for m, ms in mode_sims.items():
                levels[m][i] = ms.levels(frame)
        bar.update(1)
    return Split(inputs, np.stack(targets), codes, levels)


def _concat(parts: list[Split]) -> Split:
    return Split(np.concatenate([p.inputs for p in parts]), np.concatenate([p.targets for p in parts]),
                 np.concatenate([p.codes for p in parts]),
                 {m: np.concatenate([p.levels[m] for p in parts]) for m in parts[0].levels})


def _take(split: Split, idx: np.ndarray) -> Split:
    return Split(split.inputs[idx], split.targets[idx], split.codes[idx], {m: v[idx] for m, v in split.levels.items()})


def prepare(config: LearnConfig, data_dir, modes: tuple[str, ...] = (), progress: bool = True) -> Prepared:
    """Encoder inputs, targets and the ``modes``' levels of every frame of the dataset in
    ``data_dir`` (which must hold ``config.data``); the training worlds' frames split into
    train and val by ``config.train.seed``."""
    return split_by_seed(prepare_frames(config, data_dir, modes, progress), config.train.seed,
                         config.train.val_fraction)


@dataclass
class PreparedFrames:
    """Every frame prepared, before the training worlds' frames are split into train and val."""

    train_all: Split
    test: Split
    grid: np.ndarray
    inside: np.ndarray
    count: int


def prepare_frames(config: LearnConfig, data_dir, modes: tuple[str, ...] = (), progress: bool = True
                   ) -> PreparedFrames:
    """:func:`prepare` without the split (it does not depend on the training seed)."""
    from raspv_learn.dataset import DataError

    recipe = read_recipe(data_dir)
    if recipe != config.data:
        raise DataError(f"{data_dir}: holds another recipe than {config.source}'s data section; "
                        f"render it: raspv learn dataset {config.source}")
    camera = recipe.camera
    sim = PhospheneSimulator(config.spv_config())
    total = sum(recipe.frames_of(w) for w in (*recipe.train_worlds, *recipe.test_worlds))
    parts: dict[str, list[Split]] = {"train": [], "test": []}
    with tqdm(total=total, unit="frame", desc=f"preparing {config.name}", disable=not progress,
              dynamic_ncols=True) as bar:
        for split, worlds in (("train", recipe.train_worlds), ("test", recipe.test_worlds)):
            for w in worlds:
                bar.set_postfix_str(w)
                parts[split].append(_world_part(config, load_world(data_dir, recipe, w), camera, sim, modes, bar))
    grid, inside = phosphene_grid(sim, camera)
    return PreparedFrames(_concat(parts["train"]), _concat(parts["test"]), grid, inside, sim.count)


def split_by_seed(frames: PreparedFrames, seed: int, val_fraction: float) -> Prepared:
    """The training worlds' frames split into train and val by ``seed``."""
    train_all = frames.train_all
    order = np.random.default_rng(seed).permutation(len(train_all))
    n_val = int(round(val_fraction * len(train_all)))
    return Prepared(_take(train_all, np.sort(order[n_val:])), _take(train_all, np.sort(order[:n_val])), frames.test,
                    frames.grid, frames.inside, frames.count)
