"""Recording a live graph and replaying it into the graph (real node processes)."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image
from std_msgs.msg import String

from raspv_bags.reader import BagReader
from raspv_bags.repair import repair_bag
from raspv_common import topics as T
from raspv_common.qos import LATCHED_QOS

pytestmark = pytest.mark.integration

SOURCE = {"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}]},
          "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}}}
CAMERA = [T.COLOR, T.DEPTH, T.CAMERA_INFO, T.CAMERA_POSE]


def raspv(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


def test_record_the_source_then_replay_it_byte_for_byte(graph, probe, tmp_path):
    g = graph(SOURCE)
    probe.wait_for_message(T.COLOR, Image, timeout=60)
    rec = raspv("bag", "record", "/camera/*", "-o", str(tmp_path / "rec"), "--duration", "5")
    assert rec.returncode == 0, rec.stderr
    assert "+ /camera/color/image_raw [sensor_msgs/msg/Image] (reliable)" in rec.stderr
    g.stop()
    with BagReader(tmp_path / "rec") as r:
        assert r.complete and set(r.topics) == set(CAMERA)
        counts = {t: i.count for t, i in r.topics.items()}
        assert min(counts.values()) >= 15, counts  # 10 Hz for 5 s, minus discovery
        assert all(i.qos and i.qos[0].reliable for i in r.topics.values())
        bag = [(bytes(m.data), m.timestamp_ns) for m in r.messages([T.COLOR])]
        # the bytes are the synthetic node's messages: header stamps increase at ~10 Hz
        stamps = [r.decode(m).header.stamp.sec + r.decode(m).header.stamp.nanosec * 1e-9 for m in r.messages([T.COLOR])]
    assert 0.05 < float(np.median(np.diff(stamps))) < 0.2

    received: list[tuple[bytes, float]] = []
    sub = probe.node.create_subscription(Image, T.COLOR, lambda raw: received.append((raw, time.monotonic())),
                                         QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE), raw=True)
    clock = probe.subscribe(T.CLOCK, Clock)
    try:
        play = raspv("bag", "play", str(tmp_path / "rec"), "--topics", T.COLOR, "--wait-for-subscribers", "1")
    finally:
        probe.node.destroy_subscription(sub)
        probe.unsubscribe(clock)
    ticks = [c.clock.sec * 10**9 + c.clock.nanosec for c in clock.messages]
    assert len(ticks) > 2 * len(bag) and ticks == sorted(ticks)  # 100 Hz, the bag's time
    assert bag[0][1] <= ticks[-1] <= bag[-1][1]
    assert play.returncode == 0, play.stderr
    assert "timing error over" in play.stderr and "p95" in play.stderr
    assert [d for d, _ in received] == [d for d, _ in bag]
    # never ahead of the recording's schedule
    span_bag = (bag[-1][1] - bag[0][1]) * 1e-9
    assert received[-1][1] - received[0][1] >= 0.95 * span_bag


def _record_until(out, sig, storage="mcap", then=None):
    """Start a recorder (then call ``then()``), wait until it has written a few seconds of
    data, send it ``sig``."""
    proc = subprocess.Popen([sys.executable, "-m", "raspv_bringup.cli", "bag", "record", "-o", str(out),
                             "-s", storage], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        if then is not None:
            then()
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            files = list(out.glob("*.mcap")) + list(out.glob("*.db3")) if out.exists() else []
            if files and files[0].stat().st_size > 3_000_000:  # a few seconds of 160x120 RGB-D
                break
            time.sleep(0.1)
        else:
            pytest.fail("the recorder wrote nothing within 60 s")
    finally:
        os.kill(proc.pid, sig)
        output, _ = proc.communicate(timeout=30)
    return proc.returncode, output


def test_topics_appearing_later_are_recorded_and_ctrl_c_closes_a_complete_bag(graph, probe, tmp_path):
    code, output = _record_until(tmp_path / "sqlite", signal.SIGINT, "sqlite3", then=lambda: graph(SOURCE))
    assert code == 0 and "messages over" in output, output
    assert "+ /camera/depth/image_raw" in output
    with BagReader(tmp_path / "sqlite") as r:
        assert r.complete and r.storage == "sqlite3" and r.notes == []
        assert set(CAMERA) <= set(r.topics) and r.topics[T.COLOR].count >= 5
        # the graph's tf: the source's moving transform and its fixed ones, latched as published
        assert {T.TF, T.TF_STATIC} <= set(r.topics) and r.topics[T.TF_STATIC].qos[0].transient_local
        static = [r.decode(m) for m in r.messages([T.TF_STATIC])]
        assert {(t.header.frame_id, t.child_frame_id) for t in static[0].transforms} == {
            ("map", "odom"), ("base_link", "camera_link"), ("camera_link", "camera_color_optical_frame")}


def test_a_killed_recorder_leaves_a_readable_and_repairable_bag(graph, probe, tmp_path):
    graph(SOURCE)
    probe.wait_for_message(T.COLOR, Image, timeout=60)
    out = tmp_path / "killed"
    code, _ = _record_until(out, signal.SIGKILL)
    assert code == -signal.SIGKILL
    assert not (out / "metadata.yaml").exists()
    with BagReader(out) as r:
        assert not r.complete and any("not closed" in n for n in r.notes)
        counts = {t: i.count for t, i in r.topics.items()}
        assert set(CAMERA) <= set(counts) and counts[T.COLOR] >= 5
        n = r.message_count
    assert "INCOMPLETE" in raspv("bag", "info", str(out)).stdout
    report = repair_bag(out, tmp_path / "fixed")
    assert report.message_count == n
    with BagReader(tmp_path / "fixed") as r:
        assert r.complete and r.message_count == n


def test_latched_topic_is_recorded_and_replayed_to_late_joiners(graph, probe, tmp_path):
    pub = probe.node.create_publisher(String, "/test/latched", LATCHED_QOS)
    pub.publish(String(data="the map"))
    rec = raspv("bag", "record", "/test/latched", "-o", str(tmp_path / "latched"), "--duration", "4")
    probe.node.destroy_publisher(pub)
    assert rec.returncode == 0, rec.stderr
    assert "transient-local" in rec.stderr
    with BagReader(tmp_path / "latched") as r:
        info = r.topics["/test/latched"]
        assert info.count == 1 and info.qos[0].transient_local
    g = graph({"launch": {"nodes": [{"kind": "replay"}]},
               "replay": {"ros__parameters": {"bag": str(tmp_path / "latched")}}})
    g.wait_for_output(r"finished: 1 messages", timeout=60)
    late = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
    assert probe.wait_for_message("/test/latched", String, timeout=30, qos=late).data == "the map"
    [(_, ok, _)] = probe.set_params("replay", {"rate": 3.0})
    assert ok
    [(_, ok, reason)] = probe.set_params("replay", {"rate": 0.0})
    assert not ok and "rate" in reason


def test_bad_bags_stop_the_replay_node_with_one_line(graph, tmp_path):
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "junk.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 100)
    g = graph({"launch": {"nodes": [{"kind": "replay"}]}, "replay": {"ros__parameters": {"bag": str(junk)}}})
    g.proc.wait(timeout=60)                       # the launcher checks the bag before starting the node
    assert g.stop() == 2
    assert re.search(r"replay\.ros__parameters\.bag: .*junk.*no readable records", g.output), g.output
    assert "Traceback" not in g.output
    play = raspv("bag", "play", str(tmp_path / "missing"))
    assert play.returncode == 1 and "no such bag" in play.stderr and "Traceback" not in play.stderr
    play = raspv("bag", "play", str(junk))
    assert play.returncode != 0 and "configuration error" in play.stderr and "Traceback" not in play.stderr


def test_topics_of_types_not_installed_are_skipped_with_a_warning(tmp_path):
    from raspv_bags.writer import BagWriter

    with BagWriter(tmp_path / "mixed") as w:
        w.add_topic("/lab/trial", "lab_msgs/msg/Trial", msgdef="int32 a\n")
        w.add_topic("/note", "std_msgs/msg/String")
        for i in range(3):
            w.write("/lab/trial", 10**9 + i * 10**7, b"\x00\x01\x00\x00" + i.to_bytes(4, "little"))
            w.write("/note", 10**9 + i * 10**7, b"\x00\x01\x00\x00\x02\x00\x00\x00a\x00")
    play = raspv("bag", "play", str(tmp_path / "mixed"))
    assert play.returncode == 0, play.stderr
    assert "/lab/trial: message type lab_msgs/msg/Trial is not installed; not replayed" in play.stderr
    assert "finished: 3 messages" in play.stderr
    only = raspv("bag", "play", str(tmp_path / "mixed"), "--topics", "/lab/trial")
    assert only.returncode == 2 and "none of its message types are installed" in only.stderr


def test_replay_drives_the_spv_node_to_the_same_levels_as_the_live_source(graph, probe, tmp_path):
    """Live: synthetic → spv, recorded. Replay: bag → spv. The same camera frame gives the
    same phosphene levels (the mode is deterministic; brightness also depends on timing)."""
    spv = {"width": 200, "mode": "grey"}
    # 5 Hz: the spv node computes levels for the newest frame only, so a loaded machine could
    # make the live and the replayed run skip different frames at higher rates
    live = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv"}]},
                  "cam": {"ros__parameters": {"rate": 5.0, "width": 160, "height": 120}},
                  "spv": {"ros__parameters": spv}})
    from raspv_msgs.msg import PhospheneFrame

    probe.wait_for_message(T.SPV_FRAME, PhospheneFrame, timeout=90)
    rec = raspv("bag", "record", "/camera/*", T.SPV_FRAME, T.SPV_MAP, "-o", str(tmp_path / "demo"), "--duration", "6")
    assert rec.returncode == 0, rec.stderr
    live.stop()
    with BagReader(tmp_path / "demo") as r:
        assert r.topics[T.SPV_MAP].count == 1  # latched, recorded although published before the recorder started
        live_levels = {}
        for m in r.messages([T.SPV_FRAME]):
            f = r.decode(m)
            live_levels[(f.source_stamp.sec, f.source_stamp.nanosec)] = bytes(f.levels)
    col = probe.subscribe(T.SPV_FRAME, PhospheneFrame, QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE))
    replay = graph({"launch": {"nodes": [{"kind": "replay"}, {"kind": "spv"}]},
           "replay": {"ros__parameters": {"bag": str(tmp_path / "demo"), "topics": CAMERA,
                                          "wait_for_subscribers": 2}},
           "spv": {"ros__parameters": spv}})
    def replayed():
        return {(f.source_stamp.sec, f.source_stamp.nanosec): bytes(f.levels) for f in list(col.messages)}

    replay.wait_for_output(r"finished: \d+ messages", timeout=120)
    time.sleep(0.5)  # the last frame's display ticks
    probe.unsubscribe(col)
    replay_levels = replayed()
    common = set(live_levels) & set(replay_levels) - {(0, 0)}
    assert len(common) >= 8, (len(live_levels), len(replay_levels), len(common))
    assert all(live_levels[k] == replay_levels[k] for k in common)
