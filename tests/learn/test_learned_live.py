"""The `learned` mode in a live graph: chosen at run time, the shipped encoder for the device, the
temporal model on; a bad model file refused with its reason and the old mode kept."""
import numpy as np
import pytest

from raspv_common import topics

pytestmark = pytest.mark.integration


def test_learned_mode_selected_at_run_time_in_a_live_graph(graph, probe, tmp_path):
    from raspv_msgs.msg import PhospheneFrame

    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "scene"}, {"kind": "spv"}]},
               "cam": {"ros__parameters": {"rate": 5.0, "width": 320, "height": 240, "walk_speed": 0.3,
                                           "pitch_down_deg": 30.0}},
               "spv": {"ros__parameters": {"device": "argus_iii", "mode": "depth", "width": 200, "rate": 10.0}}})
    probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90, predicate=lambda m: m.mode == "depth")
    [(_, ok, why)] = probe.set_params("spv", {"mode": "learned"})     # the shipped encoder of argus_iii
    assert ok, why
    frame = probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90,
                                   predicate=lambda m: m.mode == "learned" and any(m.levels))
    assert frame.temporal and len(frame.levels) == 240
    assert 0 < np.count_nonzero(frame.levels) < 240                      # a representation, not all on
    (tmp_path / "bad.onnx").write_bytes(b"not a model")
    [(_, ok, why)] = probe.set_params("spv", {"learned_model": str(tmp_path / "bad.onnx")})
    assert not ok and "not a model onnxruntime can load" in why
    assert probe.get_params("spv", ["mode", "learned_model"]) == {"mode": "learned", "learned_model": ""}
    assert "Traceback" not in g.output
