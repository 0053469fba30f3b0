"""Opening an SDK recording's file structure before a graph starts, without the SDK (no ROS).

``raspv launch`` (and ``--check``) runs :func:`check_recording_opens` on the `camera` node's
``file``, so a recording the SDK would fail on — a ``.db3`` cut in half, a text file with a
recording's suffix, an ``.oni`` whose recorder was killed, a DepthAI ``.mcap`` cut off — is one
line naming the file before any process starts, instead of a camera that retries for ever
behind a black headset. What is read, by format:

- RealSense ``.db3`` (SDK ≥ 2.58, a ROS 2 SQLite bag): opened as ``raspv bag info`` opens it
  (:class:`raspv_bags.reader.BagReader`); it must be undamaged and hold depth and colour images.
- RealSense ``.bag`` (older SDKs, ROS 1): opened by rosbags' ROS 1 reader; same requirement.
- OpenNI2 ``.oni``: the header and every record walked to the end record the player needs.
- DepthAI (a directory of ``.mcap`` files, or one of them): each file's records streamed
  (:class:`raspv_bags.mcap_salvage.McapSalvage`) to its end; each must hold messages.

Every failure raises :class:`~raspv_camera.rgbd_frame.CameraError` with one line naming the
file. Only the file structure is read (a few ms for the index of a large bag), never the frames.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

from raspv_camera.rgbd_frame import CameraError

ONI_MAGIC_HEADER = b"NI10"
_ONI_RECORD = struct.Struct("<IIIIIQ")      # magic, type, node id, fields size, payload size, undo position
_ONI_RECORD_MAGIC = 0x0052494E              # "NIR\0"
_ONI_NEW_DATA, _ONI_END = 10, 11
_ONI_HEADER_SIZE = 24
_REALSENSE_IMAGES = {"depth": re.compile(r"/Depth_\d+/image/data"), "colour": re.compile(r"/Color_\d+/image/data")}


def check_recording_opens(path: str | Path, sdk: str) -> None:
    """Raise :class:`CameraError` (one line naming the file) when the recording ``path`` of
    ``sdk`` ("realsense", "openni2", "depthai") cannot be played; return when it can."""
    path = Path(path).expanduser()
    if (path if path.is_dir() else path.parent).joinpath("metadata.yaml").is_file():
        raise CameraError(f"{path}: a ROS 2 bag (it has metadata.yaml), not a camera SDK's recording: play it with "
                          f"`raspv launch replay replay.bag:={path if path.is_dir() else path.parent}`")
    if sdk == "realsense":
        if path.suffix.lower() == ".bag":
            _check_rosbag1(path)
        else:
            _check_db3(path)
    elif sdk == "openni2":
        _check_oni(path)
    elif sdk == "depthai":
        from raspv_camera.depthai_driver import recording_files

        files = recording_files(path)
        if not files:
            raise CameraError(f"{path}: no .mcap file: not a DepthAI recording")
        for f in files:
            _check_mcap(f)
        if len(files) < 2:
            raise CameraError(f"{path}: a DepthAI recording needs a depth and a colour .mcap file "
                              f"(found {len(files)})")


def _realsense_streams(path: Path, counts: dict[str, int]) -> None:
    """Depth and colour image topics with messages, or a CameraError saying which is missing."""
    if not sum(counts.values()):
        raise CameraError(f"{path}: the RealSense recording holds no messages")
    for what, pattern in _REALSENSE_IMAGES.items():
        if not any(pattern.search(name) and n for name, n in counts.items()):
            raise CameraError(f"{path}: the RealSense recording has no {what} images (topics: "
                              f"{', '.join(sorted(counts))[:200]})")


def _check_db3(path: Path) -> None:
    from raspv_bags.reader import BagError, BagReader

    try:
        reader = BagReader(path)
    except BagError as exc:
        raise CameraError(f"{path}: not a readable RealSense recording ({_without_path(str(exc), path)})") from None
    try:
        if not reader.complete or reader.notes:
            raise CameraError(f"{path}: a damaged RealSense recording ({'; '.join(reader.notes) or 'incomplete'})")
        _realsense_streams(path, {t.name: t.count for t in reader.topics.values()})
    finally:
        reader.close()


def _check_rosbag1(path: Path) -> None:
    from rosbags.rosbag1 import Reader

    try:
        with Reader(path) as reader:
            counts: dict[str, int] = {}
            for c in reader.connections:
                counts[c.topic] = counts.get(c.topic, 0) + c.msgcount
    except Exception as exc:  # noqa: BLE001 - rosbags' ReaderError and the struct/OS errors of a cut file
        reason = (str(exc).strip() or type(exc).__name__).splitlines()[0]
        raise CameraError(f"{path}: not a readable RealSense (ROS 1) recording ({_without_path(reason, path)})") from None
    _realsense_streams(path, counts)


def _check_oni(path: Path) -> None:
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            header = f.read(_ONI_HEADER_SIZE)
            if not header.startswith(ONI_MAGIC_HEADER) or len(header) < _ONI_HEADER_SIZE:
                raise CameraError(f"{path}: not an OpenNI recording (no '{ONI_MAGIC_HEADER.decode()}' header)")
            offset, frames = _ONI_HEADER_SIZE, 0
            while True:
                f.seek(offset)
                head = f.read(_ONI_RECORD.size)
                if len(head) < _ONI_RECORD.size:
                    raise CameraError(f"{path}: OpenNI recording cut off at byte {offset} (no end record: "
                                      "truncated, or its recorder was killed)")
                magic, kind, _node, fields, payload, _undo = _ONI_RECORD.unpack(head)
                if magic != _ONI_RECORD_MAGIC or fields < _ONI_RECORD.size:
                    raise CameraError(f"{path}: OpenNI recording damaged at byte {offset} (not a record)")
                if kind == _ONI_END:
                    break
                if offset + fields + payload > size:
                    raise CameraError(f"{path}: OpenNI recording cut off at byte {size} (a record at byte {offset} "
                                      f"needs {fields + payload} bytes)")
                frames += kind == _ONI_NEW_DATA
                offset += fields + payload
    except OSError as exc:
        raise CameraError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not frames:
        raise CameraError(f"{path}: the OpenNI recording holds no frames")


def _check_mcap(path: Path) -> None:
    from raspv_bags.mcap_salvage import McapDamaged, McapSalvage

    try:
        scan = McapSalvage(path).scan
    except McapDamaged as exc:
        raise CameraError(f"{path}: not a DepthAI recording file ({_without_path(str(exc), path)})") from None
    if scan.stop_reason is not None or not scan.complete:
        reason = (scan.stop_reason or "incomplete").split(";")[0]
        raise CameraError(f"{path}: a damaged DepthAI recording file ({reason})")
    if not sum(scan.counts.values()):
        raise CameraError(f"{path}: the DepthAI recording file holds no messages")


def _without_path(text: str, path: Path) -> str:
    """``text`` without the leading ``<path>: `` other readers' messages start with."""
    for p in (str(path), path.name):
        if text.startswith(f"{p}: "):
            return text[len(p) + 2:]
    return text
