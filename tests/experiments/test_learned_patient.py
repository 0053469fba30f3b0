"""The learned virtual patient: its inputs (phosphene image, goal features), the expert's
demonstrations from quick_trial, behaviour cloning and the ONNX export (torch against
onnxruntime), the `learned` policy in quick_trial and as a subject-node policy, and clear
errors for a missing or foreign model file."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from raspv_experiments.learned_policy import (DEFAULT_MODEL, GRID, Learned, LearnedModelError, goal_features,
                                              load_model, phosphene_image)
from raspv_experiments.policies import PhospheneLayout, PolicyConfig

REPO = Path(__file__).resolve().parents[2]


def layout(n=10, size=200):
    c = (np.arange(n) + 0.5) * size / n
    x, y = np.meshgrid(c, c)
    return PhospheneLayout(x.ravel(), y.ravel(), size, size, 300.0)


def test_phosphene_image_places_each_brightness_where_the_phosphene_is():
    lay = layout()
    b = np.zeros(100)
    b[0], b[99] = 0.5, 1.0                 # top-left and bottom-right phosphenes
    img = phosphene_image(lay, b, grid=10)
    assert img.shape == (10, 10) and img[0, 0] == 0.5 and img[9, 9] == 1.0 and img.sum() == 1.5
    coarse = phosphene_image(lay, np.linspace(0, 1, 100), grid=5)          # 4 phosphenes a cell: the brightest
    assert coarse[4, 4] == 1.0


def test_goal_features_are_bearing_and_capped_distance():
    ahead = goal_features(np.zeros(3), np.array([2.0, 0.0]))
    assert np.allclose(ahead, [1.0, 0.0, 0.4])
    left = goal_features(np.array([0.0, 0.0, 0.0]), np.array([0.0, 20.0]))
    assert np.allclose(left, [0.0, 1.0, 1.0], atol=1e-6)
    turned = goal_features(np.array([0.0, 0.0, math.pi / 2]), np.array([0.0, 3.0]))    # facing it after a turn
    assert np.allclose(turned, [1.0, 0.0, 0.6], atol=1e-6)


def test_a_missing_or_foreign_model_is_one_clear_error(tmp_path):
    with pytest.raises(LearnedModelError, match="no model file"):
        load_model(str(tmp_path / "none.onnx"))
    (tmp_path / "junk.onnx").write_bytes(b"not onnx")
    with pytest.raises(LearnedModelError, match="not an ONNX model"):
        load_model(str(tmp_path / "junk.onnx"))


def test_the_learned_policy_is_a_subject_policy():
    from raspv_experiments.session_runner import parse_subject
    from raspv_experiments.subject_params import POLICY_NAMES

    assert "learned" in POLICY_NAMES
    assert parse_subject("scripted:learned:3") == ("scripted-learned-3", "learned", 3)


def test_demonstrations_training_export_and_the_policy_agree(tmp_path):
    """A short expert walk in the hallway → shards → a few epochs → ONNX; onnxruntime gives
    torch's commands, and the policy walks with it in quick_trial."""
    torch = pytest.importorskip("torch")
    from raspv_experiments.demonstrations import DEFAULT_SPV, DemoRecipe, DemoTask, collect, load_demonstrations
    from raspv_experiments.quick_trial import quick_trial
    from raspv_learn.patient import PatientTraining, export_patient, train_patient

    hallway = str(REPO / "experiments" / "worlds" / "hallway.yaml")
    spv = {**DEFAULT_SPV, "num_phosphenes": 100}
    recipe = DemoRecipe([DemoTask(hallway, (1.0, 1.5, 0.0), (8.6, 1.5, 0.8), 2.0)], spv, episodes_per_task=2,
                        size=(64, 48))
    figures = collect(recipe, tmp_path / "demos", progress=None)
    data = load_demonstrations(tmp_path / "demos")
    n = figures["frames"]
    assert n >= 30 and data["image"].shape == (n, GRID, GRID) and data["goal"].shape == (n, 3)
    assert np.all(np.abs(data["command"]) <= 1.0) and set(np.unique(data["episode"])) == {1, 2}
    assert data["command"][:, 0].mean() > 0.3                       # the expert walks toward the goal
    assert json.loads((tmp_path / "demos" / "recipe.json").read_text())["spv"]["num_phosphenes"] == 100

    net, fig = train_patient(data, PatientTraining(epochs=2, batch=32), progress=None)
    assert fig["val_episodes"] == 1 and len(fig["history"]) == 2 and fig["weights"] < 100_000
    path = tmp_path / "patient.onnx"
    assert export_patient(net, path, {"spv": spv, "frames": n}) <= 1e-5
    session, meta = load_model(str(path))
    assert meta["grid"] == GRID and meta["frames"] == n
    x = data["image"][:4].astype(np.float32)[:, None]
    with torch.no_grad():
        ours = net(torch.from_numpy(x), torch.from_numpy(data["goal"][:4])).numpy()
    theirs = session.run(["command"], {"image": x, "goal": data["goal"][:4]})[0]
    assert np.abs(ours - theirs).max() <= 1e-5

    res = quick_trial(hallway, (1.0, 1.5, 0.0), (8.6, 1.5, 0.8), 1.0, spv=spv, policy="learned",
                      config=PolicyConfig(seed=1), size=(64, 48), policy_kw={"model": str(path)})
    assert len(res.path) >= 9 and res.phosphenes == 100


@pytest.mark.skipif(not DEFAULT_MODEL.is_file(), reason="no shipped learned patient")
def test_the_shipped_model_has_its_provenance_and_turns_towards_the_goal():
    session, meta = load_model(str(DEFAULT_MODEL))
    assert meta["frames"] > 1000 and meta["spv"]["mode"] == "depth"
    assert DEFAULT_MODEL.stat().st_size < 2_000_000
    provenance = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    assert provenance["frames"] == meta["frames"] and provenance["best_val_loss"] < provenance["mean_command_val_loss"]
    # its answers follow the goal: with nothing in view it walks towards a goal ahead and turns
    # towards a goal on either side (the clip to the speed limits could not fail; this can)
    out = {}
    for name, goal in {"ahead": (5.0, 0.0), "left": (1.0, 4.0), "right": (1.0, -4.0)}.items():
        p = Learned(layout(), PolicyConfig(seed=1, reaction_time_s=0.0, noise=0.0), goal=goal)
        out[name] = p.decide(np.zeros(100))
    assert out["ahead"][0] > 0.1, out
    assert out["left"][1] - out["ahead"][1] > 0.2 and out["ahead"][1] - out["right"][1] > 0.2, out


def test_outside_its_training_representation_it_is_refused_naming_both(tmp_path, example_doc, write_protocol):
    """The documented example shows Argus II (60 phosphenes over 20°); the shipped patient was
    trained on depth at 26×26 over 35° and reached 0 of 6 goals there without a word."""
    from raspv_experiments.learned_policy import representation_mismatch
    from raspv_experiments.protocol import load_protocol
    from raspv_experiments.quick_trial import quick_trial
    from raspv_experiments.session_runner import RunOptions, SessionRunner

    shown = {"device": "argus_ii", "mode": "depth", "temporal": False, "max_depth": 3.0}
    line = representation_mismatch("", shown)
    assert "\n" not in line and "676 phosphenes over 35 deg" in line and "60 phosphenes over 20 deg" in line
    trained = load_model(str(DEFAULT_MODEL))[1]["spv"]
    assert representation_mismatch("", trained) is None
    with pytest.raises(LearnedModelError, match="60 phosphenes over 20 deg"):
        quick_trial(str(REPO / "experiments/worlds/hallway.yaml"), (1.0, 1.5, 0.0), (8.6, 1.5, 0.8), 1.0, spv=shown, policy="learned")
    ok = quick_trial(str(REPO / "experiments/worlds/hallway.yaml"), (1.0, 1.5, 0.0), (8.6, 1.5, 0.8), 0.3, spv=shown,
                     policy="learned", other_representation=True)
    assert ok.phosphenes == 60
    protocol = load_protocol(write_protocol(example_doc))
    options = RunOptions(out=tmp_path / "sessions", subject="scripted-learned-1", policy="learned", number=1, keys=False)
    from raspv_experiments.session import SessionError

    with pytest.raises(SessionError, match="condition depth: learned virtual patient .* 60 phosphenes over 20 deg"):
        SessionRunner(protocol, options, view=None, say=lambda s: None).run()
    assert not (tmp_path / "sessions").exists()                 # refused before anything was written
