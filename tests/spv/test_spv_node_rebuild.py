"""The spv node switches to a device whose sprites take seconds to build without stopping the
display: the change is checked at once, built in the background, and swapped in."""
import time

import pytest
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.qos import LATCHED_QOS
from raspv_msgs.msg import PhospheneFrame, PhospheneMap

pytestmark = [pytest.mark.integration, pytest.mark.slow, pytest.mark.usefixtures("warm_node_tables")]

SOURCE = {"kind": "synthetic", "name": "cam"}
SOURCE_PARAMS = {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120, "walk_speed": 0.0}}


def stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_a_new_sprite_model_is_built_in_the_background_and_swapped_in(graph, probe):
    g = graph({"launch": {"nodes": [SOURCE, {"kind": "spv"}]}, "cam": SOURCE_PARAMS,
               "spv": {"ros__parameters": {"device": "argus_ii", "mode": "grey", "width": 400, "rate": 25.0,
                                           "pulse_phase_ms": 0.45}}})       # one temporal table for all
    probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    frames.wait(3, timeout=30, predicate=lambda f: max(f.levels) > 0)
    [(_, ok, why)] = probe.set_params("spv", {"device": "argus_ii_axon"})     # answered before the sprites exist
    asked = time.time()
    assert ok, why
    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=180, qos=LATCHED_QOS,
                               predicate=lambda m: m.map_id == 2)
    assert m.device == "argus_ii_axon" and len(m.x) == 60 and (m.width, m.height) == (400, 400)
    new = frames.wait(1, timeout=60, predicate=lambda f: f.map_id == 2 and max(f.levels) > 0)[0]
    # the display went on with the old prosthesis while the axon map was built
    assert any(f.map_id == 1 and stamp(f) > asked for f in frames.messages)
    assert len(new.levels) == 60
    g.wait_for_output(r"argus_ii_axon: 60 argus_ii \(retina at \(0, 0\) um, 0 deg\) phosphenes, FOV 30 deg, "
                      r"axon_map sprites \(rho 300 um, axlambda 1000 um", timeout=30)
    img = probe.wait_for_message(topics.SPV_IMAGE, Image, timeout=30, predicate=lambda i: i.height == 400)
    assert max(img.data) > 0
    # a sprite model that cannot draw the device is refused at once, the display keeps going
    [(_, ok, _)] = probe.set_params("spv", {"sprite_model": "axon_map"})
    assert ok
    [(_, ok, why)] = probe.set_params("spv", {"device": "orion"})
    assert not ok and "the axon_map model needs a retinal layout; orion is cortical" in why
    assert probe.get_params("spv", ["device"]) == {"device": "argus_ii_axon"}
    # several changes in a row: only the newest is built, the map ids follow the accepted changes
    # (a new rho changes the sprites: a new map id too, so clients drawing the sprites get them)
    for results in (probe.set_params("spv", {"sprite_model": "", "rho_um": 200.0}),
                    probe.set_params("spv", {"device": "prima"})):
        assert all(ok for _, ok, _ in results), results
    m = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=180, qos=LATCHED_QOS,
                               predicate=lambda m: m.device == "prima")
    assert len(m.x) == 378 and m.map_id == 4
    frames.wait(1, timeout=60, predicate=lambda f: f.map_id == 4 and max(f.levels) > 0)
    assert g.running() and "Traceback" not in g.output
