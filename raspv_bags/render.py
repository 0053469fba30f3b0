"""Offline rendering of a bag into a phosphene video (no ROS imports).

The phosphenes come from :class:`raspv_spv.simulator.PhospheneSimulator` — the same object the
live ``spv`` node runs — driven the way the node drives it: the display steps at the
simulator's frame rate (50 Hz by default) on the bag's clock, and each display frame uses the
latest RGB-D frame received before it (a camera frame's levels are computed once, however
many display frames show it). Nothing waits for real time, so it runs as fast as the machine
allows.

:class:`BagFrameSource` turns a bag into RGB-D frames: colour, depth and camera info paired by
header stamp (exactly, else nearest within a tolerance), decoded only when used; the latest
``/camera/pose`` goes along when the mode reads it. Problems that leave the rest usable (an
undecodable message, a depth image of another size, camera info for another resolution) are
noted and handled; only what makes the whole render impossible raises :class:`RenderError`.

:func:`render_bag` writes an mp4 (:mod:`raspv_bags.video_sink`: mp4v through OpenCV, or H.264
with the ``video`` extra; encoded in a second thread) and/or PNG frames; ``side_by_side`` puts the colour image and the mode's other inputs (depth as
a colour map) next to the phosphenes.
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

import cv2
import numpy as np

from raspv_bags.from_frames import FramesError, intrinsics_for
from raspv_bags.reader import BagError, BagMessage, BagReader
from raspv_bags.video_sink import VideoError, VideoSink, require_codec
from raspv_common import topics as T
from raspv_common.conversions import (camera_info_distortion, camera_info_to_intrinsics, depth_from_image,
                                      pose_to_matrix, rgb_from_image)
from raspv_common.frames import is_map_frame
from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.config import config_from_node_params
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.simulator import InputError, PhospheneSimulator

# Inputs a bag provides, and those computed offline from them by the scene node's core.
BAG_INPUTS = frozenset({"color", "depth", "camera", "camera_pose", "nav_path"})
SCENE_INPUTS = frozenset({"scene", "scene_labels"})
# scene classes named in the side-by-side legend (raspv_perception.scene_labels ids)
SCENE_LEGEND = (("floor", 1), ("wall", 2), ("table/step", 3), ("obstacle", 4), ("blocked floor", 6), ("other", 5))
PANEL_LABEL_SCALE = 0.5


class RenderError(ValueError):
    """A render that cannot be done (the message says why and what to pass)."""


@dataclass
class RenderSettings:
    """What to render. ``spv``: values of the ``spv`` node's parameters (``device``, ``mode``,
    ``width``, ``rate``, ``temporal``, ``max_depth`` …, see ``raspv_spv/spv_params.py``); the
    others keep the node's defaults, so a render shows what the live node shows with the same
    parameters. ``intrinsics``: fx, fy, cx, cy [px] used when the bag has no camera info (or
    to override it)."""

    spv: dict[str, Any] = field(default_factory=dict)
    scene: dict[str, Any] = field(default_factory=dict)
    side_by_side: bool = False
    start_s: float = 0.0
    duration_s: float | None = None
    intrinsics: dict[str, float] | None = None
    color_topic: str = T.COLOR
    depth_topic: str = T.DEPTH
    info_topic: str = T.CAMERA_INFO
    pose_topic: str = T.CAMERA_POSE
    path_topic: str = T.NAV_PATH
    pair_tolerance_s: float = 0.02
    codec: str = "mp4v"          # the video's: mp4v (OpenCV) or h264 (the video extra), raspv_bags.video_sink

    def spv_params(self) -> dict[str, Any]:
        """The spv node's parameter values: defaults plus :attr:`spv`, validated by the node's
        schema (:class:`RenderError` naming what is allowed)."""
        from raspv_common.params import ParamSchema
        from raspv_spv.spv_params import PARAMS

        schema = ParamSchema.of(PARAMS)
        values, errors = schema.validate(self.spv)
        if errors:
            raise RenderError("; ".join(f"{k}: {m}" for k, m in errors))
        return {**schema.defaults(), **values}

    def scene_params(self) -> dict[str, Any]:
        """The scene node's parameter values (defaults plus :attr:`scene`), validated."""
        from raspv_common.params import ParamSchema
        from raspv_perception.scene_params import PARAMS

        schema = ParamSchema.of(PARAMS)
        values, errors = schema.validate(self.scene)
        if errors:
            raise RenderError("scene " + "; ".join(f"{k}: {m}" for k, m in errors))
        return {**schema.defaults(), **values}


class OfflineScene:
    """The ``scene`` node's work on the frames of a bag: :class:`ScenePerception` (the node's
    core, configured from its parameters) on every depth frame, in order, with the camera pose
    as prior when the node would use it (``use_pose_prior``, within ``pose_max_age``)."""

    def __init__(self, params: dict[str, Any]) -> None:
        import dataclasses

        from raspv_perception.scene_config import SceneConfig
        from raspv_perception.scene_params import CONFIG_FIELDS
        from raspv_perception.scene_perception import ScenePerception

        try:
            config = dataclasses.replace(SceneConfig(), **{k: params[k] for k in CONFIG_FIELDS})
        except ValueError as exc:
            raise RenderError(f"scene perception: {exc}") from None
        self.perception = ScenePerception(config)
        self.params = params

    def add(self, inputs: FrameInputs, pose_stamp_s: float | None) -> None:
        prior = None
        if (self.params["use_pose_prior"] and inputs.camera_pose is not None and pose_stamp_s is not None
                and abs(pose_stamp_s - inputs.stamp) <= self.params["pose_max_age"]):
            prior = inputs.camera_pose
        result = self.perception.process(inputs.depth, inputs.camera, prior)
        inputs.scene, inputs.scene_labels = result.structure, result.labels


@dataclass
class RgbdFrame:
    bag_ns: int               # bag time at which the frame was complete
    inputs: FrameInputs


@dataclass
class RenderReport:
    frames: int               # display frames written
    camera_frames: int        # RGB-D frames used
    bag_s: float              # bag time covered
    wall_s: float
    video: Path | None
    png_dir: Path | None
    size: tuple[int, int]     # output frame width, height
    rate: float               # display rate = video frame rate [Hz]
    notes: list[str]

    @property
    def speed(self) -> float:
        """Bag seconds rendered per wall-clock second."""
        return self.bag_s / self.wall_s if self.wall_s > 0 else float("inf")


class BagFrameSource:
    """RGB-D frames of a bag (see the module docstring)."""

    def __init__(self, reader: BagReader, settings: RenderSettings, needs: frozenset[str], what: str) -> None:
        """``what``: the mode and overlays, for messages (e.g. "mode 'grey' + overlay 'path'")."""
        self.reader = reader
        self.s = settings
        self.notes: list[str] = []
        unsupported = sorted(needs - BAG_INPUTS - SCENE_INPUTS)
        if unsupported:
            raise RenderError(f"{what} needs {', '.join(unsupported)}, which offline rendering does not "
                              f"provide (it has {', '.join(sorted(BAG_INPUTS | SCENE_INPUTS))})")
        have = reader.topics
        self.scene = OfflineScene(settings.scene_params()) if needs & SCENE_INPUTS else None
        self.want_color = "color" in needs or settings.side_by_side
        self.want_depth = "depth" in needs or self.scene is not None
        self.want_pose = "camera_pose" in needs or (self.scene is not None and settings.pose_topic in have)
        self.want_path = "nav_path" in needs
        self.nav_path: np.ndarray | None = None
        if self.scene is not None and "depth" not in needs:
            needs = needs | {"depth"}  # scene perception works on depth
        listing = ", ".join(sorted(have)) or "none"
        for want, topic, kind in ((self.want_color and "color" in needs, settings.color_topic, "colour"),
                                  (self.want_depth, settings.depth_topic, "depth"),
                                  ("camera_pose" in needs, settings.pose_topic, "camera pose"),
                                  (self.want_path, settings.path_topic, "navigation path")):
            if want and topic not in have:
                raise RenderError(f"{what} needs {kind} messages but the bag has no {topic} "
                                  f"(its topics: {listing})")
        if self.want_color and settings.color_topic not in have:
            self.want_color = False
            self.notes.append(f"no {settings.color_topic} in the bag: side-by-side shows the other panels only")
        if not (self.want_color or self.want_depth):
            raise RenderError(f"nothing to render: the bag has neither {settings.color_topic} nor {settings.depth_topic}")
        self.intrinsics: CameraIntrinsics | None = None
        self.distortion: tuple[float, ...] = ()     # of the first usable camera info (OpenCV coefficients)
        self.fixed_intrinsics = settings.intrinsics
        if self.fixed_intrinsics is None and settings.info_topic not in have:
            raise RenderError(f"the bag has no camera info ({settings.info_topic}); give the intrinsics "
                              f"(--fx --fy --cx --cy or --intrinsics FILE)")
        self._noted: set[str] = set()

    def _note_once(self, key: str, text: str) -> None:
        if key not in self._noted:
            self._noted.add(key)
            self.notes.append(text)

    def _decode(self, msg: BagMessage) -> Any | None:
        try:
            return self.reader.decode(msg)
        except BagError as exc:
            self._note_once(f"decode:{msg.topic}", f"skipped undecodable messages, first: {exc}")
            return None

    def frames(self, start_ns: int | None, stop_ns: int | None) -> Iterator[RgbdFrame]:
        s = self.s
        topics = [s.info_topic] if self.fixed_intrinsics is None else []
        topics += [t for t, w in ((s.color_topic, self.want_color), (s.depth_topic, self.want_depth),
                                  (s.pose_topic, self.want_pose), (s.path_topic, self.want_path)) if w]
        if self.fixed_intrinsics is None:
            self.first_camera_info()
        tol = int(s.pair_tolerance_s * 1e9)
        colors: deque[tuple[int, BagMessage]] = deque(maxlen=10)
        depths: deque[tuple[int, BagMessage]] = deque(maxlen=10)
        pose = None
        both = self.want_color and self.want_depth
        for msg in self.reader.messages(topics, start_ns=start_ns, stop_ns=stop_ns):
            if msg.topic == s.info_topic:
                info = self._decode(msg)
                if info is not None:
                    try:
                        self.intrinsics = camera_info_to_intrinsics(info)
                    except ValueError as exc:
                        self._note_once("info", f"ignored camera info without calibration ({exc})")
                continue
            if msg.topic == s.pose_topic:
                pose = msg
                continue
            if msg.topic == s.path_topic:
                self._path(msg)
                continue
            stamp = _header_stamp_ns(msg)
            if stamp is None:
                self._note_once(f"stamp:{msg.topic}", f"{msg.topic}: unreadable header; messages skipped")
                continue
            if not both:
                frame = self._frame(msg.timestamp_ns, msg if self.want_color else None,
                                    msg if self.want_depth else None, pose)
            else:
                mine, other = (colors, depths) if msg.topic == s.color_topic else (depths, colors)
                best = min(other, key=lambda e: abs(e[0] - stamp), default=None)
                if best is None or abs(best[0] - stamp) > tol:
                    mine.append((stamp, msg))
                    continue
                other.remove(best)
                # Anything older than the pair will never be paired any more.
                for q in (colors, depths):
                    while q and q[0][0] < min(stamp, best[0]) - tol:
                        q.popleft()
                c, d = (msg, best[1]) if msg.topic == s.color_topic else (best[1], msg)
                frame = self._frame(msg.timestamp_ns, c, d, pose)
            if frame is not None:
                yield frame

    def _path(self, msg: BagMessage) -> None:
        """``nav_msgs/Path`` in the world frame → (N, 3) points for the path overlay (as the spv node)."""
        path = self._decode(msg)
        if path is None:
            return
        if not is_map_frame(path.header.frame_id):
            self._note_once("pathframe", f"ignored {msg.topic} in frame {path.header.frame_id!r}; expected 'map'")
            return
        self.nav_path = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in path.poses],
                                 dtype=float).reshape(-1, 3)

    def first_camera_info(self) -> None:
        for msg in self.reader.messages([self.s.info_topic]):
            info = self._decode(msg)
            if info is None:
                continue
            try:
                self.intrinsics = camera_info_to_intrinsics(info)
            except ValueError:
                continue
            try:
                self.distortion = camera_info_distortion(info)
            except ValueError as exc:
                self._note_once("distortion", f"camera info: {exc}; its distortion is ignored")
            return
        if self.intrinsics is None:
            raise RenderError(f"no usable camera info on {self.s.info_topic}; give the intrinsics "
                              f"(--fx --fy --cx --cy or --intrinsics FILE)")

    def _frame(self, bag_ns: int, cmsg: BagMessage | None, dmsg: BagMessage | None,
               pmsg: BagMessage | None) -> RgbdFrame | None:
        color = depth = None
        try:
            if cmsg is not None:
                m = self._decode(cmsg)
                if m is None:
                    return None
                color = np.ascontiguousarray(rgb_from_image(m))
            if dmsg is not None:
                m = self._decode(dmsg)
                if m is None:
                    return None
                depth = depth_from_image(m)
        except ValueError as exc:  # unsupported encoding, inconsistent size/step
            self._note_once(f"image:{exc}", f"skipped images: {exc}")
            return None
        ref = color if color is not None else depth
        h, w = ref.shape[:2]
        if color is not None and depth is not None and depth.shape != (h, w):
            dh, dw = depth.shape
            if abs(dw / dh - w / h) > 0.01:
                self._note_once("shape", f"skipped frames whose colour ({w}x{h}) and depth ({dw}x{dh}) differ in shape")
                return None
            depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_NEAREST)
            self._note_once("resize", f"depth {dw}x{dh} resampled (nearest) to the colour's {w}x{h}")
        cam = self._camera(w, h)
        if cam is None:
            return None
        pose = pose_stamp = None
        if pmsg is not None:
            pm = self._decode(pmsg)
            if pm is not None:
                try:
                    pose = pose_to_matrix(pm.pose)
                    pose_stamp = pm.header.stamp.sec + pm.header.stamp.nanosec * 1e-9
                except ValueError:
                    pose = None
        stamp = _header_stamp_ns(dmsg if dmsg is not None else cmsg) * 1e-9
        inputs = FrameInputs(color=color, depth=depth, camera=cam, stamp=stamp, camera_pose=pose)
        if self.want_path:
            if self.nav_path is None:
                return None  # no path received yet: the overlay cannot run on this frame
            inputs.extras["nav_path"] = self.nav_path
        if self.scene is not None:
            self.scene.add(inputs, pose_stamp)
        return RgbdFrame(bag_ns, inputs)

    def _camera(self, w: int, h: int) -> CameraIntrinsics | None:
        if self.fixed_intrinsics is not None:
            try:
                return intrinsics_for(self.fixed_intrinsics, w, h)
            except FramesError as exc:
                raise RenderError(str(exc)) from None
        cam = self.intrinsics
        if (cam.width, cam.height) == (w, h):
            return cam
        if abs(cam.width / cam.height - w / h) > 0.01:
            self._note_once("infoshape", f"skipped frames of {w}x{h}: the camera info is for {cam.width}x{cam.height}")
            return None
        self._note_once("infoscale", f"camera info for {cam.width}x{cam.height} rescaled to the images' {w}x{h}")
        return cam.scaled(w, h)


def _header_stamp_ns(msg: BagMessage) -> int | None:
    """Header stamp of a serialised message that starts with a std_msgs/Header (CDR: 4-byte
    encapsulation header, then int32 sec, uint32 nanosec) — read without deserialising."""
    data = msg.data
    if len(data) < 12:
        return None
    le = bytes(data[1:2]) in (b"\x01", b"\x03")
    sec = int.from_bytes(bytes(data[4:8]), "little" if le else "big", signed=True)
    nsec = int.from_bytes(bytes(data[8:12]), "little" if le else "big")
    return sec * 1_000_000_000 + nsec


# -- output -----------------------------------------------------------------------------------

def _bgr(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(img, cv2.COLOR_RGB2BGR)


def _text_band(img: np.ndarray, width: int) -> None:
    """Darken the top-left corner behind a caption so it reads on any image."""
    band = img[:28, :min(img.shape[1], width + 16)]
    band[:] = (band * 0.35).astype(np.uint8)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    _text_band(img, cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, PANEL_LABEL_SCALE, 1)[0][0])
    cv2.putText(img, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, PANEL_LABEL_SCALE, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def depth_panel(depth: np.ndarray, max_depth: float) -> np.ndarray:
    """Depth (m, NaN holes) → BGR colour map, near = warm, holes black."""
    d = np.nan_to_num(depth, nan=0.0)
    scaled = np.clip(255.0 - d * (255.0 / max_depth), 0, 255).astype(np.uint8)
    out = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
    out[~np.isfinite(depth) | (d <= 0)] = 0
    return out


def _legend(img: np.ndarray, items: tuple[tuple[str, int], ...]) -> np.ndarray:
    """Words in their class colours along the top of a panel."""
    from raspv_perception.scene_labels import COLORS

    widths = [cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, PANEL_LABEL_SCALE, 1)[0][0] for t, _ in items]
    _text_band(img, sum(widths) + 12 * (len(items) - 1))
    x = 8
    for (text, cls), w in zip(items, widths):
        colour = tuple(int(c) for c in COLORS[cls][::-1])
        cv2.putText(img, text, (x, 20), cv2.FONT_HERSHEY_SIMPLEX, PANEL_LABEL_SCALE, colour, 1, cv2.LINE_AA)
        x += w + 12
    return img


def labels_panel(labels: np.ndarray) -> np.ndarray:
    """Scene classes (``raspv_perception.scene_labels``) → BGR image in their display colours."""
    from raspv_perception.scene_labels import COLORS

    lut = np.zeros((256, 3), np.uint8)
    for cls, rgb in COLORS.items():
        lut[cls] = rgb[::-1]
    return lut[labels]


class PanelComposer:
    """Side-by-side frames: colour | other inputs | phosphenes, all at the phosphene height.
    The camera panels outline the part of the camera image the prosthesis field of view covers
    (the phosphene image's border seen through K_C·K_P⁻¹)."""

    def __init__(self, height: int, needs: frozenset[str], max_depth: float, title: str,
                 K_P: np.ndarray, phosphene_size: tuple[int, int]) -> None:
        self.height = height
        self.needs = needs
        self.max_depth = max_depth
        self.title = title
        w, h = phosphene_size
        border = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], dtype=float)
        self._border_rays = border @ np.linalg.inv(K_P).T
        self._outline: dict[CameraIntrinsics, np.ndarray] = {}

    def _fit(self, img: np.ndarray) -> tuple[np.ndarray, float]:
        h, w = img.shape[:2]
        scale = self.height / h
        return cv2.resize(img, (max(1, int(round(w * scale))), self.height), interpolation=cv2.INTER_AREA), scale

    def _draw_field(self, panel: np.ndarray, scale: float, camera: CameraIntrinsics | None) -> np.ndarray:
        if camera is None:
            return panel
        poly = self._outline.get(camera)
        if poly is None:
            u, v, _ = camera.project(self._border_rays)
            poly = self._outline[camera] = np.stack([u + 0.5, v + 0.5], axis=1)  # pixel centres → corners
        pts = np.round(poly * scale).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(panel, [pts], True, (0, 255, 255), max(1, self.height // 300), cv2.LINE_AA)
        return panel

    def compose(self, phosphenes: np.ndarray, inputs: FrameInputs | None) -> np.ndarray:
        panels = []
        cam = inputs.camera if inputs is not None else None
        if inputs is not None and inputs.color is not None:
            img, k = self._fit(cv2.cvtColor(inputs.color, cv2.COLOR_RGB2BGR))
            panels.append(_label(self._draw_field(img, k, cam), "colour (yellow: prosthesis field of view)"))
        if inputs is not None and inputs.depth is not None and "depth" in self.needs:
            img, k = self._fit(depth_panel(inputs.depth, self.max_depth))
            panels.append(_label(self._draw_field(img, k, cam), f"depth 0-{self.max_depth:g} m"))
        if inputs is not None and inputs.scene_labels is not None and "scene_labels" in self.needs:
            img, k = self._fit(labels_panel(inputs.scene_labels))
            panels.append(_legend(self._draw_field(img, k, cam), SCENE_LEGEND))
        panels.append(_label(_bgr(phosphenes).copy(), self.title))
        return np.hstack(panels)


def render_bag(bag: str | Path, video: str | Path | None = None, png_dir: str | Path | None = None,
               settings: RenderSettings | None = None,
               progress: Callable[[float, float], None] | None = None) -> RenderReport:
    """Render ``bag`` into ``video`` (mp4) and/or PNG frames in ``png_dir``. ``progress(done_s,
    total_s)`` is called with the bag time rendered. Raises :class:`RenderError` (or
    :class:`~raspv_bags.reader.BagError`) when the render cannot be done at all."""
    s = settings or RenderSettings()
    if video is None and png_dir is None:
        raise RenderError("give an output: a video file and/or a PNG folder")
    if video is not None:
        try:
            require_codec(s.codec)  # before any work: an unknown codec, or its extra missing (MissingExtra)
        except VideoError as exc:
            raise RenderError(str(exc)) from None
    params = s.spv_params()
    try:
        sim = PhospheneSimulator(config_from_node_params(params))  # as the spv node builds it
    except (KeyError, ValueError) as exc:
        raise RenderError(f"phosphene simulator: {exc.args[0] if exc.args else exc}") from None
    config = sim.config
    display_rate = config.frame_rate
    t_wall = time.monotonic()
    with BagReader(bag) as reader:
        if reader.start_ns is None:
            raise RenderError(f"{bag}: the bag has no messages")
        what = f"mode {config.mode!r}" + "".join(f" + overlay {o!r}" for o in config.overlays)
        source = BagFrameSource(reader, s, sim.needs, what)
        start_ns = reader.start_ns + int(s.start_s * 1e9)
        end_ns = reader.end_ns if s.duration_s is None else min(reader.end_ns, start_ns + int(s.duration_s * 1e9))
        if start_ns > reader.end_ns:
            raise RenderError(f"start {s.start_s:.2f} s is past the end of the bag ({reader.duration_s:.2f} s)")
        total_s = (end_ns - start_ns) * 1e-9
        max_depth = float(params["max_depth"])
        title = f"{config.device.name}, {config.mode}" + ("".join(f" + {o}" for o in config.overlays))
        composer = (PanelComposer(config.height, sim.needs, max_depth, title, sim.map.K, (config.width, config.height))
                    if s.side_by_side else None)
        period_ns = 1e9 / display_rate
        sink: VideoSink | None = None
        png = Path(png_dir) if png_dir is not None else None
        if png is not None:
            png.mkdir(parents=True, exist_ok=True)
        written = used = 0
        size = (config.width, config.height)
        current: RgbdFrame | None = None
        levels: np.ndarray | None = None

        def emit(tick_ns: int) -> None:
            nonlocal sink, written, size
            brightness = sim.brightness(levels, 1)
            image = sim.render(brightness)
            # mono8 phosphenes go to a single-channel writer/PNG as they are (no conversion)
            frame = composer.compose(image, current.inputs) if composer else (_bgr(image) if image.ndim == 3 else image)
            size = (frame.shape[1], frame.shape[0])
            if video is not None:
                if sink is None:
                    sink = VideoSink(Path(video), display_rate, size, color=frame.ndim == 3, codec=s.codec)
                sink.write(frame)
            if png is not None:
                cv2.imwrite(str(png / f"frame_{written:06d}.png"), frame)
            written += 1
            if progress is not None and written % 25 == 0:
                progress(min(total_s, (tick_ns - start_ns) * 1e-9), total_s)

        first_ns: int | None = None
        k = 0  # display tick k is at first_ns + k / display_rate (integer ns, no accumulated rounding)

        def tick(i: int) -> int:
            return first_ns + int(round(i * period_ns))

        try:
            for frame in source.frames(start_ns, end_ns + 1):
                if first_ns is None:
                    first_ns = frame.bag_ns
                while current is not None and tick(k) < frame.bag_ns:
                    emit(tick(k))
                    k += 1
                try:
                    new_levels = sim.levels(frame.inputs)
                except InputError as exc:
                    raise RenderError(f"{exc}") from None
                current, levels = frame, new_levels
                used += 1
            while current is not None and tick(k) <= end_ns:
                emit(tick(k))
                k += 1
        except VideoError as exc:
            raise RenderError(str(exc)) from None
        finally:
            if sink is not None:
                try:
                    sink.close()
                except VideoError as exc:
                    raise RenderError(str(exc)) from None
        if written == 0:
            raise RenderError("no RGB-D frame could be rendered: " + ("; ".join(source.notes + reader.notes) or
                                                                       "no colour/depth frames in the time range"))
        if progress is not None:
            progress(total_s, total_s)
        notes = list(dict.fromkeys(reader.notes + source.notes))
    return RenderReport(written, used, total_s, time.monotonic() - t_wall, Path(video) if video else None,
                        png, size, display_rate, notes)
