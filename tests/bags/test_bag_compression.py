"""Compressed recordings (issue 36, item 1): MCAP chunks compressed losslessly (zstd, lz4) hold
the same messages, every reader opens them — ours, rosbags itself, the salvage of a recorder
killed after a flush — and the files are smaller; refusals are one line."""
from __future__ import annotations

import pytest
from rosbags.rosbag2 import Reader

from raspv_bags.reader import BagReader
from raspv_bags.recording import Recording
from raspv_bags.writer import BagWriteError, BagWriter, QosSpec

from .conftest import make_rgbd_bag


def _messages(bag) -> list[tuple[str, str, int, bytes]]:
    with BagReader(bag) as r:
        types = {name: t.msgtype for name, t in r.topics.items()}
        return [(m.topic, types[m.topic], m.timestamp_ns, bytes(m.data)) for m in r.messages()]


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_compressed_chunks_hold_the_same_messages_for_every_reader(tmp_path, compression):
    source = _messages(make_rgbd_bag(tmp_path / "plain", frames=12, size=(160, 120)))
    w = BagWriter(tmp_path / "packed", "mcap", flush_interval_s=None, compression=compression)
    for i, (topic, msgtype, stamp, data) in enumerate(source):
        w.add_topic(topic, msgtype, [QosSpec()])
        w.write(topic, stamp, data)
        if i == len(source) // 2:
            w.flush()         # what a killed recorder leaves: the flushed chunks, no summary or footer
            killed = tmp_path / "killed"
            killed.mkdir()
            mcap = next((tmp_path / "packed").glob("*.mcap"))
            (killed / mcap.name).write_bytes(mcap.read_bytes())
    w.close()
    assert _messages(tmp_path / "packed") == source
    with Reader(tmp_path / "packed") as plain:          # rosbags without our salvage
        assert [bytes(d) for _, _, d in plain.messages()] == [m[3] for m in source]
    with BagReader(killed) as r:
        assert not r.complete
    assert _messages(killed) == source[:len(source) // 2 + 1]
    # the test images are ramps: far more than the 1.5× a compressor that did nothing could not reach
    assert w.bytes_written > 5 * w.file_bytes, (w.bytes_written, w.file_bytes)


def test_compression_refusals_are_one_line_and_the_recorder_compresses_mcap_by_default(tmp_path):
    with pytest.raises(BagWriteError, match="unknown compression 'zip'; use one of zstd, lz4, none"):
        BagWriter(tmp_path / "a", compression="zip")
    with pytest.raises(BagWriteError, match="is for MCAP bags"):
        BagWriter(tmp_path / "b", "sqlite3", compression="zstd")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    for storage, expected in (("mcap", "zstd"), ("sqlite3", "none")):
        rec = Recording(tmp_path / storage, storage)
        assert rec.writer.compression == expected
        rec.close()
