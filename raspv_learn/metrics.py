"""Scores of the computational observer: intersection over union of the walker classes, and what
a representation costs in stimulation (active phosphenes, charge)."""
from __future__ import annotations

import numpy as np
import torch

from raspv_learn.networks import NUM_CLASSES

CLASS_NAMES = ("floor", "wall", "obstacle")


class Confusion:
    """Accumulated confusion matrix of the scored cells (target classes 1..3; 0 not scored)."""

    def __init__(self) -> None:
        self.matrix = np.zeros((NUM_CLASSES, NUM_CLASSES), np.int64)

    def add(self, logits: torch.Tensor, targets: torch.Tensor) -> None:
        pred = logits.argmax(1).reshape(-1).cpu().numpy()
        true = targets.reshape(-1).cpu().numpy().astype(np.int64) - 1
        keep = true >= 0
        np.add.at(self.matrix, (true[keep], pred[keep]), 1)

    def iou(self) -> dict[str, float]:
        tp = np.diag(self.matrix).astype(np.float64)
        denom = self.matrix.sum(0) + self.matrix.sum(1) - tp
        iou = np.divide(tp, denom, out=np.full(NUM_CLASSES, np.nan), where=denom > 0)
        out = {f"iou_{name}": float(v) for name, v in zip(CLASS_NAMES, iou)}
        out["miou"] = float(np.nanmean(iou))
        out["accuracy"] = float(tp.sum() / max(1, self.matrix.sum()))
        return out


def class_weights(targets: np.ndarray) -> torch.Tensor:
    """Median-frequency balancing (Eigen & Fergus 2015) of the scored target classes: weight
    median(f)/f_c, so a rare class (obstacles) counts as much as a common one (floor)."""
    counts = np.bincount(targets.reshape(-1), minlength=NUM_CLASSES + 1)[1:].astype(np.float64)
    freq = counts / max(1.0, counts.sum())
    freq = np.where(freq > 0, freq, np.nan)
    w = np.nanmedian(freq) / freq
    return torch.tensor(np.nan_to_num(w, nan=0.0), dtype=torch.float32)


def stimulation_cost(levels: np.ndarray, inside: np.ndarray, num_levels: int, amplitude_ua: float,
                     phase_ms: float) -> dict[str, float]:
    """Mean fraction of the phosphenes in view that are on, and mean charge per frame [nC] of
    one phase of every pulse (level/(N_L−1) · amplitude · phase), over frames ``levels`` (n, N)."""
    lv = np.asarray(levels)[:, np.asarray(inside, bool)].astype(np.float64)
    return {"active_fraction": float((lv > 0).mean()),
            "charge_nc": float((lv / (num_levels - 1)).sum(1).mean() * amplitude_ua * phase_ms)}
