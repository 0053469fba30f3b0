"""What a consumer concludes about one producing node (raspv_common.liveliness._Producer): the
states the spv node and the bridge turn into stale bounds. Real /proc, no DDS.

The case that showed a false no-data ring: a RASPV node whose alive publisher is in the graph
but whose announcement has not arrived yet (a graph starting on a loaded machine) is *alive* —
judged as an unknown publisher, its camera's first jittery frames crossed the 0.26 s crash bound."""
import json
import subprocess
import sys

from raspv_common import liveliness as L
from raspv_common import process_state as proc


def announcement(state=L.DELIVERING, **identity):
    return json.dumps({"state": state, **(identity or proc.identity())})


def test_a_publisher_that_announces_nothing_is_unknown():
    assert L._Producer().verdict == L.UNKNOWN


def test_a_raspv_node_whose_announcement_is_on_its_way_is_alive():
    p = L._Producer()
    p.announces = True
    assert p.verdict == L.PENDING
    assert L.combined_state({L.PENDING}) == L.ALIVE                   # a graph starting
    assert L.combined_state({L.PENDING, L.GONE}) == L.GONE            # the old camera died, its replacement starts
    assert L.combined_state({L.PENDING, L.PAUSED}) == L.PAUSED
    assert L.combined_state({L.UNKNOWN}) == L.UNKNOWN


def test_once_heard_a_local_node_is_judged_by_its_process():
    p = L._Producer()
    p.announces = True
    p.announced(announcement())                       # this very process: running
    assert p.verdict == L.ALIVE
    p.announced(announcement(L.PAUSED))
    assert p.verdict == L.PAUSED
    p.announced(announcement(L.DOWN))
    assert p.verdict == L.GONE
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    p.announced(announcement(pid=child.pid, started=1, ns=proc.NAMESPACE))   # exited
    assert p.verdict == L.GONE


def test_a_remote_node_is_judged_by_dds_liveliness():
    p = L._Producer()
    p.announced(announcement(pid=1, started=1, ns="another-machine"))
    assert p.verdict == L.UNKNOWN                      # heard, but DDS has not reported it alive yet
    p.alive, p.ever_alive = 1, True
    assert p.verdict == L.ALIVE
    p.alive = 0                                        # its lease lapsed
    assert p.verdict == L.GONE


def test_a_garbled_announcement_changes_nothing():
    p = L._Producer()
    p.announces = True
    p.announced("[1, 2")
    p.announced("[1, 2]")
    assert p.verdict == L.PENDING and not p.heard


def test_a_replaced_process_is_dead_until_its_replacement_sends():
    """Issue 36: spv killed, its warm spare registered under the same name ~0.24 s later and the
    input counted as alive (the 1-s late bound: a headset without frames for 1.02 s). The verdict
    follows the processes its last message can have come from, not the node name."""
    old, new = (subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]) for _ in range(2))
    try:
        producers = {"/spv": L._Producer()}
        spv = producers["/spv"]

        def announce(child):
            spv.announced(announcement(pid=child.pid, started=proc._stat(child.pid)[1], ns=proc.NAMESPACE))

        announce(old)
        sources = L.live_processes(producers, ["/spv"])          # a frame arrives from the old process
        assert L.input_state(producers, ["/spv"], sources) == L.ALIVE
        old.kill()
        old.wait()
        announce(new)                                            # the spare takes over the name
        assert L.input_state(producers, ["/spv"]) == L.ALIVE     # by name: alive (the bug)
        assert L.input_state(producers, ["/spv"], sources) == L.GONE
        sources = L.live_processes(producers, ["/spv"])          # the replacement's first frame
        assert sources == {("/spv", (new.pid, proc._stat(new.pid)[1]))}
        assert L.input_state(producers, ["/spv"], sources) == L.ALIVE
    finally:
        for child in (old, new):
            child.kill()
            child.wait()
