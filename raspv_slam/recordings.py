"""RGB-D recordings for the SLAM commands: a RASPV bag, or any folder ``raspv bag from-frames``
reads (TUM layout, rgb/ + depth/ folders, pairs of files) (no ROS).

Each frame is (stamp [s], colour RGB uint8, depth float32 metres with NaN, ground-truth pose
W ← C or None): from the bag's ``/camera/pose`` or the folder's ``groundtruth.txt``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from raspv_bags.camera_metadata import recorded_rolling_shutter
from raspv_bags.from_frames import (CAMERA_DISTORTION, CAMERA_PRESETS, CAMERA_ROLLING_SHUTTER, FramesError,
                                    discover_frames, intrinsics_for, load_intrinsics_file, read_depth)
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import RGBDFormatError, read_color

INTRINSICS_FILE = "intrinsics.yaml"      # a frames folder's own intrinsics (fx, fy, cx, cy [, width, height])


ROLLING_SHUTTER_READOUT = CAMERA_ROLLING_SHUTTER      # presets' colour readout [s] (raspv_bags.from_frames)


class RecordingError(ValueError):
    """A recording that cannot be read (one line saying why and what to pass)."""


@dataclass
class RecordingFrame:
    stamp: float
    rgb: np.ndarray | None
    depth: np.ndarray | None
    groundtruth: np.ndarray | None = None      # W ← C, metres


@dataclass
class Recording:
    path: Path
    kind: str                                   # "bag" or the frames layout (tum, folders, pairs)
    intrinsics: CameraIntrinsics
    distortion: tuple[float, ...] = ()
    count: int | None = None
    notes: list[str] = field(default_factory=list)
    _frames: object = None
    rolling_shutter: float = 0.0                # [s] readout of the colour camera's rolling shutter (0: global)
    camera: str | None = None                   # the preset in use (given, or a TUM folder's own), else None

    def frames(self, limit: int | None = None) -> Iterator[RecordingFrame]:
        n = 0
        for f in self._frames():
            if limit is not None and n >= limit:
                return
            n += 1
            yield f


def open_recording(path: str | Path, camera: str | None = None, intrinsics: dict | None = None,
                   distortion: tuple[float, ...] | None = None, rolling_shutter: float | None = None) -> Recording:
    """Open a bag (a folder with ``metadata.yaml``, an ``.mcap``/``.db3``) or a frames folder.
    ``camera``: a preset name (``tum-fr1`` …, also sets TUM's distortion and the Kinect's
    rolling-shutter readout); ``intrinsics``: fx, fy, cx, cy [px] overriding the bag's camera
    info; ``rolling_shutter``: readout [s] overriding the preset's, or the one a bag carries
    (``raspv bag from-frames`` keeps its preset's in the bag's metadata)."""
    rec = _open_recording(path, camera, intrinsics, distortion)
    if rolling_shutter is None:
        carried = recorded_rolling_shutter(rec.path) if rec.kind == "bag" and rec.camera is None else None
        rolling_shutter = carried if carried is not None else ROLLING_SHUTTER_READOUT.get(rec.camera or "", 0.0)
    rec.rolling_shutter = rolling_shutter
    return rec


def _open_recording(path, camera, intrinsics, distortion) -> Recording:
    path = Path(path).expanduser()
    if not path.exists():
        raise RecordingError(f"{path}: no such recording")
    if camera is not None and camera not in CAMERA_PRESETS:
        raise RecordingError(f"unknown camera preset {camera!r}; use one of {', '.join(CAMERA_PRESETS)}")
    values = intrinsics
    if values is None and camera is not None:
        values = dict(zip(("fx", "fy", "cx", "cy"), CAMERA_PRESETS[camera]))
    if _is_bag(path):
        return _open_bag(path, values, camera, distortion)
    return _open_frames(path, values, camera, distortion)


def _is_bag(path: Path) -> bool:
    return path.suffix in (".mcap", ".db3") or (path.is_dir() and (path / "metadata.yaml").is_file()) or \
        (path.is_dir() and any(path.glob("*.mcap")))


def _open_frames(path: Path, values: dict | None, camera: str | None, distortion) -> Recording:
    try:
        fs = discover_frames(path)
    except FramesError as exc:
        raise RecordingError(str(exc)) from None
    preset = camera or fs.camera_hint
    if values is None and (path / INTRINSICS_FILE).is_file():       # e.g. a `raspv sim walk` sequence
        values = load_intrinsics_file(path / INTRINSICS_FILE)
        preset = camera
    if values is None:
        if preset is None:
            raise RecordingError(f"{path}: no camera intrinsics; give --camera {'|'.join(CAMERA_PRESETS)} "
                                 "or --intrinsics FILE.yaml")
        values = dict(zip(("fx", "fy", "cx", "cy"), CAMERA_PRESETS[preset]))
    if not fs.pairs:
        raise RecordingError(f"{path}: no colour/depth pairs")
    first = read_color(fs.pairs[0].color)
    K = intrinsics_for(values, first.shape[1], first.shape[0])
    if distortion is None:
        distortion = CAMERA_DISTORTION.get(preset or "", ())
    notes = list(fs.notes) + ([f"camera {preset}"] if preset and camera is None else [])

    def frames() -> Iterator[RecordingFrame]:
        for pair in fs.pairs:
            try:
                rgb = read_color(pair.color)
                depth = read_depth(pair.depth, fs.depth_format, fs.depth_scale)
            except (RGBDFormatError, OSError) as exc:
                notes.append(f"skipped {pair.color.name}: {exc}")
                continue
            yield RecordingFrame(pair.stamp_s, rgb, depth, pair.pose)

    return Recording(path, fs.layout, K, tuple(distortion), len(fs.pairs), notes, frames,
                     camera=preset)          # the same preset gives the distortion above and the readout


def _open_bag(path: Path, values: dict | None, camera: str | None, distortion) -> Recording:
    from raspv_bags.reader import BagError, BagReader
    from raspv_bags.render import BagFrameSource, RenderError, RenderSettings
    from raspv_common import topics as T

    try:
        reader = BagReader(path)
    except BagError as exc:
        raise RecordingError(str(exc)) from None
    needs = {"color", "depth"} | ({"camera_pose"} if T.CAMERA_POSE in reader.topics else set())
    try:
        source = BagFrameSource(reader, RenderSettings(intrinsics=values), frozenset(needs), "SLAM")
        if values is None:
            source.first_camera_info()
    except RenderError as exc:
        reader.close()
        raise RecordingError(f"{path}: {exc}") from None
    K = source.intrinsics if values is None else None
    count = reader.topics[T.COLOR].count if T.COLOR in reader.topics else None
    if K is None:
        w, h = _first_size(reader)
        K = intrinsics_for(values, w, h)

    def frames() -> Iterator[RecordingFrame]:
        try:
            for f in source.frames(None, None):
                i = f.inputs
                yield RecordingFrame(i.stamp, i.color, i.depth, i.camera_pose)
        finally:
            reader.close()

    if distortion is None:          # the preset's, else the bag's camera info's (from-frames writes a preset's)
        distortion = CAMERA_DISTORTION.get(camera, ()) if camera else source.distortion
    return Recording(path, "bag", K, tuple(distortion), count,
                     list(reader.notes) + source.notes, frames, camera=camera)


def _first_size(reader) -> tuple[int, int]:
    from raspv_common import topics as T

    for msg in reader.messages([T.COLOR, T.DEPTH]):
        m = reader.decode(msg)
        return int(m.width), int(m.height)
    raise RecordingError(f"{reader.path}: no colour or depth images")


def read_intrinsics(path: str | Path) -> dict:
    try:
        return load_intrinsics_file(Path(path))
    except FramesError as exc:
        raise RecordingError(str(exc)) from None
