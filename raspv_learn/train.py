"""Training: the encoder end to end through the twin, and the computational observer.

End to end (:func:`train_end_to_end`): encoder inputs → encoder → stimulation sampled at each
phosphene's camera pixel → levels ⌊s·(N_L − 1) + ½⌋ (straight through) → the twin's phosphene
images (steady state: what a level held for 10 frames shows with the temporal model on) →
decoder → walker classes on the target grid. Loss: cross-entropy with median-frequency class
weights + ``charge_weight`` · mean(level/(N_L − 1)) over the phosphenes in view — an L1 penalty
on the stimulation, proportional to the charge delivered per frame, the sparsity/charge term of
de Ruyter van Steveninck et al. 2022 and Granley et al. 2022 — ramped up over the first
``charge_warmup`` of the steps, + a starting curriculum ``code_weight`` · mean((s − c)²), c the
walker-class code of each phosphene's own ray (floor 0, walls ½, obstacles 1), annealed to 0
over the first ``code_warmup`` of the steps: a representation regularised towards a target
image, as de Ruyter van Steveninck et al. 2022 do, that the decoder can read from the start.
From a random start the joint training here collapsed to dark images in every try (the decoder
learns the class prior first, and any light then raises the loss), so the curriculum starts it;
the code is only where it starts, the end point is the decoder's objective. Adam, cosine
learning rate.

The observer (:func:`train_observer`): the same decoder architecture, alone, on the images of
fixed levels (a hand-designed mode's, or a frozen encoder's), with the observer's schedule.

Both pick the epoch with the best mean IoU on the validation frames (training worlds only)
and report the held-out worlds' scores of that epoch. Checkpoints are written atomically after
every epoch (a kill loses at most the epoch in progress; ``resume`` continues it with the same
batches: epoch e shuffles with seed (seed, e)). Same seed, same result.
"""
from __future__ import annotations

import copy
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from tqdm import tqdm

from raspv_learn.config import LearnConfig, ObserverSpec
from raspv_learn.metrics import Confusion, class_weights
from raspv_learn.networks import NUM_CLASSES, Decoder, Encoder, quantise_levels, sample_at
from raspv_learn.prepare import Prepared, Split
from raspv_learn.twin import PhospheneTwin


class TrainError(ValueError):
    """A run that cannot start or continue (one line)."""


class Pipeline(nn.Module):
    """Encoder → phosphene levels → twin images → decoder, for one device and camera."""

    def __init__(self, config: LearnConfig, twin: PhospheneTwin, grid: np.ndarray, inside: np.ndarray) -> None:
        super().__init__()
        self.encoder = Encoder(len(config.encoder.channels), config.encoder.features)
        self.decoder = Decoder(config.target.stride_px, config.decoder.features)
        self.twin = twin
        self.num_levels = twin.num_levels
        self.register_buffer("grid", torch.from_numpy(grid))
        self.register_buffer("inside", torch.from_numpy(inside.astype(np.float32)))

    def levels(self, x: torch.Tensor) -> torch.Tensor:
        """(B, N) float levels of encoder inputs (B, C, h, w); 0 outside the camera."""
        return quantise_levels(sample_at(self.encoder(x), self.grid), self.num_levels) * self.inside

    def images(self, levels: torch.Tensor) -> torch.Tensor:
        """(B, 1, H, W) phosphene images of levels (temporal steady state)."""
        return self.twin(levels / (self.num_levels - 1) * self.twin.visible).unsqueeze(1)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        lv = self.levels(x)
        return self.decoder(self.images(lv)), lv


def set_threads(threads: int) -> None:
    torch.set_num_threads(max(1, int(threads)))


def _batches(n: int, size: int, seed: int, epoch: int) -> list[np.ndarray]:
    order = np.random.default_rng([seed, epoch]).permutation(n)
    return [order[i:i + size] for i in range(0, n, size)]


def _targets(split: Split, idx: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(split.targets[idx].astype(np.int64) - 1)      # −1: not scored


def _save(path: Path, state: dict) -> None:
    tmp = path.with_suffix(".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def _evaluate(predict: Callable[[np.ndarray], torch.Tensor], split: Split, batch: int) -> dict[str, float]:
    conf = Confusion()
    with torch.no_grad():
        for i in range(0, len(split), batch):
            idx = np.arange(i, min(len(split), i + batch))
            conf.add(predict(idx), torch.from_numpy(split.targets[idx]))
    return conf.iou()


def confusions_per_frame(predict: Callable[[np.ndarray], torch.Tensor], split: Split, batch: int) -> np.ndarray:
    """(n, 3, 3) int32 confusion matrix of each frame of ``split`` (true class × predicted class
    over the scored cells): what the evaluation's bootstrap pools over resampled frames."""
    out = np.zeros((len(split), NUM_CLASSES, NUM_CLASSES), np.int32)
    with torch.no_grad():
        for i in range(0, len(split), batch):
            idx = np.arange(i, min(len(split), i + batch))
            pred = predict(idx).argmax(1).reshape(len(idx), -1).numpy()
            true = split.targets[idx].reshape(len(idx), -1).astype(np.int64) - 1
            for j in range(len(idx)):
                keep = true[j] >= 0
                out[i + j] = np.bincount(true[j][keep] * NUM_CLASSES + pred[j][keep],
                                         minlength=NUM_CLASSES * NUM_CLASSES).reshape(NUM_CLASSES, NUM_CLASSES)
    return out


@dataclass
class RunResult:
    """Validation and held-out scores of the chosen epoch, and the wall time."""

    best_epoch: int
    val: dict
    test: dict
    seconds: float                  # wall time of the epochs
    cpu_seconds: float = 0.0        # CPU time of the epochs (threads summed): the wall time on idle cores
    test_confusions: np.ndarray | None = None    # (n, 3, 3) per held-out frame (train_observer per_frame=True)


def train_end_to_end(config: LearnConfig, data: Prepared, twin: PhospheneTwin, out_dir: str | Path,
                     resume: bool = False, progress: bool = True, score_test: bool = True
                     ) -> tuple[Pipeline, RunResult]:
    """Train encoder and decoder together; checkpoints in ``out_dir``. Returns the pipeline
    with the best epoch's weights and its scores (``score_test`` False: the held-out worlds are
    not touched, ``test`` is empty — a pre-registered evaluation scores them in compare only)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ckpt = out / "checkpoint.pt"
    t = config.train
    set_threads(t.threads)
    torch.manual_seed(t.seed)
    model = Pipeline(config, twin, data.grid, data.inside)
    opt = torch.optim.Adam([{"params": model.encoder.parameters(), "lr": t.encoder_lr},
                            {"params": model.decoder.parameters(), "lr": t.lr}], weight_decay=t.weight_decay)
    batches_per_epoch = math.ceil(len(data.train) / t.batch_size)
    warmup_steps = max(1.0, t.charge_warmup * t.epochs * batches_per_epoch)
    code_steps = max(1.0, t.code_warmup * t.epochs * batches_per_epoch)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, t.epochs * batches_per_epoch)
    start, history, best, elapsed, cpu = 0, [], {"score": -1.0, "epoch": -1}, 0.0, 0.0
    if ckpt.exists():
        if not resume:
            raise TrainError(f"{out}: holds a run already; continue it with --resume, or choose another --out")
        state = torch.load(ckpt, weights_only=False)
        if state["config_key"] != config.key():
            raise TrainError(f"{ckpt}: was trained with another configuration; choose another --out")
        model.encoder.load_state_dict(state["encoder"])
        model.decoder.load_state_dict(state["decoder"])
        opt.load_state_dict(state["optimizer"])
        sched.load_state_dict(state["scheduler"])
        start, history, best, elapsed = state["epoch"], state["history"], state["best"], state["elapsed_s"]
        cpu = state.get("cpu_s", 0.0)
    weights = class_weights(data.train.targets)
    inputs = torch.from_numpy(data.train.inputs)
    codes = torch.from_numpy(data.train.codes.astype(np.float32))
    inside = model.inside.bool()
    bar = tqdm(total=t.epochs * batches_per_epoch, initial=start * batches_per_epoch, unit="batch",
               desc=f"training {config.name}", disable=not progress, dynamic_ncols=True)
    try:
        for epoch in range(start, t.epochs):
            t0, c0 = time.perf_counter(), time.process_time()
            model.train()
            totals = np.zeros(3)
            for b, idx in enumerate(_batches(len(data.train), t.batch_size, t.seed, epoch)):
                step = epoch * batches_per_epoch + b
                logits, lv = model(inputs[idx].float())
                ce = F.cross_entropy(logits, _targets(data.train, idx), weight=weights, ignore_index=-1)
                charge = (lv[:, inside] / (model.num_levels - 1)).mean()
                loss = ce + min(1.0, step / warmup_steps) * t.charge_weight * charge
                code_weight = t.code_weight * max(0.0, 1.0 - step / code_steps)
                if code_weight > 0:
                    code, scored = codes[idx], torch.isfinite(codes[idx])
                    if scored.any():
                        s = lv / (model.num_levels - 1)
                        loss = loss + code_weight * ((s - torch.nan_to_num(code)) ** 2)[scored].mean()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                sched.step()
                totals += (float(ce.detach()), float(charge.detach()), 1)
                bar.update(1)
                bar.set_postfix_str(f"epoch {epoch + 1}/{t.epochs} ce {totals[0] / totals[2]:.3f} "
                                    f"stim {totals[1] / totals[2]:.3f}")
            model.eval()
            val = _evaluate(lambda i: model(torch.from_numpy(data.val.inputs[i]).float())[0], data.val, 64)
            elapsed += time.perf_counter() - t0
            cpu += time.process_time() - c0
            history.append({"epoch": epoch + 1, "ce": totals[0] / totals[2], "stimulation": totals[1] / totals[2],
                            **{f"val_{k}": v for k, v in val.items()}, "elapsed_s": elapsed, "cpu_s": cpu})
            if val["miou"] > best["score"]:
                best = {"score": val["miou"], "epoch": epoch + 1, "encoder": copy.deepcopy(model.encoder.state_dict()),
                        "decoder": copy.deepcopy(model.decoder.state_dict())}
            _save(ckpt, {"config_key": config.key(), "epoch": epoch + 1, "encoder": model.encoder.state_dict(),
                         "decoder": model.decoder.state_dict(), "optimizer": opt.state_dict(),
                         "scheduler": sched.state_dict(), "history": history, "best": best, "elapsed_s": elapsed,
                         "cpu_s": cpu})
            with open(out / "log.jsonl", "a") as f:
                f.write(json.dumps(history[-1]) + "\n")
    finally:
        bar.close()
    model.encoder.load_state_dict(best["encoder"])
    model.decoder.load_state_dict(best["decoder"])
    model.eval()
    test = (_evaluate(lambda i: model(torch.from_numpy(data.test.inputs[i]).float())[0], data.test, 64)
            if score_test else {})
    val = {k[4:]: v for k, v in history[best["epoch"] - 1].items() if k.startswith("val_")}
    return model, RunResult(best["epoch"], val, test, elapsed, cpu)


def encoder_levels(model: Pipeline, split: Split, batch: int = 64) -> np.ndarray:
    """(n, N) uint8 levels of a trained encoder on every frame of ``split``."""
    out = []
    model.eval()
    with torch.no_grad():
        for i in range(0, len(split), batch):
            out.append(model.levels(torch.from_numpy(split.inputs[i:i + batch]).float()).round().to(torch.uint8))
    return torch.cat(out).numpy()


def ground_truth_levels(split: Split, num_levels: int) -> np.ndarray:
    """(n, N) uint8 levels showing each phosphene's ground-truth walker class (floor off, walls
    half, obstacles full; off where not scored): what the phosphenes can carry to the observer
    when the classes are right — a ceiling for class-coding representations, not a mode."""
    code = np.nan_to_num(split.codes.astype(np.float32), nan=0.0)
    return np.floor(code * (num_levels - 1) + 0.5).astype(np.uint8)


def train_observer(levels: dict[str, np.ndarray], data: Prepared, twin: PhospheneTwin, stride: int, features: int,
                   spec: ObserverSpec, seed: int, threads: int, name: str = "", progress: bool = True,
                   per_frame: bool = False) -> RunResult:
    """A fresh decoder trained on the phosphene images of fixed ``levels`` (``train``, ``val``,
    ``test``: (n, N) uint8 each); the held-out scores of its best validation epoch."""
    set_threads(threads)
    torch.manual_seed(seed)
    decoder = Decoder(stride, features)
    opt = torch.optim.Adam(decoder.parameters(), lr=spec.lr, weight_decay=1e-4)
    per_epoch = math.ceil(len(data.train) / spec.batch_size)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, spec.epochs * per_epoch)
    weights = class_weights(data.train.targets)

    def images(part: str, idx: np.ndarray) -> torch.Tensor:
        with torch.no_grad():
            return twin.render_levels(levels[part][idx]).unsqueeze(1)

    best, history, elapsed, cpu = {"score": -1.0, "epoch": -1}, [], 0.0, 0.0
    with tqdm(total=spec.epochs * per_epoch, unit="batch", desc=f"observer {name}", disable=not progress,
              dynamic_ncols=True) as bar:
        for epoch in range(spec.epochs):
            t0, c0 = time.perf_counter(), time.process_time()
            decoder.train()
            for idx in _batches(len(data.train), spec.batch_size, seed, epoch):
                loss = F.cross_entropy(decoder(images("train", idx)), _targets(data.train, idx), weight=weights,
                                       ignore_index=-1)
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                sched.step()
                bar.update(1)
                bar.set_postfix_str(f"epoch {epoch + 1}/{spec.epochs} ce {float(loss.detach()):.3f}")
            decoder.eval()
            val = _evaluate(lambda i: decoder(images("val", i)), data.val, 64)
            elapsed += time.perf_counter() - t0
            cpu += time.process_time() - c0
            history.append(val)
            if val["miou"] > best["score"]:
                best = {"score": val["miou"], "epoch": epoch + 1, "state": copy.deepcopy(decoder.state_dict())}
    decoder.load_state_dict(best["state"])
    decoder.eval()
    test = _evaluate(lambda i: decoder(images("test", i)), data.test, 64)
    frames = confusions_per_frame(lambda i: decoder(images("test", i)), data.test, 64) if per_frame else None
    return RunResult(best["epoch"], history[best["epoch"] - 1], test, elapsed, cpu, frames)
