"""What the wearer saw: the share of frames in the configured representation (raspv_common.shown_share)
on synthetic frame sequences, and from bags — one in today's format, one recorded before
PhospheneFrame had configured_mode (decoded with its own stored definition, the mode inferred)."""
from __future__ import annotations

import subprocess
import sys

import pytest

from raspv_common.shown_share import ShownFrame, fallback_kinds, shown_share


def frames(spec: list[tuple[str, tuple[str, ...]]], period: float = 0.02, configured=("chess_floor", ("path",))):
    return [ShownFrame(i * period, m, o, *configured) for i, (m, o) in enumerate(spec)]


def test_share_counts_frames_and_seconds_per_fallback_kind():
    spec = ([("chess_floor", ("path",))] * 90 + [("depth", ("path",))] * 5 + [("chess_floor", ())] * 3
            + [("no_data", ())] * 2)
    share = shown_share(frames(spec))
    assert (share.frames, share.own_frames, share.share) == (100, 90, 0.9)
    assert share.expected_mode == "chess_floor" and share.expected_overlays == ("path",) and not share.inferred
    assert share.fallbacks["mode:depth"] == {"frames": 5, "seconds": pytest.approx(0.1)}
    assert share.fallbacks["overlays:-path"]["frames"] == 3 and share.fallbacks["no_data"]["frames"] == 2
    assert share.seconds == pytest.approx(2.0) and share.own_seconds == pytest.approx(1.8)
    # irregular stamps: each frame lasts until the next; the last until end_t
    uneven = [ShownFrame(0.0, "depth"), ShownFrame(0.5, "grey"), ShownFrame(0.6, "depth")]
    s = shown_share(uneven, "depth", (), end_t=1.0)
    assert s.fallbacks["mode:grey"]["seconds"] == pytest.approx(0.1) and s.own_seconds == pytest.approx(0.9)


def test_expected_mode_given_configured_or_inferred():
    spec = [("depth", ())] * 8 + [("grey", ())] * 2
    # a trial's condition decides: frames shown before the node switched to it are not its own
    assert shown_share(frames(spec, configured=("grey", ())), "grey", ()).share == pytest.approx(0.2)
    # configured_mode present: it is the expectation
    assert shown_share(frames(spec, configured=("depth", ()))).share == pytest.approx(0.8)
    # an old recording (no configured_mode): the most frequent mode shown, not counting no_data
    old = [ShownFrame(i * 0.1, m) for i, m in enumerate(["no_data"] * 20 + ["depth"] * 7 + ["grey"] * 3)]
    s = shown_share(old)
    assert s.inferred and s.expected_mode == "depth" and s.own_frames == 7 and s.fallbacks["no_data"]["frames"] == 20
    assert "inferred" in s.describe() and "no_data 20 frames" in s.describe()
    empty = shown_share([], "depth")
    assert empty.frames == 0 and empty.share == 1.0
    assert fallback_kinds(ShownFrame(0, "depth", ("stairs",)), "depth", ("path",)) == ["overlays:-path", "overlays:+stairs"]


GAZE_FIELDS = ("field_offset_", "saccade")


def write_frames(path, legacy: bool | str, spec):
    """A bag of /spv/frame messages, in today's format, the one before the gaze fields
    (``legacy="before_gaze"``) or the one before configured_mode (``legacy=True``)."""
    from rosbags.typesys import get_types_from_msg

    from raspv_bags.message_types import raspv_msg_dir, typestore
    from raspv_bags.writer import BagWriter

    store = typestore()
    text = (raspv_msg_dir() / "PhospheneFrame.msg").read_text()
    msgtype = "raspv_msgs/msg/PhospheneFrame"
    serialise_as = msgtype
    if legacy:        # the definition as it was: no gaze fields (and no configured_mode / configured_overlays / sprite_levels)
        old = GAZE_FIELDS if legacy == "before_gaze" else ("configured_", "sprite_levels", *GAZE_FIELDS)
        lines = [line for line in text.splitlines() if not any(line.startswith(f) or f" {f}" in line.split("#")[0]
                                                                for f in old)]
        text = "\n".join(line for line in lines if not line.lstrip().startswith(("# (stale", "# this on the display")))
        serialise_as = f"test_legacy_{'gaze' if legacy == 'before_gaze' else 'old'}/msg/PhospheneFrame"
        if serialise_as not in store.fielddefs:
            store.register(get_types_from_msg(text, serialise_as))
    cls = store.types[serialise_as]
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    import numpy as np

    with BagWriter(path) as w:
        if legacy:   # the definition stored as a recorder of that time stored it (rosbags, below BagWriter)
            w._connections["/spv/frame"] = w._writer.add_connection(
                "/spv/frame", msgtype, rihs01="RIHS01_" + "0" * 64,
                msgdef=text + "\n" + "=" * 80 + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
                + "=" * 80 + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
            w.counts["/spv/frame"], w.types["/spv/frame"] = 0, msgtype
        else:
            w.add_topic("/spv/frame", msgtype)
        for i, (mode, overlays, configured) in enumerate(spec):
            t = Time(sec=i // 50, nanosec=(i % 50) * 20_000_000)
            fields = dict(header=Header(stamp=t, frame_id="phosphene"), source_stamp=t, scene_stamp=t, map_id=1,
                          mode=mode, overlays=list(overlays), levels=np.zeros(3, np.uint8),
                          brightness=np.zeros(3, np.float32), temporal=False)
            if legacy != True:  # noqa: E712
                fields.update(configured_mode=configured[0], configured_overlays=list(configured[1]),
                              sprite_levels=np.zeros(0, np.uint8))
            if not legacy:
                fields.update(field_offset_x_px=-12.0, field_offset_y_px=3.0, saccade=False)
            w.write("/spv/frame", 1_000_000_000 + i * 20_000_000, store.serialize_cdr(cls(**fields), serialise_as))


@pytest.mark.parametrize("legacy", [False, "before_gaze", True])
def test_bag_info_prints_the_share(tmp_path, legacy):
    spec = [("chess_floor", ("path",), ("chess_floor", ("path",)))] * 45 + [("depth", ("path",), ("chess_floor", ("path",)))] * 5
    write_frames(tmp_path / "bag", legacy, spec)
    out = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "bag", "info", str(tmp_path / "bag")],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    line = next(l for l in out.stdout.splitlines() if l.startswith("shown:"))
    assert "90.0 % of 50 frames in chess_floor+path" in line and "mode:depth 5 frames / 0.10 s" in line
    assert ("inferred" in line) == (legacy is True)
