"""The playback core: order, bytes, selection, remapping, offsets, loops, /clock, QoS choice."""
from __future__ import annotations

import threading
import time

import pytest

from raspv_bags.playback import PlaybackOptions, Player, parse_remap, publisher_qos
from raspv_bags.reader import BagError, BagReader
from raspv_bags.writer import BagWriter, QosSpec
from raspv_common import topics as T

from .conftest import T0, make_rgbd_bag


class Sink:
    def __init__(self, player_ref=None):
        self.published: list[tuple[str, bytes, float]] = []
        self.clock: list[int] = []
        self.player = player_ref

    def publish(self, topic, _msgtype, data):
        self.published.append((topic, bytes(data), time.monotonic()))

    def tick(self, ns):
        self.clock.append(ns)


def _play(bag, **opts):
    sink = Sink()
    player = Player(str(bag), PlaybackOptions(**opts), sink.publish, sink.tick)
    report = player.run()
    return player, sink, report


def test_every_message_goes_out_in_order_unchanged_and_never_early(rgbd_bag):
    with BagReader(rgbd_bag) as r:
        expected = [(m.topic, bytes(m.data), m.timestamp_ns) for m in r.messages()]
    player, sink, report = _play(rgbd_bag, rate=8.0)
    assert [(t, d) for t, d, _ in sink.published] == [(t, d) for t, d, _ in expected]
    # publish call at or after the due time of each message (the scheduler never runs ahead)
    start = sink.published[0][2]
    for (_, _, when), (_, _, ts) in zip(sink.published, expected):
        assert when - start >= (ts - expected[0][2]) / 8.0 * 1e-9 - 1e-3
    assert report.counts == {T.COLOR: 12, T.DEPTH: 12, T.CAMERA_INFO: 12}
    assert report.timing.count == 36 and report.loops == 1 and not report.stopped
    assert report.bag_s == pytest.approx(1.1)


def test_clock_carries_bag_time_before_every_message(rgbd_bag):
    _, sink, _ = _play(rgbd_bag, rate=8.0, clock_rate_hz=200.0)
    assert sink.clock == sorted(sink.clock)
    assert sink.clock[0] >= int(T0 * 1e9) and sink.clock[-1] == int(round((T0 + 1.1) * 1e9))
    assert len(sink.clock) > 36  # ticks between messages as well


def test_selection_remapping_and_start_offset(rgbd_bag):
    _, sink, report = _play(rgbd_bag, rate=8.0, topics=(T.COLOR, T.DEPTH), exclude=(T.DEPTH,),
                            remap={T.COLOR: "/replayed/color"}, start_offset_s=0.5)
    assert {t for t, _, _ in sink.published} == {"/replayed/color"}
    assert report.counts == {"/replayed/color": 7}  # frames at 0.5 … 1.1 s


def test_rate_scales_the_schedule(rgbd_bag):
    player = Player(str(rgbd_bag), PlaybackOptions(rate=2.0), lambda *a: None)
    player._anchor_wall, player._anchor_bag = 100.0, player.start_ns
    assert player.due_time(player.start_ns + 10**9) == pytest.approx(100.5)
    player.set_rate(4.0)
    bag_now = player._anchor_bag
    assert player.due_time(bag_now + 10**9) == pytest.approx(player._anchor_wall + 0.25)
    player.set_paused(True)
    assert player.due_time(bag_now + 10**9) == float("inf")
    player.reader.close()


def test_loop_plays_again_until_stopped(rgbd_bag):
    sink = Sink()
    player = Player(str(rgbd_bag), PlaybackOptions(rate=20.0, loop=True, topics=(T.COLOR,)), sink.publish)
    result = {}
    th = threading.Thread(target=lambda: result.setdefault("r", player.run()))
    th.start()
    deadline = time.monotonic() + 60
    while len(sink.published) < 30 and time.monotonic() < deadline:
        time.sleep(0.01)
    player.stop()
    th.join(10)
    rep = result["r"]
    assert rep.stopped and rep.loops >= 3
    first = [d for _, d, _ in sink.published[:12]]
    assert [d for _, d, _ in sink.published[12:24]] == first


def test_bad_options_and_bags_are_refused_with_a_reason(tmp_path, rgbd_bag):
    with pytest.raises(ValueError, match="rate must be > 0"):
        Player(str(rgbd_bag), PlaybackOptions(rate=0.0), lambda *a: None)
    with pytest.raises(BagError, match="past the end of the bag"):
        Player(str(rgbd_bag), PlaybackOptions(start_offset_s=5.0), lambda *a: None)
    with pytest.raises(BagError, match="none of the selected topics"):
        Player(str(rgbd_bag), PlaybackOptions(topics=("/nope",)), lambda *a: None)
    with BagWriter(tmp_path / "empty") as w:
        w.add_topic("/a", "std_msgs/msg/String")
    with pytest.raises(BagError, match="no messages"):
        Player(str(tmp_path / "empty"), PlaybackOptions(), lambda *a: None)
    with pytest.raises(ValueError, match="expected /from:=/to"):
        parse_remap(["/a=/b"])
    assert parse_remap(["/a:=/b"]) == {"/a": "/b"}


def test_salvaged_bag_plays_what_it_holds(tmp_path):
    bag = make_rgbd_bag(tmp_path / "full", frames=6)
    cut = tmp_path / "cut"
    cut.mkdir()
    f = next(bag.glob("*.mcap"))
    (cut / f.name).write_bytes(f.read_bytes()[: int(f.stat().st_size * 0.8)])
    player, sink, report = _play(cut, rate=10.0)
    assert 0 < len(sink.published) < 18
    assert any("not closed" in n for n in report.notes)


def test_qos_matches_the_live_graph():
    assert publisher_qos(T.COLOR, [QosSpec(reliable=False)]) == ("sensor", QosSpec(True, False, 2))
    assert publisher_qos(T.SPV_MAP) == ("latched", QosSpec(True, True, 1))
    assert publisher_qos("/lab/latched", [QosSpec(True, True, 1)])[0] == "latched"
    assert publisher_qos("/lab/fast", [QosSpec(False, False, 5)]) == ("recorded", QosSpec(False, False, 5))
    assert publisher_qos(T.SIM_COLLISIONS)[0] == "event"
    assert publisher_qos("/other") == ("recorded", QosSpec(True, False, 10))
