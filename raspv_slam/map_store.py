"""Maps on disk: a folder per map, versioned, loaded by name or path (no ROS).

A map folder holds::

    map.yaml          format, version, camera, SLAM settings, M ← S, counts
    keyframes.npz     ids, stamps, poses S ← K, odometry parents, sub-maps, ORB keypoints,
                      descriptors, 3-D points, compressed colour/depth, place-database word histograms
    pose_graph.npz    edges a ← b with their kind (odometry, covisibility, loop)
    vocabulary.npy    the bag-of-binary-words vocabulary (when the map had one)
    occupancy.yaml    floor-projected occupancy, map_server YAML + PGM (when anchored to a floor)
    building_alignment.yaml   where the map sits on a building map (raspv slam align; kept on re-save)

A map holding sub-maps not merged yet (a new map started after tracking was lost in an
unmapped place) is saved with them: each keyframe's sub-map is stored (``segments``; version 2,
version-1 maps are one sub-map), its poses stay in that sub-map's own frame, a later mapping run
on the loaded map can still merge them, and the floor occupancy is the first sub-map's only.

Arrays are stored without pickling. A map is written into a temporary folder beside the target
and renamed over it, so a killed process leaves the old map or the new one, never half of one.
Names without a slash are looked up in the maps directory: ``$RASPV_MAPS_DIR``, else
``~/.local/share/raspv/maps``. Every problem loading a map is one line (:class:`SlamMapError`).
"""
from __future__ import annotations

import os
import shutil
import zipfile
from pathlib import Path

import numpy as np
import yaml

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.occupancy import save_map as save_occupancy
from raspv_common.slam_map_files import ALIGNMENT_FILE, MAPS_DIR_ENV, SlamMapError, maps_dir, resolve_map_path  # noqa: F401 (re-exported)
from raspv_slam.config import SlamConfig
from raspv_slam.features import Features
from raspv_slam.keyframe import Keyframe
from raspv_slam.place_recognition import PlaceDatabase, Vocabulary
from raspv_slam.pose_graph import EDGE_KINDS
from raspv_slam.slam_map import Edge, SlamMap

FORMAT = "raspv-slam-map"
VERSION = 2                        # 2: keyframes carry their sub-map (version 1 maps load as one)
KEPT_ON_SAVE = (ALIGNMENT_FILE,)   # files other tools add to a map folder, kept when it is saved again


def _offsets(parts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    sizes = np.array([len(p) for p in parts], dtype=np.int64)
    return np.concatenate([[0], np.cumsum(sizes)]), sizes


class _Parts:
    """An array to write as the concatenation of ``parts`` along their first axis (each
    (n, *trailing) of ``dtype``), without making the concatenation in memory."""

    def __init__(self, parts: list[np.ndarray], trailing: tuple[int, ...], dtype) -> None:
        self.parts, self.trailing, self.dtype = parts, tuple(trailing), np.dtype(dtype)


def _write_npz(path: Path, arrays: dict) -> None:
    """What ``np.savez`` writes (uncompressed ``.npy`` entries, no pickles, read by ``np.load``),
    with :class:`_Parts` entries written part by part: a map's keyframe images and features
    (hundreds of MB after a 10-minute walk) are never copied into one array."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, value in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                if isinstance(value, _Parts):
                    rows = sum(len(p) for p in value.parts)
                    np.lib.format.write_array_header_1_0(f, {"descr": np.lib.format.dtype_to_descr(value.dtype),
                                                             "fortran_order": False, "shape": (rows,) + value.trailing})
                    for p in value.parts:
                        f.write(np.ascontiguousarray(p, dtype=value.dtype).reshape((-1,) + value.trailing).tobytes())
                else:
                    np.lib.format.write_array(f, np.asanyarray(value), allow_pickle=False)


def save_map(slam_map: SlamMap, path: str | Path) -> Path:
    """Write ``slam_map`` into the folder ``path`` (a name goes into the maps directory)."""
    from raspv_slam.floor_occupancy import floor_occupancy

    target = resolve_map_path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.saving-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    with slam_map.lock:
        keyframes = [slam_map.keyframes[k] for k in sorted(slam_map.keyframes)]
        poses = slam_map.poses()
        edges = list(slam_map.edges)
        parents = dict(slam_map.parent)
        segments = dict(slam_map.segment)
        world_from_slam = slam_map.world_from_slam.copy()
        anchored = slam_map.anchored
    words, place_ids, hist = slam_map.places.state()
    feats = [kf.features for kf in keyframes]
    feature_offsets, _ = _offsets([f.keypoints for f in feats])
    color_offsets, _ = _offsets([kf.color_jpeg for kf in keyframes])
    depth_offsets, _ = _offsets([kf.depth_png for kf in keyframes])
    ids = np.array([kf.id for kf in keyframes], dtype=np.int64)
    row = {k: i for i, k in enumerate(place_ids)}
    words_per_kf = np.zeros((len(keyframes), hist.shape[1] if hist.ndim == 2 else 0), np.uint16)
    indexed = np.zeros(len(keyframes), bool)
    for i, kf in enumerate(keyframes):
        if kf.id in row and hist.ndim == 2 and hist.shape[0] > row[kf.id]:
            words_per_kf[i] = hist[row[kf.id]]
            indexed[i] = True
    _write_npz(tmp / "keyframes.npz", dict(
        ids=ids, stamps=np.array([kf.stamp for kf in keyframes], dtype=np.float64),
        poses=np.array([poses[kf.id] for kf in keyframes], dtype=np.float64).reshape(-1, 4, 4),
        parents=np.array([parents.get(kf.id, -1) for kf in keyframes], dtype=np.int64),
        segments=np.array([segments.get(kf.id, 0) for kf in keyframes], dtype=np.int64),
        feature_offsets=feature_offsets, keypoints=_Parts([f.keypoints for f in feats], (2,), np.float32),
        descriptors=_Parts([f.descriptors for f in feats], (32,), np.uint8),
        points=_Parts([f.points for f in feats], (3,), np.float32),
        octaves=_Parts([f.octaves for f in feats], (), np.int8),
        color_offsets=color_offsets, color=_Parts([kf.color_jpeg for kf in keyframes], (), np.uint8),
        depth_offsets=depth_offsets, depth=_Parts([kf.depth_png for kf in keyframes], (), np.uint8),
        words=words_per_kf, indexed=indexed))
    np.savez(tmp / "pose_graph.npz", a=np.array([e.a for e in edges], dtype=np.int64),
             b=np.array([e.b for e in edges], dtype=np.int64),
             a_from_b=np.array([e.a_from_b for e in edges], dtype=np.float64).reshape(-1, 4, 4),
             kind=np.array([EDGE_KINDS.index(e.kind) for e in edges], dtype=np.int8))
    if words is not None:
        np.save(tmp / "vocabulary.npy", words)
    if anchored:
        save_occupancy(floor_occupancy(slam_map), tmp / "occupancy.yaml")
    K = slam_map.intrinsics
    meta = {"format": FORMAT, "version": VERSION,
            "camera": {"width": K.width, "height": K.height, "fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy},
            "world_from_slam": [float(v) for v in world_from_slam.ravel()], "anchored": bool(anchored),
            "keyframes": len(keyframes), "edges": len(edges),
            "sub_maps": len({segments.get(kf.id, 0) for kf in keyframes}),
            "loop_edges": sum(e.kind == "loop" for e in edges), "vocabulary_words": 0 if words is None else len(words),
            "config": slam_map.config.as_dict()}
    (tmp / "map.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    for name in KEPT_ON_SAVE:
        if (target / name).is_file():
            shutil.copy2(target / name, tmp / name)
    old = target.with_name(f".{target.name}.old-{os.getpid()}")
    if target.exists():
        target.rename(old)
    tmp.rename(target)
    shutil.rmtree(old, ignore_errors=True)
    return target


def _read_meta(path: Path, shown: str) -> dict:
    if not path.exists():
        raise SlamMapError(f"{shown}: no such map (looked in {path})")
    if not path.is_dir():
        raise SlamMapError(f"{shown}: not a map folder (a map is a folder with map.yaml)")
    meta_path = path / "map.yaml"
    if not meta_path.is_file():
        raise SlamMapError(f"{shown}: not a RASPV SLAM map (no map.yaml in {path})")
    try:
        meta = yaml.safe_load(meta_path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise SlamMapError(f"{shown}: map.yaml is unreadable ({str(exc).splitlines()[0]})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise SlamMapError(f"{shown}: map.yaml is not a RASPV SLAM map description")
    version = meta.get("version")
    if not isinstance(version, int) or version > VERSION:
        raise SlamMapError(f"{shown}: map format version {version!r}; this RASPV reads version {VERSION} "
                           "(made by a newer RASPV?)")
    return meta


def _npz(path: Path, shown: str, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise SlamMapError(f"{shown}: {path.name} is missing")
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in keys if k not in data.files]
            if missing:
                raise SlamMapError(f"{shown}: {path.name} lacks {', '.join(missing)}")
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        if isinstance(exc, SlamMapError):
            raise
        raise SlamMapError(f"{shown}: {path.name} is damaged ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None


def load_map(name_or_path: str | Path, config: SlamConfig | None = None) -> SlamMap:
    """Read a map (a folder, or a name in :func:`maps_dir`). ``config``: settings to run with
    (default: those the map was built with)."""
    shown = str(name_or_path)
    path = resolve_map_path(name_or_path)
    meta = _read_meta(path, shown)
    try:
        cam = meta["camera"]
        intrinsics = CameraIntrinsics(int(cam["width"]), int(cam["height"]), float(cam["fx"]), float(cam["fy"]),
                                      float(cam["cx"]), float(cam["cy"]))
        world_from_slam = np.array(meta["world_from_slam"], dtype=np.float64).reshape(4, 4)
        saved_config = SlamConfig.from_dict(meta.get("config") or {})
    except (KeyError, TypeError, ValueError) as exc:
        raise SlamMapError(f"{shown}: map.yaml has a bad camera, frame or settings entry ({exc})") from None
    k = _npz(path / "keyframes.npz", shown, ("ids", "stamps", "poses", "parents", "feature_offsets", "keypoints",
                                             "descriptors", "points", "octaves", "color_offsets", "color",
                                             "depth_offsets", "depth", "words", "indexed"))
    g = _npz(path / "pose_graph.npz", shown, ("a", "b", "a_from_b", "kind"))
    n = len(k["ids"])
    if "segments" not in k:                                   # version 1: one map
        k["segments"] = np.zeros(n, np.int64)
    if n != meta.get("keyframes") or any(len(k[x]) != n for x in ("stamps", "poses", "parents", "segments", "words", "indexed")) \
            or any(len(k[x]) != n + 1 for x in ("feature_offsets", "color_offsets", "depth_offsets")):
        raise SlamMapError(f"{shown}: keyframes.npz does not hold the {meta.get('keyframes')} keyframes map.yaml lists")
    if k["feature_offsets"][-1] != len(k["keypoints"]) or k["color_offsets"][-1] != len(k["color"]) \
            or k["depth_offsets"][-1] != len(k["depth"]):
        raise SlamMapError(f"{shown}: keyframes.npz is inconsistent (offsets past the data)")
    vocabulary = None
    if (path / "vocabulary.npy").is_file():
        try:
            vocabulary = Vocabulary(np.load(path / "vocabulary.npy", allow_pickle=False))
        except (OSError, ValueError) as exc:
            raise SlamMapError(f"{shown}: vocabulary.npy is damaged ({str(exc).splitlines()[0]})") from None
    if vocabulary is not None and k["words"].shape[1] != len(vocabulary):
        raise SlamMapError(f"{shown}: the word histograms do not match the vocabulary")
    slam_map = SlamMap(intrinsics, config or saved_config)
    fo, co, do = k["feature_offsets"], k["color_offsets"], k["depth_offsets"]
    ids = [int(i) for i in k["ids"]]
    for i, kf_id in enumerate(ids):
        a, b = fo[i], fo[i + 1]
        features = Features(k["keypoints"][a:b], k["descriptors"][a:b], k["points"][a:b], k["octaves"][a:b])
        kf = Keyframe(kf_id, float(k["stamps"][i]), features, k["color"][co[i]:co[i + 1]], k["depth"][do[i]:do[i + 1]])
        slam_map.add_keyframe(kf, k["poses"][i], segment=int(k["segments"][i]))
        if k["parents"][i] >= 0:
            slam_map.parent[kf_id] = int(k["parents"][i])
    known = set(ids)
    for a, b, T, kind in zip(g["a"], g["b"], g["a_from_b"], g["kind"]):
        if int(a) not in known or int(b) not in known or not 0 <= int(kind) < len(EDGE_KINDS):
            raise SlamMapError(f"{shown}: pose_graph.npz names keyframes the map does not have")
        slam_map.edges.append(Edge(int(a), int(b), T, EDGE_KINDS[int(kind)]))
    indexed = np.flatnonzero(k["indexed"])
    slam_map.places = PlaceDatabase.restore(slam_map.config, vocabulary, [ids[i] for i in indexed],
                                            k["words"][indexed],
                                            {kf_id: slam_map.keyframes[kf_id].features.descriptors for kf_id in ids})
    if meta.get("anchored"):
        slam_map.anchor(world_from_slam)
    else:
        slam_map.world_from_slam = world_from_slam
    return slam_map


def check_map(value: str) -> None:
    """The ``slam_map`` file kind's check: the map loads (nothing is written)."""
    load_map(value)
