"""Dataset rendering, end-to-end training (checkpoints, resume, seeds), the comparison and the CLI,
on a tiny dataset rendered from two shipped worlds."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest
import torch
import yaml

from raspv_bringup.cli import main as raspv
from raspv_learn import train as train_module
from raspv_learn.config import ConfigError, config_from_mapping, load_config
from raspv_learn.dataset import DataError, load_world, read_recipe, render_dataset, shard_path
from raspv_learn.prepare import prepare
from raspv_learn.twin import PhospheneTwin

TINY = {"name": "tiny", "device": "argus_iii",
        "data": {"train_worlds": ["stairs"], "test_worlds": ["apartment"], "frames_per_world": 6,
                 "test_frames_per_world": 2, "shard_frames": 3, "width": 160, "height": 120},
        "spv": {"width": 80}, "encoder": {"features": 4, "focal_px": 32.0}, "decoder": {"features": 4},
        "train": {"epochs": 2, "batch_size": 2, "val_fraction": 0.2}, "observer": {"epochs": 1, "batch_size": 2}}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    folder = tmp_path_factory.mktemp("learn")
    path = folder / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    config = load_config(path)
    render_dataset(config.data, folder / "data", progress=False)
    return config, path, folder / "data"


def test_dataset_from_the_shipped_worlds(tiny):
    config, _, data = tiny
    assert read_recipe(data) == config.data
    frames = load_world(data, config.data, "stairs")
    a = frames.arrays
    assert len(frames) == 6 and a["rgb"].shape == (6, 120, 160, 3) and a["depth_mm"].dtype == np.uint16
    assert set(np.unique(a["gt"])) <= {0, 1, 2, 3} and (a["gt"] == 1).any() and (a["gt"] == 2).any()
    assert (a["scene_labels"] > 0).any() and a["world_from_camera"].shape == (6, 4, 4)
    # the eye at 1.6 m, lower as the head pitches down about the neck (0–45°)
    assert np.all((a["world_from_camera"][:, 2, 3] > 1.45) & (a["world_from_camera"][:, 2, 3] < 1.61))
    # a killed run resumes: a missing shard is rendered again, the same frames from its seed
    shard = shard_path(data, "stairs", 1)
    before = dict(np.load(shard))
    shard.unlink()
    render_dataset(config.data, data, progress=False)
    after = np.load(shard)
    for k, v in before.items():
        np.testing.assert_array_equal(after[k], v, err_msg=k)
    other = config_from_mapping({**TINY, "data": {**TINY["data"], "seed": 1}}, "other")
    with pytest.raises(DataError, match="holds a dataset of another recipe"):
        render_dataset(other.data, data, progress=False)


def test_training_resumes_after_a_kill_with_the_same_weights(tiny, tmp_path, monkeypatch):
    config, _, data_dir = tiny
    data = prepare(config, data_dir, progress=False)
    assert len(data.train) + len(data.val) == 6 and len(data.test) == 2
    assert data.train.inputs.shape[1:] == (9, 28, 37)          # the 60° camera on a grid of focal length 32 px
    twin = PhospheneTwin.from_config(config.spv_config())
    whole, result = train_module.train_end_to_end(config, data, twin, tmp_path / "a", progress=False)
    assert 1 <= result.best_epoch <= 2 and set(result.test) >= {"iou_obstacle", "miou"}
    assert len((tmp_path / "a" / "log.jsonl").read_text().splitlines()) == 2

    save = train_module._save
    calls = []

    def killed_after_first_checkpoint(path, state):
        save(path, state)
        calls.append(path)
        raise KeyboardInterrupt

    monkeypatch.setattr(train_module, "_save", killed_after_first_checkpoint)
    with pytest.raises(KeyboardInterrupt):
        train_module.train_end_to_end(config, data, twin, tmp_path / "b", progress=False)
    monkeypatch.setattr(train_module, "_save", save)
    with pytest.raises(train_module.TrainError, match="--resume"):
        train_module.train_end_to_end(config, data, twin, tmp_path / "b", progress=False)
    resumed, again = train_module.train_end_to_end(config, data, twin, tmp_path / "b", resume=True, progress=False)
    assert len(calls) == 1 and again.best_epoch == result.best_epoch
    assert json.dumps(again.test, sort_keys=True) == json.dumps(result.test, sort_keys=True)   # NaN-safe
    for a, b in zip(whole.state_dict().values(), resumed.state_dict().values()):
        torch.testing.assert_close(a, b, rtol=0, atol=0)


def test_train_and_compare_commands(tiny, tmp_path, capsys, monkeypatch):
    _, path, data = tiny
    out = tmp_path / "run"
    assert raspv(["learn", "train", str(path), "--data", str(data), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "result.json").read_text())
    assert summary["phosphenes"] == 240 and summary["onnx_max_diff"] <= 1e-5 and (out / "encoder.onnx").exists()
    assert raspv(["learn", "compare", str(path), "--data", str(data), "--out", str(out), "--quiet",
                  "--modes", "depth", "wall_obstacles"]) == 0
    rows = json.loads((out / "compare.json").read_text())["rows"]
    assert [r["mode"] for r in rows] == ["depth", "wall_obstacles", "learned"]
    assert all(0 <= r["active_fraction"] <= 1 for r in rows)
    table = (out / "compare.md").read_text()
    assert "| learned |" in table and "obstacle IoU" in table
    printed = capsys.readouterr().out
    assert "points obstacle IoU" in printed

    # scored rows are kept when only the encoder's training changes; --ceiling adds the true classes' row
    observed = []
    real = train_module.train_observer
    monkeypatch.setattr(train_module, "train_observer", lambda levels, *a, **k: observed.append(1) or real(levels, *a, **k))
    longer = tmp_path / "longer.yaml"
    longer.write_text(yaml.safe_dump({**TINY, "train": {**TINY["train"], "epochs": 3}}))
    assert raspv(["learn", "compare", str(longer), "--data", str(data), "--out", str(out), "--quiet",
                  "--modes", "depth", "wall_obstacles", "--no-learned", "--ceiling"]) == 0
    assert len(observed) == 1                                         # the ceiling only
    rows = json.loads((out / "compare.json").read_text())["rows"]
    assert [r["mode"] for r in rows] == ["depth", "wall_obstacles", "learned", "ground_truth_classes"]
    printed = capsys.readouterr().out
    assert "| ground_truth_classes (ceiling: the true classes, not a mode) |" in printed


def test_the_shipped_comparisons_print_without_data(capsys):
    for name in ("argus_iii", "optimist"):
        assert raspv(["learn", "compare", name, "--shipped"]) == 0
        printed = capsys.readouterr().out
        assert "| learned |" in printed and "(best hand-designed)" in printed
        assert re.search(r"learned vs best hand-designed \(\w+\): [+-][\d.]+ points obstacle IoU "
                         r"\(target \+10: (met|MISSED)\)", printed)


@pytest.mark.parametrize("change, message", [
    ({"epochs_typo": 3}, "unknown key"),
    ({"device": "argus_iv"}, "unknown device preset"),
    ({"train": {"lr": "fast"}}, "train.lr: must be a float"),
    ({"data": {"train_worlds": ["office"], "test_worlds": ["office"]}}, "both training and held-out"),
    ({"encoder": {"channels": ["grey", "colour"]}}, "encoder.channels: unknown"),
])
def test_bad_configurations_are_one_line_errors(tmp_path, capsys, change, message):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({**TINY, **change}))
    with pytest.raises(ConfigError, match=message):
        load_config(path)
    assert raspv(["learn", "train", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert message.split(":")[0] in err and len(err.splitlines()) == 1


def test_a_missing_dataset_names_the_command(tmp_path, capsys):
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    assert raspv(["learn", "train", str(path), "--data", str(tmp_path / "nothing"), "--quiet"]) == 2
    assert "raspv learn dataset" in capsys.readouterr().err


def test_realistic_depth_dataset_keeps_the_frames_and_the_true_depth(tiny, tmp_path):
    """A recipe with the sim's depth sensor: the same frames as the perfect-depth recipe (the
    sensor has its own generator), the sensor's depth with holes and noise, the perfect depth kept
    for the targets."""
    config, _, perfect_dir = tiny
    sensor = {"noise_at_1m": 0.0014, "baseline": 0.075, "subpixel": 8.0, "edge_jump": 0.04, "edge_width": 1,
              "dark_level": 25, "dark_dropout": 0.6, "specular_dropout": 0.7, "max_range": 6.0}
    real = config_from_mapping({**TINY, "data": {**TINY["data"], "frames_per_world": 3, "test_frames_per_world": 1,
                                                 "depth_sensor": sensor}}, "real")
    assert real.data.key() != config.data.key() and config.key() == load_config(tiny[1]).key()
    render_dataset(real.data, tmp_path, progress=False)
    assert read_recipe(tmp_path) == real.data
    ours, perfect = load_world(tmp_path, real.data, "stairs"), load_world(perfect_dir, config.data, "stairs")
    np.testing.assert_array_equal(ours.arrays["rgb"], perfect.arrays["rgb"][:3])
    np.testing.assert_array_equal(ours.arrays["true_depth_mm"], perfect.arrays["depth_mm"][:3])
    read, true = ours.arrays["depth_mm"], ours.arrays["true_depth_mm"]
    holes = (read == 0) & (true > 0)
    assert 0.001 < holes.mean() < 0.5                                   # edges, dark and shiny surfaces
    both = (read > 0) & (true > 0)
    assert (read[both] != true[both]).mean() > 0.3                      # noise and quantisation
    assert np.abs(read[both].astype(np.int64) - true[both]).mean() < 100   # mm: noise, not garbage
    for i in range(3):
        np.testing.assert_array_equal(ours.true_depth(i), perfect.depth(i))


@pytest.mark.slow
def test_the_pre_registered_scoring_end_to_end(tiny, tmp_path, monkeypatch, capsys):
    """A tiny evaluation: dataset with realistic depth, two seeds trained for it, the scoring of
    both depths (ledger lines, per-frame counts that give the table's numbers), then a model trained
    after the scoring is refused, and scored with --rescore the table says so."""
    import os

    from raspv_learn import ledger as ledger_module
    from raspv_learn.bootstrap import iou_of
    from raspv_learn.evaluation import EVALUATIONS_DIR, configuration_for, load_evaluation

    config, path, data = tiny
    text = (EVALUATIONS_DIR / "grocery.yaml").read_text()
    for old, new in (("name: grocery", "name: tinyeval"), ("test_worlds: [grocery]", "test_worlds: [apartment]"),
                     ("test_frames_per_world: 500", "test_frames_per_world: 2"),
                     ("configurations: [argus_iii, optimist]", "configurations: [tiny]"),
                     ("training_seeds: [0, 1, 2]", "training_seeds: [0, 1]"), ("resamples: 10000", "resamples: 200")):
        assert old in text
        text = text.replace(old, new)
    ev_path = tmp_path / "tinyeval.yaml"
    ev_path.write_text(text)
    ev = load_evaluation(ev_path)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(ledger_module, "LEDGER", tmp_path / "ledger.jsonl")
    perfect = configuration_for(config, ev, 0, "perfect")
    assert perfect.data == config.data                    # the fixture's dataset is the perfect one
    (tmp_path / "data" / "learn").mkdir(parents=True)
    os.symlink(data, tmp_path / "data" / "learn" / perfect.data.key())
    ev_args = ["--evaluation", str(ev_path), "--quiet"]
    assert raspv(["learn", "dataset", str(path), *ev_args]) == 0
    for seed in ("0", "1"):
        assert raspv(["learn", "train", str(path), *ev_args, "--seed", seed]) == 0
    state = torch.load(tmp_path / "runs/learn/tinyeval/tiny-seed1/weights.pt", weights_only=False)
    assert state["evaluation"]["sha256"] == ev.sha256 and state["seed"] == 1 and state["config"]["train"]["seed"] == 1
    assert json.loads((tmp_path / "runs/learn/tinyeval/tiny-seed1/result.json").read_text())["test"] == {}
    assert "apartment not scored (evaluation tinyeval" in capsys.readouterr().out     # train never scores the test world
    assert raspv(["learn", "compare", str(path), *ev_args]) == 0
    out = capsys.readouterr().out
    assert "tiny, realistic depth (primary)" in out and "tiny, perfect depth" in out and "RESCORED" not in out
    results = json.loads((tmp_path / "runs/learn/tinyeval/results.json").read_text())
    assert [t["depth"] for t in results["tables"]] == ["realistic", "perfect"]
    for t in results["tables"]:
        counts = np.load(tmp_path / f"runs/learn/tinyeval/per_frame-tiny-{t['depth']}.npz")["counts"]
        assert counts.shape == (6, 2, 2, 3)
        np.testing.assert_allclose([r["per_seed"] for r in t["rows"]], iou_of(counts.sum(2)), equal_nan=True)
    lines = [json.loads(x) for x in (tmp_path / "ledger.jsonl").read_text().splitlines()]
    assert len(lines) == 4 and {(x["seed"], x["depth"], x["rescore"]) for x in lines} == \
        {(0, "realistic", False), (1, "realistic", False), (0, "perfect", False), (1, "perfect", False)}
    # seed 1 trained again after the scoring: refused, then scored with --rescore and marked
    import shutil

    shutil.rmtree(tmp_path / "runs/learn/tinyeval/tiny-seed1")
    assert raspv(["learn", "train", str(path), *ev_args, "--seed", "1"]) == 0
    capsys.readouterr()
    assert raspv(["learn", "compare", str(path), *ev_args, "--depth", "realistic"]) == 2
    assert "pass --rescore" in capsys.readouterr().err
    assert raspv(["learn", "compare", str(path), *ev_args, "--depth", "realistic", "--rescore"]) == 0
    assert "RESCORED" in capsys.readouterr().out
    lines = [json.loads(x) for x in (tmp_path / "ledger.jsonl").read_text().splitlines()]
    assert [x["rescore"] for x in lines[4:]] == [False, True]
