"""The `learned` mode in a live graph: chosen at run time, the shipped encoder for the device, the
temporal model on; the twin draws the node's image from a recorded frame; a bad model file is
refused with its reason and the mode kept."""
import numpy as np
import pytest
import torch
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.conversions import image_to_array
from raspv_learn.twin import PhospheneTwin
from raspv_spv.spv_params import PARAMS

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SPV = {"device": "argus_iii", "mode": "depth", "width": 200, "rate": 10.0}


@pytest.fixture
def node_params():
    """The spv node's parameters; its temporal table built into the session's cache first (2-3
    minutes on a loaded machine: not the graph's time budget)."""
    from raspv_spv.config import config_from_node_params
    from raspv_spv.simulator import PhospheneSimulator

    params = {p.name: p.default for p in PARAMS}
    params.update(SPV)
    PhospheneSimulator(config_from_node_params(params))
    return params


def test_learned_mode_selected_at_run_time_in_a_live_graph(graph, probe, tmp_path, node_params):
    from raspv_msgs.msg import PhospheneFrame

    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "scene"}, {"kind": "spv"}]},
               "cam": {"ros__parameters": {"rate": 5.0, "width": 320, "height": 240, "walk_speed": 0.3,
                                           "pitch_down_deg": 30.0}},
               "spv": {"ros__parameters": dict(SPV)}})
    # three nodes starting on a loaded machine: the first frame can take long
    probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=150, predicate=lambda m: m.mode == "depth")
    [(_, ok, why)] = probe.set_params("spv", {"mode": "learned"})     # the shipped encoder of argus_iii
    assert ok, why
    frame = probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90,
                                   predicate=lambda m: m.mode == "learned" and any(m.levels))
    assert frame.temporal and len(frame.levels) == 240
    assert 0 < np.count_nonzero(frame.levels) < 240                      # a representation, not all on
    # the twin of the node's configuration draws the node's image from a recorded /spv/frame
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    images = probe.subscribe(topics.SPV_IMAGE, Image)
    stamp = lambda m: (m.header.stamp.sec, m.header.stamp.nanosec)        # noqa: E731
    images.wait(1, timeout=60, predicate=lambda i: any(stamp(i) == stamp(f) and f.mode == "learned"
                                                       for f in frames.messages))
    image = next(i for i in images.messages if any(stamp(i) == stamp(f) for f in frames.messages))
    recorded = next(f for f in frames.messages if stamp(f) == stamp(image))
    twin = PhospheneTwin.from_node_params({**node_params, "mode": "learned"})
    with torch.no_grad():
        ours = twin(torch.tensor([list(recorded.brightness)]))[0].numpy() * 255
    assert np.abs(np.rint(ours) - image_to_array(image)).max() <= 1
    (tmp_path / "bad.onnx").write_bytes(b"not a model")
    [(_, ok, why)] = probe.set_params("spv", {"learned_model": str(tmp_path / "bad.onnx")})
    assert not ok and "not a model onnxruntime can load" in why
    assert probe.get_params("spv", ["mode", "learned_model"]) == {"mode": "learned", "learned_model": ""}
    assert "Traceback" not in g.output
