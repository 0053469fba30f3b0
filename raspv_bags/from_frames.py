"""Building a bag from RGB-D image files, so public datasets play through the graph (no ROS).

Layouts found by :func:`discover_frames`:

- **TUM RGB-D** sequence: ``rgb.txt`` and ``depth.txt`` (``timestamp filename`` lines) —
  colour and depth associated by nearest timestamp (≤ ``max_dt_s``, as TUM's associate.py);
  depth PNG uint16 with metres = value / 5000; ``groundtruth.txt`` (``t tx ty tz qx qy qz qw``,
  the colour camera's optical centre in the motion-capture frame) gives ``/camera/pose``.
- **Sub-folders** ``rgb/`` (or ``color/``, ``colour/``, ``image/``) and ``depth/``.
- **Flat folder** of pairs named ``<key>rgb…``/``<key>depth…`` (``frame_…_rgb.tiff`` +
  ``frame_…_depth.tiff``, ``tum_color.png`` + ``tum_depth.png``).
- **Explicit** lists of colour and depth files.

Timestamps come from the TUM lists, else from file names that are numbers (seconds) or
``YYYYMMDDTHHMMSS.ffffff`` stamps, else from a frame rate. Depth: uint16 with a scale
(TUM 1/5000; millimetres by default elsewhere), NYU v2 raw disparity, or float metres.

:func:`write_frames_bag` writes ``/camera/color/image_raw`` (rgb8),
``/camera/depth/image_raw`` (32FC1 metres, NaN = no reading), ``/camera/color/camera_info``
and optionally ``/camera/pose`` (world ← camera optical), serialised with the bag typestore.
Unreadable images and pairs whose sizes cannot be reconciled are skipped with a note; a depth
image with the colour's aspect ratio but another size is resampled (nearest) to the colour.
"""
from __future__ import annotations

import bisect
import datetime as dt
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np
import yaml

from raspv_bags.message_types import typestore
from raspv_bags.writer import BagWriter, QosSpec
from raspv_common import topics as T
from raspv_common.frames import MAP
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import RGBDFormatError, depth_from_scaled_uint16, read_color, read_nyu_disparity

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".ppm", ".pgm", ".bmp", ".exr", ".npy"}
COLOR_DIRS = ("rgb", "color", "colour", "image", "images")
COLOR_TOKENS = ("rgb", "color", "colour", "image")
DEPTH_FORMATS = ("auto", "tum", "mm", "nyu", "metres")
FRAME_ID = "camera_color_optical_frame"
SENSOR = QosSpec(reliable=True, transient_local=False, depth=2)

# Intrinsics presets (px): TUM RGB-D calibrations, PrimeSense/Kinect defaults (640×480).
CAMERA_PRESETS: dict[str, tuple[float, float, float, float]] = {
    "primesense": (525.0, 525.0, 319.5, 239.5),
    "tum-fr1": (517.3, 516.5, 318.6, 255.3),
    "tum-fr2": (520.9, 521.0, 325.1, 249.7),
    "tum-fr3": (535.4, 539.2, 320.1, 247.6),
    "xtion-60deg": (554.26, 554.26, 319.5, 239.5),
}
# TUM's published lens distortion of the freiburg colour cameras (plumb bob k1 k2 p1 p2 k3): their
# images are raw (fr3's were rectified), the depth registered to the distorted colour image.
CAMERA_DISTORTION: dict[str, tuple[float, ...]] = {
    "tum-fr1": (0.2624, -0.9531, -0.0054, 0.0026, 1.1633),
    "tum-fr2": (0.2312, -0.7849, -0.0033, -0.0001, 0.9172),
}
# Colour cameras with a rolling shutter, first-to-last-row readout [s]: the Kinect v1 of TUM's
# freiburg 1 and 2 sequences (estimated 20-30 ms from the roll residual of direct registrations
# against motion capture on fr1/rpy, which follows the yaw rate; the middle taken).
CAMERA_ROLLING_SHUTTER: dict[str, float] = {"tum-fr1": 0.025, "tum-fr2": 0.025}
# A bag's metadata.yaml custom_data key holding that readout [s, as text]: what a recording carries
# for the camera info ROS lacks (raspv_bags.camera_metadata)
ROLLING_SHUTTER_KEY = "raspv.rolling_shutter_readout"


class FramesError(ValueError):
    """The frames or their intrinsics cannot be used (the message says why and what to pass)."""


@dataclass(frozen=True)
class FramePair:
    stamp_s: float                    # capture time, seconds since the epoch
    color: Path
    depth: Path
    pose: np.ndarray | None = None    # 4×4 world ← camera optical, metres


@dataclass
class FrameSet:
    layout: str
    pairs: list[FramePair]
    depth_format: str                 # tum | mm | nyu | metres (resolved from auto)
    depth_scale: float | None         # metres per unit for uint16 depth
    notes: list[str] = field(default_factory=list)
    camera_hint: str | None = None    # a preset the layout suggests (TUM freiburg1/2/3)


# -- discovery ------------------------------------------------------------------------------

def _read_list(path: Path) -> list[tuple[float, str]]:
    """TUM ``timestamp value…`` list (``#`` comments) → [(t, rest of line)]."""
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split(None, 1)
        try:
            out.append((float(parts[0]), parts[1] if len(parts) > 1 else ""))
        except (ValueError, IndexError):
            raise FramesError(f"{path}:{n}: expected 'timestamp value', got {line!r}") from None
    return out


def associate(a: Sequence[float], b: Sequence[float], max_dt_s: float) -> list[tuple[int, int]]:
    """Pairs (i, j) of nearest timestamps, each used once, |a_i − b_j| ≤ ``max_dt_s``
    (greedy by increasing difference, as TUM's associate.py)."""
    b_sorted = sorted(range(len(b)), key=lambda j: b[j])
    bs = [b[j] for j in b_sorted]
    candidates = []
    for i, t in enumerate(a):
        k = bisect.bisect_left(bs, t)
        for kk in (k - 2, k - 1, k, k + 1):
            if 0 <= kk < len(bs) and abs(bs[kk] - t) <= max_dt_s:
                candidates.append((abs(bs[kk] - t), i, b_sorted[kk]))
    used_a, used_b, pairs = set(), set(), []
    for _, i, j in sorted(candidates):
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def read_groundtruth(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """TUM ``groundtruth.txt`` → (times (N,) s, poses (N, 7): tx ty tz qx qy qz qw), sorted by
    time; the pose is world ← camera optical (the colour camera's optical centre)."""
    times, poses = [], []
    for t, rest in _read_list(path):
        vals = rest.split()
        if len(vals) != 7:
            raise FramesError(f"{path}: expected 't tx ty tz qx qy qz qw' lines, got {len(vals) + 1} values")
        times.append(t)
        poses.append([float(v) for v in vals])
    if not times:
        raise FramesError(f"{path}: no poses")
    order = np.argsort(times)
    return np.asarray(times)[order], np.asarray(poses)[order]


_ISO = re.compile(r"(\d{8}T\d{6}(?:\.\d+)?)")


def stamp_from_name(name: str) -> float | None:
    """Seconds since the epoch from a file name: ``1305031102.175304.png`` or
    ``frame_20121214T142255.814212_rgb.tiff`` (local time); None if it holds no stamp."""
    stem = name.rsplit(".", 1)[0] if not name.endswith(".npy") else name[:-4]
    for s in (stem, stem.rsplit(".", 1)[0]):
        try:
            t = float(s)
            if t > 1e8:  # looks like epoch seconds
                return t
        except ValueError:
            pass
    m = _ISO.search(name)
    if m:
        text = m.group(1)
        fmt = "%Y%m%dT%H%M%S.%f" if "." in text else "%Y%m%dT%H%M%S"
        return dt.datetime.strptime(text, fmt).timestamp()
    return None


def _images(d: Path) -> list[Path]:
    return sorted(p for p in d.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def _pair_key(name: str, tokens: Sequence[str]) -> str | None:
    low = name.lower()
    stem = low.rsplit(".", 1)[0]
    for tok in tokens:
        i = stem.rfind(tok)
        if i >= 0:
            return stem[:i] + "*" + stem[i + len(tok):]
    return None


def _stamps(colors: Sequence[Path], fps: float, start_s: float, notes: list[str]) -> list[float]:
    stamps = [stamp_from_name(p.name) for p in colors]
    if all(s is not None for s in stamps) and len(set(stamps)) == len(stamps):
        return [float(s) for s in stamps]
    notes.append(f"no timestamps in the file names: {fps:g} frames per second assumed")
    return [start_s + i / fps for i in range(len(colors))]


def discover_frames(source: Path | None = None, colors: Sequence[Path] = (), depths: Sequence[Path] = (),
                    fps: float = 30.0, start_s: float | None = None, depth_format: str = "auto",
                    depth_scale: float | None = None, groundtruth: Path | None = None,
                    max_dt_s: float = 0.02) -> FrameSet:
    """Find colour/depth pairs in ``source`` (a folder) or in the explicit ``colors``/``depths``
    lists (see the module docstring). ``start_s``: first stamp when a frame rate is used
    (default: now)."""
    if depth_format not in DEPTH_FORMATS:
        raise FramesError(f"unknown depth format {depth_format!r}; use one of {', '.join(DEPTH_FORMATS)}")
    if not fps > 0:
        raise FramesError(f"frame rate must be > 0, got {fps}")
    start = dt.datetime.now().timestamp() if start_s is None else start_s
    notes: list[str] = []
    hint = None
    if colors or depths:
        colors, depths = [Path(p) for p in colors], [Path(p) for p in depths]
        if len(colors) != len(depths):
            raise FramesError(f"{len(colors)} colour files but {len(depths)} depth files; give them in pairs")
        for p in [*colors, *depths]:
            if not p.is_file():
                raise FramesError(f"{p}: no such file")
        layout = "files"
        stamps = _stamps(colors, fps, start, notes)
        pairs = [FramePair(t, c, d) for t, c, d in zip(stamps, colors, depths)]
    else:
        if source is None or not Path(source).is_dir():
            raise FramesError(f"{source}: not a folder (give a folder, or --color and --depth files)")
        source = Path(source)
        m = re.search(r"freiburg([123])", source.resolve().as_posix())
        hint = f"tum-fr{m.group(1)}" if m else None
        if (source / "rgb.txt").is_file() and (source / "depth.txt").is_file():
            layout = "tum"
            rgb = _read_list(source / "rgb.txt")
            dep = _read_list(source / "depth.txt")
            matches = associate([t for t, _ in rgb], [t for t, _ in dep], max_dt_s)
            if not matches:
                raise FramesError(f"{source}: no colour/depth timestamps within {max_dt_s * 1e3:.0f} ms of each other")
            if len(matches) < min(len(rgb), len(dep)):
                notes.append(f"{min(len(rgb), len(dep)) - len(matches)} frames without a partner within "
                             f"{max_dt_s * 1e3:.0f} ms left out")
            pairs = [FramePair(rgb[i][0], source / rgb[i][1].split()[0], source / dep[j][1].split()[0])
                     for i, j in matches]
            if groundtruth is None and (source / "groundtruth.txt").is_file():
                groundtruth = source / "groundtruth.txt"
        else:
            sub_c = next((source / d for d in COLOR_DIRS if (source / d).is_dir()), None)
            if sub_c is not None and (source / "depth").is_dir():
                layout = "folders"
                cs, ds = _images(sub_c), _images(source / "depth")
                if not cs or not ds:
                    raise FramesError(f"{source}: {sub_c.name}/ has {len(cs)} images and depth/ has {len(ds)}")
                by_stem = {p.stem: p for p in ds}
                if all(p.stem in by_stem for p in cs):
                    cs_ds = [(c, by_stem[c.stem]) for c in cs]
                else:
                    tc = [stamp_from_name(p.name) for p in cs]
                    td = [stamp_from_name(p.name) for p in ds]
                    if all(t is not None for t in tc + td):
                        cs_ds = [(cs[i], ds[j]) for i, j in associate(tc, td, max_dt_s)]
                    elif len(cs) == len(ds):
                        cs_ds = list(zip(cs, ds))
                        notes.append("colour and depth paired in file-name order")
                    else:
                        raise FramesError(f"{source}: cannot pair {len(cs)} colour with {len(ds)} depth images "
                                          f"(names differ and hold no timestamps)")
                stamps = _stamps([c for c, _ in cs_ds], fps, start, notes)
                pairs = [FramePair(t, c, d) for t, (c, d) in zip(stamps, cs_ds)]
            else:
                layout = "pairs"
                files = _images(source)
                dmap = {k: p for p in files if (k := _pair_key(p.name, ("depth",)))}
                cmap = {k: p for p in files if "depth" not in p.name.lower() and (k := _pair_key(p.name, COLOR_TOKENS))}
                keys = sorted(set(dmap) & set(cmap))
                if not keys:
                    raise FramesError(
                        f"{source}: no RGB-D frames found. Expected a TUM sequence (rgb.txt, depth.txt), "
                        f"sub-folders rgb/ and depth/, or files named like <name>_rgb.png + <name>_depth.png")
                cs_ds = [(cmap[k], dmap[k]) for k in keys]
                stamps = _stamps([c for c, _ in cs_ds], fps, start, notes)
                pairs = [FramePair(t, c, d) for t, (c, d) in zip(stamps, cs_ds)]
                order = np.argsort(stamps, kind="stable")
                pairs = [pairs[i] for i in order]
    if groundtruth is not None:
        pairs = _attach_poses(pairs, Path(groundtruth), max_dt_s, notes)
    if depth_format == "auto":
        depth_format = "tum" if layout == "tum" else "mm"
    if depth_scale is None:
        depth_scale = {"tum": 1.0 / 5000.0, "mm": 0.001}.get(depth_format)
    return FrameSet(layout, pairs, depth_format, depth_scale, notes, hint)


def _attach_poses(pairs: list[FramePair], path: Path, max_dt_s: float, notes: list[str]) -> list[FramePair]:
    """Pose per frame interpolated between the ground-truth samples around it (linear
    translation, slerp rotation); frames more than ``max_dt_s`` outside its span get none."""
    from scipy.spatial.transform import Rotation, Slerp

    if not path.is_file():
        raise FramesError(f"{path}: no such ground-truth file")
    times, poses = read_groundtruth(path)
    times, keep = np.unique(times, return_index=True)
    poses = poses[keep]
    stamps = np.array([p.stamp_s for p in pairs])
    inside = (stamps >= times[0] - max_dt_s) & (stamps <= times[-1] + max_dt_s)
    clipped = np.clip(stamps, times[0], times[-1])
    rot = Rotation.from_quat(poses[:, 3:])
    R = Slerp(times, rot)(clipped).as_matrix() if len(times) > 1 else np.repeat(rot.as_matrix()[None], len(stamps), 0)
    t = np.stack([np.interp(clipped, times, poses[:, i]) for i in range(3)], axis=1)
    out = []
    for k, p in enumerate(pairs):
        pose = None
        if inside[k]:
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = R[k], t[k]
        out.append(FramePair(p.stamp_s, p.color, p.depth, pose))
    missing = int((~inside).sum())
    if missing:
        notes.append(f"{missing} frames outside the ground truth's time span have no pose")
    return out


# -- intrinsics -----------------------------------------------------------------------------

def load_intrinsics_file(path: Path) -> dict[str, float]:
    """Intrinsics from YAML: ``fx, fy, cx, cy`` (optional ``width, height``), or a ROS
    camera-calibration file (``camera_matrix: {data: [9 values]}``, ``image_width/height``)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise FramesError(f"{path}: cannot read intrinsics ({exc})") from None
    if not isinstance(data, dict):
        raise FramesError(f"{path}: expected a mapping with fx, fy, cx, cy")
    if "camera_matrix" in data:
        try:
            K = np.asarray(data["camera_matrix"]["data"], dtype=float).reshape(3, 3)
        except (KeyError, TypeError, ValueError):
            raise FramesError(f"{path}: camera_matrix.data must hold 9 numbers") from None
        out = {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2]}
        if "image_width" in data and "image_height" in data:
            out.update(width=data["image_width"], height=data["image_height"])
        return out
    missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
    if missing:
        raise FramesError(f"{path}: missing {', '.join(missing)} (expected fx, fy, cx, cy [px])")
    try:
        return {k: float(v) for k, v in data.items() if k in ("fx", "fy", "cx", "cy", "width", "height")}
    except (TypeError, ValueError):
        raise FramesError(f"{path}: fx, fy, cx, cy must be numbers") from None


def intrinsics_for(values: dict[str, float], width: int, height: int) -> CameraIntrinsics:
    """Intrinsics for images of ``width`` × ``height``: rescaled if the values were given for
    another size (``width``/``height`` keys)."""
    try:
        cam = CameraIntrinsics(int(values.get("width", width)), int(values.get("height", height)),
                               float(values["fx"]), float(values["fy"]), float(values["cx"]), float(values["cy"]))
    except (KeyError, ValueError) as exc:
        raise FramesError(f"invalid intrinsics {values}: {exc}") from None
    return cam if (cam.width, cam.height) == (width, height) else cam.scaled(width, height)


# -- reading images -------------------------------------------------------------------------

def read_depth(path: Path, depth_format: str, depth_scale: float | None) -> np.ndarray:
    """Depth image file → float32 metres (H, W), NaN where there is no reading."""
    if depth_format == "nyu":
        return read_nyu_disparity(path)
    if path.suffix.lower() == ".npy":
        raw = np.load(path)
    else:
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise RGBDFormatError(f"{path}: not a readable depth image")
    if raw.ndim != 2:
        raise RGBDFormatError(f"{path}: depth must be single-channel, got shape {raw.shape}")
    if raw.dtype == np.uint16:
        if depth_format == "metres":
            raise RGBDFormatError(f"{path}: 16-bit integer depth cannot be 'metres'; give a scale (--depth-scale)")
        return depth_from_scaled_uint16(raw, depth_scale if depth_scale else 0.001)
    if raw.dtype in (np.float32, np.float64):
        d = raw.astype(np.float32)
        d[~np.isfinite(d) | (d <= 0)] = np.nan
        return d
    raise RGBDFormatError(f"{path}: unsupported depth pixel type {raw.dtype} (expected uint16 or float)")


# -- writing --------------------------------------------------------------------------------

@dataclass
class FromFramesReport:
    output: Path
    frames: int
    skipped: int
    size: tuple[int, int] | None
    intrinsics: CameraIntrinsics | None
    with_pose: int
    notes: list[str]


class _Serialiser:
    """rosbags message objects for the source topics."""

    def __init__(self) -> None:
        self.store = typestore()
        t = self.store.types
        self.Time, self.Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self.Image, self.CameraInfo = t["sensor_msgs/msg/Image"], t["sensor_msgs/msg/CameraInfo"]
        self.Roi = t["sensor_msgs/msg/RegionOfInterest"]
        self.PoseStamped, self.Pose = t["geometry_msgs/msg/PoseStamped"], t["geometry_msgs/msg/Pose"]
        self.Point, self.Quaternion = t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Quaternion"]

    def header(self, stamp_ns: int, frame_id: str):
        sec, nsec = divmod(stamp_ns, 1_000_000_000)
        return self.Header(stamp=self.Time(sec=sec, nanosec=nsec), frame_id=frame_id)

    def image(self, arr: np.ndarray, encoding: str, header) -> bytes:
        arr = np.ascontiguousarray(arr)
        h, w = arr.shape[:2]
        msg = self.Image(header=header, height=h, width=w, encoding=encoding, is_bigendian=0,
                         step=arr.strides[0], data=arr.reshape(-1).view(np.uint8))
        return bytes(self.store.serialize_cdr(msg, "sensor_msgs/msg/Image"))

    def camera_info(self, cam: CameraIntrinsics, header, distortion: tuple[float, ...] = ()) -> bytes:
        K = cam.K.reshape(-1)
        P = np.array([cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0], dtype=np.float64)
        d = np.zeros(max(5, len(distortion)))
        d[:len(distortion)] = distortion
        msg = self.CameraInfo(header=header, height=cam.height, width=cam.width,
                              distortion_model="rational_polynomial" if len(d) == 8 else "plumb_bob",
                              d=d, k=K.astype(np.float64), r=np.eye(3).reshape(-1), p=P,
                              binning_x=0, binning_y=0,
                              roi=self.Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))
        return bytes(self.store.serialize_cdr(msg, "sensor_msgs/msg/CameraInfo"))

    def pose(self, T_wc: np.ndarray, header) -> bytes:
        from scipy.spatial.transform import Rotation

        x, y, z, w = (float(v) for v in Rotation.from_matrix(T_wc[:3, :3]).as_quat())
        msg = self.PoseStamped(header=header, pose=self.Pose(
            position=self.Point(x=float(T_wc[0, 3]), y=float(T_wc[1, 3]), z=float(T_wc[2, 3])),
            orientation=self.Quaternion(x=x, y=y, z=z, w=w)))
        return bytes(self.store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))


class RgbdBagWriter:
    """A new bag with the source topics of the graph (colour rgb8, depth 32FC1, camera info and
    optionally the camera pose), written from arrays. Used by from-frames, tests and benchmarks."""

    def __init__(self, output: str | Path, storage: str = "mcap", with_pose: bool = False,
                 frame_id: str = FRAME_ID, distortion: tuple[float, ...] = (), rolling_shutter_readout: float = 0.0) -> None:
        self.ser = _Serialiser()
        self.frame_id = frame_id
        self.distortion = tuple(distortion)        # lens distortion of the raw colour images (OpenCV k1 k2 p1 p2 [k3])
        self.writer = BagWriter(output, storage, flush_interval_s=None)
        if rolling_shutter_readout > 0:            # [s] the colour camera's readout, in metadata.yaml's custom_data
            self.writer.set_custom_data(ROLLING_SHUTTER_KEY, repr(float(rolling_shutter_readout)))
        self.writer.add_topic(T.COLOR, "sensor_msgs/msg/Image", [SENSOR])
        self.writer.add_topic(T.DEPTH, "sensor_msgs/msg/Image", [SENSOR])
        self.writer.add_topic(T.CAMERA_INFO, "sensor_msgs/msg/CameraInfo", [SENSOR])
        if with_pose:
            self.writer.add_topic(T.CAMERA_POSE, "geometry_msgs/msg/PoseStamped", [SENSOR])
        self.frames = 0

    def add(self, stamp_s: float, color: np.ndarray | None, depth: np.ndarray | None, camera: CameraIntrinsics,
            pose: np.ndarray | None = None) -> None:
        """One frame: ``color`` RGB uint8 (H, W, 3), ``depth`` float32 metres (H, W), both stamped
        ``stamp_s`` (header and bag time); ``pose`` 4×4 world ← camera optical."""
        stamp_ns = int(round(stamp_s * 1e9))
        header = self.ser.header(stamp_ns, self.frame_id)
        if color is not None:
            self.writer.write(T.COLOR, stamp_ns, self.ser.image(color, "rgb8", header))
        if depth is not None:
            self.writer.write(T.DEPTH, stamp_ns, self.ser.image(np.asarray(depth, np.float32), "32FC1", header))
        self.writer.write(T.CAMERA_INFO, stamp_ns, self.ser.camera_info(camera, header, self.distortion))
        if pose is not None:
            self.writer.write(T.CAMERA_POSE, stamp_ns, self.ser.pose(pose, self.ser.header(stamp_ns, MAP)))
        self.frames += 1

    def close(self) -> None:
        self.writer.close()

    def __enter__(self) -> "RgbdBagWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_frames_bag(frames: FrameSet, intrinsics: dict[str, float] | None, output: Path,
                     storage: str = "mcap", progress: Callable[[int, int], None] | None = None,
                     frame_id: str = FRAME_ID, distortion: tuple[float, ...] = (),
                     rolling_shutter_readout: float = 0.0) -> FromFramesReport:
    """Write ``frames`` into the new bag ``output``. ``intrinsics``: fx, fy, cx, cy [px] (and
    optionally the width/height they were measured at); ``distortion``: the colour images' lens
    distortion (OpenCV k1 k2 p1 p2 [k3]) for the camera info, none by default;
    ``rolling_shutter_readout``: the colour camera's [s] (0: global shutter), kept in the bag's
    metadata (:func:`raspv_bags.camera_metadata.recorded_rolling_shutter`). Raises
    :class:`FramesError` when no intrinsics are given or no pair is usable."""
    if not frames.pairs:
        raise FramesError("no frames to write")
    if intrinsics is None:
        hint = f" (this looks like TUM {frames.camera_hint}: --camera {frames.camera_hint})" if frames.camera_hint else ""
        raise FramesError("no camera intrinsics: give --fx --fy --cx --cy, --intrinsics FILE.yaml or --camera "
                          f"{'|'.join(CAMERA_PRESETS)}{hint}")
    notes = list(frames.notes)
    skipped = with_pose = 0
    size: tuple[int, int] | None = None
    cam: CameraIntrinsics | None = None
    resized_note = False
    out = RgbdBagWriter(output, storage, with_pose=any(p.pose is not None for p in frames.pairs), frame_id=frame_id,
                        distortion=distortion, rolling_shutter_readout=rolling_shutter_readout)
    try:
        for n, pair in enumerate(frames.pairs):
            if progress is not None:
                progress(n, len(frames.pairs))
            try:
                color = read_color(pair.color)
                depth = read_depth(pair.depth, frames.depth_format, frames.depth_scale)
            except (RGBDFormatError, OSError, ValueError) as exc:
                notes.append(f"skipped frame {n}: {exc}")
                skipped += 1
                continue
            h, w = color.shape[:2]
            if depth.shape != (h, w):
                dh, dw = depth.shape
                if abs(dw / dh - w / h) > 0.01:
                    notes.append(f"skipped frame {n}: colour {w}x{h} and depth {dw}x{dh} differ in shape "
                                 f"({pair.color.name}, {pair.depth.name})")
                    skipped += 1
                    continue
                depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_NEAREST)
                if not resized_note:
                    notes.append(f"depth {dw}x{dh} resampled (nearest) to the colour's {w}x{h}")
                    resized_note = True
            if size is None:
                size = (w, h)
                cam = intrinsics_for(intrinsics, w, h)
            elif size != (w, h):
                notes.append(f"skipped frame {n}: {w}x{h}, the sequence is {size[0]}x{size[1]} ({pair.color.name})")
                skipped += 1
                continue
            out.add(pair.stamp_s, color, depth, cam, pair.pose)
            with_pose += pair.pose is not None
    finally:
        out.close()
    if progress is not None:
        progress(len(frames.pairs), len(frames.pairs))
    if not out.frames:
        raise FramesError("no usable frame: " + "; ".join(notes[-3:]))
    return FromFramesReport(Path(output), out.frames, skipped, size, cam, with_pose, notes)
