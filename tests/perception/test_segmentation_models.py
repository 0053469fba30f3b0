"""A user's own segmentation model: a small network built and exported here with PyTorch (to ONNX
and TorchScript, as docs/perception.md tells users to), its model YAML, the same predictions
through onnxruntime and torch, and one-line errors for every kind of bad model."""
from __future__ import annotations


import numpy as np
import pytest
import yaml

from raspv_perception.model_spec import ModelError
from raspv_perception.segmentation_models import OnnxModel, TorchScriptModel, load_model
from raspv_bringup.testing import dev_requirement

torch = dev_requirement("torch")


@pytest.fixture
def write_model(write_user_model):
    return write_user_model


def scene() -> np.ndarray:
    img = np.full((240, 320, 3), 128, np.uint8)
    img[40:120, 40:140] = (220, 20, 20)        # red box
    img[140:220, 180:300] = (20, 30, 230)      # blue box
    return img


@pytest.mark.parametrize("kind", ["onnx", "torchscript"])
def test_a_users_model_segments_with_its_yaml(write_model, tmp_path, kind):
    path = write_model(tmp_path, "onnx" if kind == "onnx" else "pt")
    model = load_model(kind, str(path))
    assert isinstance(model, OnnxModel if kind == "onnx" else TorchScriptModel)
    labels = model.predict(scene()).labels
    assert labels.shape == (240, 320) and labels.dtype == np.uint8
    assert (labels[50:110, 50:130] == 1).all() and (labels[150:210, 190:290] == 2).all()
    assert (labels[:30] == 0).all()
    assert model.classes.ids_for(["crimson"])[0].tolist() == [1]


def test_onnx_and_torch_agree_on_the_exported_network(write_model, tmp_path):
    onnx_path = write_model(tmp_path, "onnx")
    (tmp_path / "ts").mkdir()
    pt_path = write_model(tmp_path / "ts", "pt")
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (64, 96, 3), np.uint8)
    a, b = load_model("onnx", str(onnx_path)), load_model("torchscript", str(pt_path))
    x = a._input_tensor(img)
    assert np.abs(a._run(x) - b._run(x)).max() < 1e-5
    assert np.array_equal(a.predict(img).labels, b.predict(img).labels)


def test_labels_by_built_in_set_and_background(write_model, tmp_path):
    path = write_model(tmp_path, "onnx", labels=["red", "blue"], background=True)
    assert load_model("onnx", str(path)).classes.names == ("background", "red", "blue")
    path.with_suffix(".yaml").write_text(yaml.safe_dump({"input_size": [96, 64], "labels": "ade20k"}))
    with pytest.raises(ModelError, match=r"outputs 3 class scores but the labels name 150 classes \(ade20k\)"):
        load_model("onnx", str(path))


@pytest.mark.parametrize("change, message", [
    ({"input_size": [128, 128]}, r"input shape \[1, 3, 64, 96\]; redblue.yaml expects \[1, 3, 128, 128\]"),
    ({"labels": "cityscapes"}, r"labels: unknown label set 'cityscapes'; built in: ade20k, coco_stuff, person"),
    ({"layout": "chw"}, r"layout: expected nchw or nhwc, got 'chw'"),
    ({"std": [1, 0, 1]}, r"std: expected 3 positive numbers"),
    ({"colour_order": "rgb"}, r"unknown key 'colour_order'"),
    ({"labels": ["a", "b"]}, r"outputs 3 class scores but the labels name 2 classes"),
])
def test_bad_model_files_fail_in_one_line_naming_the_file(write_model, tmp_path, change, message):
    path = write_model(tmp_path, "onnx", **change)
    with pytest.raises(ModelError, match=message) as err:
        load_model("onnx", str(path))
    assert "\n" not in str(err.value) and "redblue" in str(err.value)


def test_unreadable_and_missing_models(write_model, tmp_path):
    bad = tmp_path / "broken.onnx"
    bad.write_bytes(b"this is not an onnx file")
    bad.with_suffix(".yaml").write_text("input_size: [64, 64]\nlabels: ade20k\n")
    with pytest.raises(ModelError, match="broken.onnx: not a model onnxruntime can load"):
        load_model("onnx", str(bad))
    bad_pt = tmp_path / "broken.pt"
    bad_pt.write_bytes(b"junk")
    bad_pt.with_suffix(".yaml").write_text("input_size: [64, 64]\nlabels: ade20k\n")
    with pytest.raises(ModelError, match="broken.pt: not a TorchScript file"):
        load_model("torchscript", str(bad_pt))
    with pytest.raises(ModelError, match="absent.onnx: no such model file"):
        load_model("onnx", str(tmp_path / "absent.onnx"))
    (tmp_path / "no_yaml.onnx").write_bytes(b"")
    with pytest.raises(ModelError, match="no_yaml.yaml: no model file; a segmentation model needs a YAML beside it"):
        load_model("onnx", str(tmp_path / "no_yaml.onnx"))
    (tmp_path / "bad.yaml").write_text("input_size: [64, 64\n")
    (tmp_path / "bad.onnx").write_bytes(b"")
    with pytest.raises(ModelError, match=r"bad.yaml: not valid YAML at line"):
        load_model("onnx", str(tmp_path / "bad.onnx"))
    with pytest.raises(ModelError, match="the onnx backend needs a model file"):
        load_model("onnx", "")


def test_torchscript_without_torch_says_what_to_install(write_model, tmp_path, monkeypatch):
    path = write_model(tmp_path, "pt")
    import sys
    monkeypatch.setitem(sys.modules, "torch", None)          # as if torch were not installed
    with pytest.raises(ModelError, match=r"the torchscript backend needs torch \(the 'learn' extra\): "):
        load_model("torchscript", str(path))
