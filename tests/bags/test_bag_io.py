"""Writing and reading bags: round trips, raspv_msgs types, unfinished and damaged bags."""
from __future__ import annotations

import shutil
import sqlite3

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import Reader

from raspv_bags.reader import BagError, BagReader
from raspv_bags.repair import repair_bag
from raspv_bags.message_types import ensure_type, typestore
from raspv_bags.writer import BagWriteError, BagWriter, QosSpec
from raspv_common import topics as T
from raspv_common.conversions import depth_from_image, rgb_from_image

from .conftest import make_rgbd_bag


def _payloads(n: int, size: int = 3000) -> list[bytes]:
    """CDR-like payloads (4-byte encapsulation header + distinct bytes)."""
    rng = np.random.default_rng(1)
    return [b"\x00\x01\x00\x00" + rng.integers(0, 255, size, dtype=np.uint8).tobytes() for _ in range(n)]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_round_trip_keeps_bytes_order_types_and_qos(tmp_path, storage):
    data = _payloads(20)
    with BagWriter(tmp_path / "b", storage, flush_interval_s=None) as w:
        w.add_topic("/a", "sensor_msgs/Image", [QosSpec(True, False, 2)])
        w.add_topic(T.SPV_MAP, "raspv_msgs/msg/PhospheneMap", [QosSpec(True, True, 1)])
        for i, d in enumerate(data):
            w.write("/a", 1_000_000_000 + i * 50_000_000, d)
    with BagReader(tmp_path / "b") as r:
        assert r.complete and r.notes == [] and r.storage == storage
        assert r.topics["/a"].msgtype == "sensor_msgs/msg/Image" and r.topics["/a"].count == 20
        assert r.topics[T.SPV_MAP].qos == (QosSpec(True, True, 1),) and r.topics[T.SPV_MAP].count == 0
        msgs = list(r.messages())
        assert [bytes(m.data) for m in msgs] == data
        assert [m.timestamp_ns for m in msgs] == [1_000_000_000 + i * 50_000_000 for i in range(20)]
        assert r.duration_s == pytest.approx(0.95)
        # start offset and topic filter
        assert len(list(r.messages(["/a"], start_ns=1_500_000_000))) == 10


def test_writer_refuses_existing_directory_unknown_storage_and_undeclared_topics(tmp_path):
    (tmp_path / "exists").mkdir()
    with pytest.raises(BagWriteError, match="exists already"):
        BagWriter(tmp_path / "exists")
    with pytest.raises(BagWriteError, match="unknown storage"):
        BagWriter(tmp_path / "x", "rosbag1")
    with pytest.raises(BagWriteError, match="is not a directory"):
        BagWriter(tmp_path / "missing" / "x")
    with BagWriter(tmp_path / "ok") as w:
        with pytest.raises(BagWriteError, match="was not added"):
            w.write("/nope", 0, b"1234")
        with pytest.raises(BagWriteError, match="unknown and has no definition"):
            w.add_topic("/c", "nobody_msgs/msg/Thing")


def test_rosbags_and_rclpy_serialise_raspv_and_image_messages_identically():
    """Bags hold rclpy's bytes (record) and rosbags' bytes (from-frames): they must agree."""
    from raspv_msgs.msg import PhospheneFrame
    from sensor_msgs.msg import Image

    from raspv_common.conversions import array_to_image

    frame = PhospheneFrame(map_id=7, mode="depth", overlays=["stairs"], levels=[0, 3, 7], brightness=[0.0, 0.5, 1.0],
                           temporal=True)
    frame.header.frame_id = "phosphene"
    frame.source_stamp.sec = 12
    raw = serialize_message(frame)
    store = typestore()
    back = store.deserialize_cdr(raw, "raspv_msgs/msg/PhospheneFrame")
    assert back.mode == "depth" and list(back.levels) == [0, 3, 7] and back.source_stamp.sec == 12
    # rosbags' bytes read back in rclpy as the same message (only CDR padding bytes may differ)
    assert deserialize_message(bytes(store.serialize_cdr(back, "raspv_msgs/msg/PhospheneFrame")), PhospheneFrame) == frame
    img = array_to_image(np.arange(12, dtype=np.uint8).reshape(2, 2, 3), "rgb8")
    again = store.serialize_cdr(store.deserialize_cdr(serialize_message(img), "sensor_msgs/msg/Image"), "sensor_msgs/msg/Image")
    assert deserialize_message(bytes(again), Image) == img


def test_installed_message_types_load_on_demand():
    assert ensure_type("sensor_msgs/msg/Image")
    assert ensure_type("raspv_msgs/StairDetection")
    assert not ensure_type("nobody_msgs/msg/Thing")


def test_rgbd_bag_decodes_to_the_arrays_written(rgbd_bag):
    with BagReader(rgbd_bag) as r:
        assert {T.COLOR, T.DEPTH, T.CAMERA_INFO} <= set(r.topics)
        color = next(m for m in r.messages([T.COLOR]))
        depth = list(r.messages([T.DEPTH]))[3]
        c = rgb_from_image(r.decode(color))
        d = depth_from_image(r.decode(depth))
    assert c.shape == (48, 64, 3) and c[0, 0, 0] == 0 and c[0, -1, 0] == 200
    assert d.shape == (48, 64) and np.allclose(d, 1.3)


def _cut(src, dst, nbytes):
    """A copy of the mcap bag ``src`` whose file ends after ``nbytes`` and has no metadata.yaml."""
    dst.mkdir()
    f = next(src.glob("*.mcap"))
    (dst / f.name).write_bytes(f.read_bytes()[:nbytes])
    return dst


def test_an_mcap_cut_anywhere_yields_what_precedes_the_cut(tmp_path):
    bag = make_rgbd_bag(tmp_path / "full", frames=10)
    size = next(bag.glob("*.mcap")).stat().st_size
    with BagReader(bag) as r:
        full = [bytes(m.data) for m in r.messages()]
    seen = []
    for k, frac in enumerate(np.linspace(0.05, 0.98, 12)):
        cut = _cut(bag, tmp_path / f"cut{k}", int(size * frac))
        try:
            with BagReader(cut) as r:
                assert not r.complete
                assert any("not closed" in n for n in r.notes)
                got = [bytes(m.data) for m in r.messages()]
        except BagError as exc:  # only when even the first schema/channel records are cut off
            assert "no readable records" in str(exc)
            got = []
        assert got == full[:len(got)], "salvaged messages must be the bag's first messages, unchanged"
        seen.append(len(got))
    assert seen == sorted(seen) and seen[-1] > 0.8 * len(full)


def test_a_flushed_but_never_closed_mcap_writer_loses_nothing_flushed(tmp_path):
    data = _payloads(30)
    w = BagWriter(tmp_path / "live", "mcap", flush_interval_s=None)
    w.add_topic("/a", "std_msgs/msg/String")
    for i, d in enumerate(data):
        w.write("/a", 10**9 + i, d)
        if i == 19:
            w.flush()
            snapshot = _cut(tmp_path / "live", tmp_path / "snap", 10**12)  # the files as a kill would leave them
    w.close()
    with BagReader(snapshot) as r:
        assert [bytes(m.data) for m in r.messages()] == data[:20]
        assert r.topics["/a"].count == 20


def test_killed_sqlite_writer_keeps_the_committed_messages(tmp_path):
    data = _payloads(12)
    w = BagWriter(tmp_path / "db", "sqlite3", flush_interval_s=None)
    w.add_topic("/a", "std_msgs/msg/String")
    for i, d in enumerate(data[:8]):
        w.write("/a", 10**9 + i, d)
    w.flush()
    for i, d in enumerate(data[8:]):
        w.write("/a", 2 * 10**9 + i, d)
    db = next((tmp_path / "db").glob("*.db3"))
    snap = tmp_path / "snap"
    snap.mkdir()
    for f in (tmp_path / "db").iterdir():  # database and its hot journal, as a SIGKILL leaves them
        shutil.copy(f, snap / f.name)
    w.close()
    with BagReader(snap) as r:
        assert not r.complete
        assert [bytes(m.data) for m in r.messages()] == data[:8]
    assert sqlite3.connect(db).execute("select count(*) from messages").fetchone()[0] == 12


def test_repair_makes_a_complete_bag_every_reader_opens(tmp_path):
    bag = make_rgbd_bag(tmp_path / "full", frames=8)
    cut = _cut(bag, tmp_path / "cut", int(next(bag.glob("*.mcap")).stat().st_size * 0.7))
    with BagReader(cut) as r:
        salvaged = [bytes(m.data) for m in r.messages()]
    report = repair_bag(cut, tmp_path / "fixed")
    assert report.message_count == len(salvaged) > 0
    with Reader(tmp_path / "fixed") as plain:  # rosbags itself, no salvage
        assert [bytes(d) for _, _, d in plain.messages()] == salvaged


def test_damaged_bags_give_one_clear_line(tmp_path):
    with pytest.raises(BagError, match="no such bag"):
        BagReader(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagError, match="not a bag"):
        BagReader(tmp_path / "empty")
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "junk.mcap").write_bytes(b"this is not a bag at all" * 10)
    with pytest.raises(BagError, match="not an MCAP file"):
        BagReader(junk)
    (tmp_path / "db").mkdir()
    (tmp_path / "db" / "db.db3").write_bytes(b"garbage" * 100)
    with pytest.raises(BagError, match="not a readable SQLite bag"):
        BagReader(tmp_path / "db")
    txt = tmp_path / "notes.txt"
    txt.write_text("hello")
    with pytest.raises(BagError, match="expected .mcap or .db3"):
        BagReader(txt)


def test_corrupted_bytes_inside_a_bag_keep_the_readable_part(tmp_path):
    bag = make_rgbd_bag(tmp_path / "b", frames=10)
    f = next(bag.glob("*.mcap"))
    raw = bytearray(f.read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 30000] = b"\xff" * 30000  # longer than a frame's records: smashes record headers
    raw[-30:] = b"\x00" * 30                 # and the footer
    f.write_bytes(bytes(raw))
    with BagReader(bag) as r:
        assert not r.complete and r.notes
        got = list(r.messages())
    assert 0 < len(got) < 30


def test_broken_metadata_falls_back_to_the_storage_file(rgbd_bag):
    (rgbd_bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed")
    with BagReader(rgbd_bag) as r:
        assert any("metadata.yaml" in n for n in r.notes)
        assert r.topics[T.COLOR].count == 12


def test_types_defined_only_in_the_bag_are_registered_from_its_definition(tmp_path):
    definition = "int32 a\nstring b\n"
    with BagWriter(tmp_path / "b", flush_interval_s=None) as w:
        w.add_topic("/custom", "lab_msgs/msg/Trial", msgdef=definition)
        w.add_topic("/opaque", "lab_msgs/msg/Opaque", msgdef="")
        w.write("/custom", 5, b"\x00\x01\x00\x00" + (42).to_bytes(4, "little") + (2).to_bytes(4, "little") + b"x\x00")
        w.write("/opaque", 6, b"\x00\x01\x00\x00\x01\x02")
    with BagReader(tmp_path / "b") as r:
        assert r.topics["/custom"].known_type
        assert not r.topics["/opaque"].known_type
        assert any("/opaque" in n and "unknown" in n for n in r.notes)
        custom = next(r.messages(["/custom"]))
        assert r.decode(custom).a == 42 and r.decode(custom).b == "x"
        with pytest.raises(BagError, match="cannot decode lab_msgs/msg/Opaque"):
            r.decode(next(r.messages(["/opaque"])))
