"""The segmentation node in real graphs: ground-truth labels from the sim highlighted by the spv
node (and changed at run time), the person network on the sim's colour image with depth fusion,
a user's ONNX model, and one-line start-up errors."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from raspv_msgs.msg import ClassNames, PhospheneFrame
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.qos import LATCHED_QOS
from raspv_perception.segmentation_msg import classes_from_msg

pytestmark = pytest.mark.integration

WORLD = Path(__file__).resolve().parents[1] / "data" / "worlds" / "desk_and_person.yaml"


def highlighted(frame: PhospheneFrame) -> int:
    """Phosphenes at the top level while the rest is dimmed to at most half (the overlay's mark)."""
    levels = np.frombuffer(bytes(frame.levels), np.uint8)
    top = levels == 7
    return int(top.sum()) if top.any() and levels[~top].max(initial=0) <= 4 else 0


def test_sim_labels_highlight_the_laptop_then_the_bin_at_run_time(graph, probe):
    graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "segmentation"}, {"kind": "spv"}]},
           "sim": {"ros__parameters": {"world": str(WORLD), "rate": 10.0}},
           "segmentation": {"ros__parameters": {"backend": "sim"}},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "grey", "overlays": ["highlight"], "width": 400,
                                       "highlight.classes": ["laptop"], "temporal": False}}})
    classes = classes_from_msg(probe.wait_for_message(topics.SEGMENTATION_CLASSES, ClassNames, timeout=90,
                                                      qos=LATCHED_QOS))
    assert classes.label_set == "sim" and "laptop" in classes.names and classes.id_of("trash can") == classes.id_of("bin")
    labels = probe.wait_for_message(topics.SEGMENTATION_LABELS, Image, timeout=60)
    assert labels.encoding == "mono8" and (labels.width, labels.height) == (320, 240)
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    laptop = frames.wait(1, timeout=60, predicate=lambda f: highlighted(f) > 0)[0]
    [(_, ok, _)] = probe.set_params("spv", {"highlight.classes": ["trash can"]})
    assert ok
    frames.wait(1, timeout=30, predicate=lambda f: highlighted(f) > 0 and highlighted(f) != highlighted(laptop))
    [(_, ok, reason)] = probe.set_params("spv", {"highlight.pick": "biggest"})
    assert not ok and "largest" in reason


def test_person_model_segments_the_rendered_walker(graph, probe):
    graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "scene"}, {"kind": "segmentation"}]},
           "sim": {"ros__parameters": {"world": str(WORLD), "rate": 5.0}},
           "segmentation": {"ros__parameters": {"backend": "person", "scene_max_age": 0.5}}})
    classes = classes_from_msg(probe.wait_for_message(topics.SEGMENTATION_CLASSES, ClassNames, timeout=90,
                                                      qos=LATCHED_QOS))
    assert classes.names == ("background", "person")
    colors = probe.subscribe(topics.COLOR, Image)
    msg = probe.subscribe(topics.SEGMENTATION_LABELS, Image).wait(
        1, timeout=120, predicate=lambda m: np.frombuffer(bytes(m.data), np.uint8).mean() > 0.01)[0]
    assert (msg.width, msg.height, msg.encoding) == (320, 240, "mono8")
    stamps = {(c.header.stamp.sec, c.header.stamp.nanosec) for c in colors.messages}
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) in stamps      # the stamp of its colour frame


def test_a_users_onnx_model_runs_in_the_node(graph, probe, tmp_path, write_user_model):
    path = write_user_model(tmp_path)
    graph({"launch": {"nodes": [{"kind": "synthetic"}, {"kind": "segmentation"}]},
           "segmentation": {"ros__parameters": {"backend": "onnx", "model": str(path)}}})
    classes = classes_from_msg(probe.wait_for_message(topics.SEGMENTATION_CLASSES, ClassNames, timeout=60,
                                                      qos=LATCHED_QOS))
    assert classes.names == ("background", "red thing", "blue thing")
    msg = probe.wait_for_message(topics.SEGMENTATION_LABELS, Image, timeout=60)
    assert msg.encoding == "mono8" and set(np.unique(np.frombuffer(bytes(msg.data), np.uint8))) <= {0, 1, 2}


def test_bad_models_are_refused_with_one_line(tmp_path):
    """The launcher checks the model file before any node starts (file kind
    ``segmentation_model``), so a bad model is one line and exit 2."""
    yaml_path = tmp_path / "model.yaml"
    yaml_path.write_text("input_size: [64, 64]\nlabels: cityscapes\n")
    (tmp_path / "model.onnx").write_bytes(b"junk")
    graph_file = tmp_path / "graph.yaml"
    graph_file.write_text(yaml.safe_dump({"launch": {"nodes": [{"kind": "segmentation"}]},
                                          "segmentation": {"ros__parameters": {"backend": "onnx",
                                                                               "model": str(tmp_path / "model.onnx")}}}))
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(graph_file)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stdout + res.stderr
    assert re.search(r"segmentation\.ros__parameters\.model: .*model\.yaml: labels: unknown label set 'cityscapes'; "
                     r"built in: ade20k", lines[0]), lines
