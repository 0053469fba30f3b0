"""Run-time settings that cannot keep the display rate are refused with the reason and the limit
(the budget is computed on this machine; the values here are far beyond any machine's)."""
from __future__ import annotations

import pytest
from raspv_msgs.msg import PhospheneMap

from raspv_common import topics
from raspv_common.qos import LATCHED_QOS

pytestmark = pytest.mark.integration


def test_settings_beyond_the_display_budget_are_refused_and_a_directory_is_not_a_device(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv"}]},
               "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"width": 200, "rate": 20.0, "temporal": False}}})
    probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    for name, value in (("rate", 240.0), ("num_phosphenes", 3000)):      # small phosphenes: these fit
        [(_, ok, why)] = probe.set_params("spv", {name: value})
        assert ok, why
    # 3000 phosphenes of 10 deg (a 150 px sprite each) at 240 Hz: ~100 M sprite pixels per 4.2 ms frame
    [(_, ok, why)] = probe.set_params("spv", {"phosphene_fov_deg": 10.0})
    assert not ok and "cannot run at 240 Hz" in why and "at most ~" in why, why
    [(_, ok, why)] = probe.set_params("spv", {"device": "/tmp"})
    assert not ok and "is a directory" in why, why
    assert probe.get_params("spv", ["num_phosphenes", "phosphene_fov_deg", "rate", "device"]) == {
        "num_phosphenes": 3000, "phosphene_fov_deg": 0.0, "rate": 240.0, "device": "default"}
    assert "Traceback" not in g.output


def test_a_rate_the_wearers_page_does_not_keep_is_refused_with_the_reason(graph, probe):
    """The page's reports (``/hmd/presentation``, as the bridge forwards them) judge the display
    rate: 57.6 of 90 frames/s composited → 90 Hz refused in ``/spv/status`` and by `param set`."""
    import json
    import time

    from std_msgs.msg import String

    from raspv_common.qos import EVENT_QOS

    graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv"}]},
           "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
           "spv": {"ros__parameters": {"width": 200, "rate": 90.0, "temporal": False}}})
    probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    status = probe.subscribe(topics.SPV_STATUS, String, qos=LATCHED_QOS)
    reports = probe.publisher(topics.HMD_PRESENTATION, String, EVENT_QOS, wait_for_subscribers=1)

    def page_verdict(m) -> bool:
        return "90" in json.loads(m.data).get("display", {}).get("page", {})

    deadline, verdict = time.monotonic() + 60, []
    while not verdict:                                  # a page reports about once a second; here twice
        assert time.monotonic() < deadline, "no page verdict in /spv/status"
        reports.publish(String(data=json.dumps({"fps": 57.6, "refresh_hz": 90.0})))
        try:
            verdict = status.wait(1, 0.5, page_verdict)
        except TimeoutError:
            pass
    display = json.loads(verdict[0].data)["display"]
    assert display["page"]["90"]["verdict"] == "refused" and display["verdict"] == "refused", display
    assert "57.6 of 90 frames/s" in display["rates"]["90"]["reason"], display
    [(_, ok, why)] = probe.set_params("spv", {"rate": 50.0})
    assert ok, why
    [(_, ok, why)] = probe.set_params("spv", {"rate": 90.0})
    assert not ok and "90 Hz is not kept" in why and "measured" in why, why
