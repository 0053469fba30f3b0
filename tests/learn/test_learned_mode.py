"""The live `learned` mode (onnxruntime) against the training pipeline (torch), and its model files."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from raspv_common.intrinsics import CameraIntrinsics
from raspv_learn.config import LearnConfig
from raspv_learn.export import export_encoder
from raspv_learn.networks import Encoder, quantise_levels, sample_at
from raspv_learn.prepare import phosphene_grid
from raspv_learn.twin import PhospheneTwin
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.learned import (CHANNELS, ModelError, encoder_inputs, input_size, load_encoder, sample_map,
                                     shipped_model, stimulation_levels)
from raspv_spv.simulator import PhospheneSimulator, check_config

CAMERA = CameraIntrinsics.from_hfov(160, 120, 60.0)


def synthetic_frame(seed: int = 0):
    """A room-like RGB-D frame with scene classes: floor below, a wall, a box."""
    rng = np.random.default_rng(seed)
    h, w = CAMERA.height, CAMERA.width
    rows = np.arange(h)[:, None].repeat(w, 1)
    depth = np.where(rows > h // 2, 1.6 / np.maximum(1e-3, (rows - h // 2) / CAMERA.fy), 4.0).astype(np.float32)
    depth = np.minimum(depth, 6.0)
    labels = np.where(rows > h // 2, 1, 2).astype(np.uint8)
    labels[60:100, 40:70] = 4
    depth[60:100, 40:70] = 1.5
    depth[:5, :20] = np.nan
    color = (rng.integers(0, 255, (h, w, 3)) // 2 + 60 * (labels[..., None] == 4)).astype(np.uint8)
    return color, depth, labels


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A small random encoder (weights spread so the stimulation spans [0, 1]) exported as the
    live mode loads it."""
    torch.manual_seed(0)
    config = LearnConfig("test", "argus_iii", spv={"width": 160}, source="test")
    encoder = Encoder(len(CHANNELS), 8)
    with torch.no_grad():
        for p in encoder.parameters():
            p.mul_(3.0)
        encoder.out.bias.fill_(0.0)
    color, depth, labels = synthetic_frame()
    x = encoder_inputs(color, depth, labels, input_size(CAMERA, config.encoder.focal_px))
    path = tmp_path_factory.mktemp("model") / "encoder.onnx"
    diff = export_encoder(encoder, config, 8, path, x)
    assert diff <= 1e-5
    return encoder.eval(), config, path


def test_the_live_level_rule_is_the_trainings():
    s = np.concatenate([np.random.default_rng(0).random(1000), np.arange(15) / 14, [0.0, 1.0, 1.2, -0.1]])
    ours = stimulation_levels(s, 8)
    theirs = quantise_levels(torch.from_numpy(s), 8).numpy()
    np.testing.assert_array_equal(ours, theirs)
    assert stimulation_levels(np.array([0.07, 0.0715, np.nan]), 8).tolist() == [0, 1, 0]


def test_the_live_bilinear_sampling_is_grid_sample():
    rng = np.random.default_rng(1)
    stimulation = rng.random((17, 23)).astype(np.float32)
    uv = np.stack([rng.uniform(-5, CAMERA.width + 5, 500), rng.uniform(-5, CAMERA.height + 5, 500)], 1)
    ours = sample_map(stimulation, uv, (CAMERA.width, CAMERA.height))
    grid = np.stack([2 * (uv[:, 0] + 0.5) / CAMERA.width - 1, 2 * (uv[:, 1] + 0.5) / CAMERA.height - 1], 1)
    theirs = sample_at(torch.from_numpy(stimulation)[None, None], torch.from_numpy(grid)).numpy()[0]
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


def test_encoder_inputs_of_a_frame():
    color, depth, labels = synthetic_frame()
    size = input_size(CAMERA, 64.0)
    assert size == (74, 55)                     # 160 px at f = 138.6 px, the grid at f = 64 px
    x = encoder_inputs(color, depth, labels, size)
    assert x.shape == (9, 55, 74) and x.dtype == np.float32
    assert 0.0 <= x.min() and x.max() <= 1.0 + 1e-6
    classes = x[3:]
    np.testing.assert_allclose(classes.sum(0), 1.0, atol=1e-5)     # floor, wall, obstacle cover the frame
    assert x[2].min() < 1.0 and x[2].max() == pytest.approx(1.0)      # the depth hole is not a reading
    # the same frame from a camera of twice the resolution gives the same grid
    big = encoder_inputs(np.repeat(np.repeat(color, 2, 0), 2, 1), np.repeat(np.repeat(depth, 2, 0), 2, 1),
                         np.repeat(np.repeat(labels, 2, 0), 2, 1), size)
    np.testing.assert_allclose(big[3:], x[3:], atol=1e-5)


def test_live_mode_levels_and_image_equal_the_training_pipeline(exported):
    """The live node's learned mode (numpy + onnxruntime) and the torch pipeline that trained it
    give the same levels, and the twin draws the live node's image."""
    encoder, config, path = exported
    color, depth, labels = synthetic_frame(3)
    sim = PhospheneSimulator(spv_config("argus_iii", width=160, mode="learned", temporal=False,
                                        mode_settings={"learned_model": str(path)}))
    assert sim.needs == {"color", "depth", "scene_labels", "camera"}
    frame = sim.step(FrameInputs(color=color, depth=depth, scene_labels=labels, camera=CAMERA))
    x = torch.from_numpy(encoder_inputs(color, depth, labels, input_size(CAMERA, config.encoder.focal_px)))[None]
    grid, inside = phosphene_grid(sim, CAMERA)
    with torch.no_grad():
        s = sample_at(encoder(x), torch.from_numpy(grid))
        ours = (quantise_levels(s, 8) * torch.from_numpy(inside.astype(np.float32)))[0].numpy()
    near_boundary = np.abs((s[0].numpy() * 7 + 0.5) % 1.0 - 0.5) > 0.4999   # ties ORT and torch may round apart
    assert len(np.unique(frame.levels)) >= 3                              # the test exercises several levels
    np.testing.assert_array_equal(frame.levels[~near_boundary], ours[~near_boundary].astype(np.uint8))
    twin = PhospheneTwin(sim)
    with torch.no_grad():
        image = twin.render_levels(frame.levels[None])[0].numpy() * 255
    assert np.abs(np.rint(image) - frame.image).max() <= 1


def test_bad_model_files_are_one_line_errors(tmp_path, exported):
    _, _, good = exported
    cases = {tmp_path / "missing.onnx": "no such learned-encoder file",
             tmp_path / "garbage.onnx": "not a model onnxruntime can load"}
    (tmp_path / "garbage.onnx").write_bytes(b"\x00not onnx")
    import onnx

    plain = onnx.load(str(good))
    del plain.metadata_props[:]
    onnx.save(plain, str(tmp_path / "plain.onnx"))
    cases[tmp_path / "plain.onnx"] = "not a RASPV learned encoder"
    from raspv_bringup.file_kinds import check_file

    for path, why in cases.items():
        with pytest.raises(ModelError, match=why):
            load_encoder(path)
        with pytest.raises(ValueError, match=why):            # a parameter change the node refuses
            check_config(spv_config("argus_iii", mode="learned", mode_settings={"learned_model": str(path)}))
        line = check_file("learned_model", str(path))
        assert why in line and "\n" not in line
    assert check_file("learned_model", str(good)) is None


def test_the_node_parameter_and_the_shipped_encoders():
    from raspv_spv.spv_params import PARAMS

    params = {p.name: p for p in PARAMS}
    assert "learned" in params["mode"].choices
    assert params["learned_model"].default == "" and params["learned_model"].file_kind == "learned_model"
    for device in ("optimist", "argus_iii"):
        model = load_encoder(shipped_model(device))
        assert model.device == device and model.channels == CHANNELS and model.num_levels == 8
        summary = json.loads(shipped_model(device).with_suffix(".json").read_text())
        assert summary["config"] == device
        # the encoder answers the scene, not only its own record: it stimulates the near box
        # (obstacle) apart from the wall around it, and the box's place changes when the box goes
        color, depth, labels = synthetic_frame()
        with_box = model.stimulation(color, depth, labels, CAMERA)
        rows, cols = with_box.shape
        box = (slice(int(rows * 65 / 120), int(rows * 95 / 120)), slice(int(cols * 45 / 160), int(cols * 65 / 160)))
        wall = (slice(int(rows * 10 / 120), int(rows * 50 / 120)), slice(int(cols * 90 / 160), int(cols * 150 / 160)))
        assert abs(float(with_box[box].mean()) - float(with_box[wall].mean())) > 0.1, device
        depth_no_box, labels_no_box = depth.copy(), labels.copy()
        depth_no_box[60:100, 40:70] = depth[60:100, 100:130]
        labels_no_box[60:100, 40:70] = labels[60:100, 100:130]
        without = model.stimulation(color, depth_no_box, labels_no_box, CAMERA)
        assert float(np.abs(with_box[box] - without[box]).mean()) > 0.3, device
    assert shipped_model("argus_ii").name == "optimist.onnx"                 # no encoder of its own: the fallback
    assert shipped_model("config/devices/argus_iii.yaml").name == "argus_iii.onnx"
