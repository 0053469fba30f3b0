"""Training the learned virtual patient (torch; :mod:`raspv_experiments.learned_policy` runs it
with onnxruntime): behaviour cloning of the expert's demonstrations
(:mod:`raspv_experiments.demonstrations`).

The network (:class:`PatientNet`, ≈ 25 k weights): the ``G × G`` phosphene image through three
strided 3×3 convolutions (8, 16, 16 channels, ReLU) to a 4 × 4 × 16 code, joined with the goal
features (3), one hidden layer of 64, and ``tanh`` to the command (speed, turning rate as
fractions of the subject's maxima). Loss: mean squared error on the expert's command (turning
weighted ``TURN_WEIGHT``: it decides the path). Adam, minibatches, a validation split by
episode (the last ``val_fraction`` of the episodes, so no frame of a validation walk is
trained on); the weights with the lowest validation loss are kept. Seeded: the same
demonstrations and settings give the same weights (single-threaded torch).
"""
from __future__ import annotations

import json
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch
from torch import nn

from raspv_learn.export import keep_if_it_matches

TURN_WEIGHT = 2.0


class PatientNet(nn.Module):
    def __init__(self, grid: int = 32) -> None:
        super().__init__()
        self.grid = grid
        self.conv = nn.Sequential(
            nn.Conv2d(1, 8, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(8, 16, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(16, 16, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(4), nn.Flatten())
        self.head = nn.Sequential(nn.Linear(16 * 16 + 3, 64), nn.ReLU(), nn.Linear(64, 2), nn.Tanh())

    def forward(self, image: torch.Tensor, goal: torch.Tensor) -> torch.Tensor:
        return self.head(torch.cat([self.conv(image), goal], dim=1))


@dataclass
class PatientTraining:
    epochs: int = 30
    batch: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-5
    val_fraction: float = 0.15
    seed: int = 1


def train_patient(data: dict[str, np.ndarray], settings: PatientTraining | None = None,
                  progress: Callable[[str], None] | None = print) -> tuple[PatientNet, dict[str, Any]]:
    """Behaviour cloning on ``data`` (:func:`~raspv_experiments.demonstrations.load_demonstrations`);
    (the network with the best validation loss, figures)."""
    s = settings or PatientTraining()
    torch.manual_seed(s.seed)
    torch.set_num_threads(1)
    episodes = np.unique(data["episode"])
    n_val = max(1, int(round(len(episodes) * s.val_fraction))) if len(episodes) > 1 else 0
    val_eps = episodes[len(episodes) - n_val:] if n_val else episodes[:0]
    val = np.isin(data["episode"], val_eps)
    image = torch.from_numpy(data["image"].astype(np.float32))[:, None]
    goal = torch.from_numpy(data["goal"].astype(np.float32))
    command = torch.from_numpy(data["command"].astype(np.float32))
    tr, va = np.flatnonzero(~val), np.flatnonzero(val)
    net = PatientNet(int(data["image"].shape[-1]))
    opt = torch.optim.Adam(net.parameters(), lr=s.lr, weight_decay=s.weight_decay)
    weights = torch.tensor([1.0, TURN_WEIGHT])

    def loss_of(idx: np.ndarray) -> torch.Tensor:
        i = torch.from_numpy(idx)
        return (((net(image[i], goal[i]) - command[i]) ** 2) * weights).mean()

    best, best_state, history, started = float("inf"), None, [], time.monotonic()
    for epoch in range(s.epochs):
        net.train()
        order = np.random.default_rng([s.seed, epoch]).permutation(tr)
        total = 0.0
        for k in range(0, len(order), s.batch):
            opt.zero_grad()
            loss = loss_of(order[k:k + s.batch])
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(order[k:k + s.batch])
        net.eval()
        with torch.no_grad():
            vloss = float(loss_of(va)) if len(va) else total / max(len(tr), 1)
        history.append({"epoch": epoch + 1, "train": total / max(len(tr), 1), "val": vloss})
        if vloss < best:
            best, best_state = vloss, {k: v.clone() for k, v in net.state_dict().items()}
        if progress is not None:
            progress(f"epoch {epoch + 1}/{s.epochs}: train {history[-1]['train']:.4f}, validation {vloss:.4f}"
                     f" ({time.monotonic() - started:.0f} s)")
    if best_state is not None:
        net.load_state_dict(best_state)
    net.eval()
    with torch.no_grad():       # a reference: always predicting the mean command
        base = float((((command[va if len(va) else tr] - command[tr].mean(0)) ** 2) * weights).mean())
    figures = {"frames": int(len(command)), "train_frames": int(len(tr)), "val_frames": int(len(va)),
               "episodes": int(len(episodes)), "val_episodes": int(n_val), "best_val_loss": best,
               "mean_command_val_loss": base, "seconds": round(time.monotonic() - started, 1),
               "weights": int(sum(p.numel() for p in net.parameters())), "settings": asdict(s), "history": history}
    return net, figures


def export_patient(net: PatientNet, path: str | Path, metadata: dict[str, Any]) -> float:
    """Write ``net`` to ``path`` as ONNX (atomically) with ``raspv_patient`` metadata; checked:
    onnxruntime must give torch's output to ``raspv_learn.export.EXPORT_TOLERANCE``. Returns the largest difference."""
    import onnx
    import onnxruntime as ort

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.onnx")
    g = net.grid
    rng = np.random.default_rng(0)
    image = torch.from_numpy(rng.random((2, 1, g, g), np.float32))
    goal = torch.from_numpy(rng.random((2, 3), np.float32))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(net.eval(), (image, goal), str(tmp), dynamo=False, opset_version=17,
                          input_names=["image", "goal"], output_names=["command"],
                          dynamic_axes={"image": {0: "batch"}, "goal": {0: "batch"}, "command": {0: "batch"}})
    model = onnx.load(str(tmp))
    entry = model.metadata_props.add()
    entry.key, entry.value = "raspv_patient", json.dumps({"grid": g, **metadata})
    onnx.save(model, str(tmp))
    with torch.no_grad():
        ours = net(image, goal).numpy()
    theirs = ort.InferenceSession(str(tmp), providers=["CPUExecutionProvider"]).run(
        ["command"], {"image": image.numpy(), "goal": goal.numpy()})[0]
    return keep_if_it_matches(tmp, path, ours, theirs)
