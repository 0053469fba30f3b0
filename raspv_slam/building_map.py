"""A saved SLAM map placed on a building map: the alignment stored with the map (no ROS).

``raspv slam align MAP --building B.yaml`` registers the map's floor occupancy
(``occupancy.yaml`` in the map folder, written when the map is anchored to the floor) to the
building's map_server map with :func:`raspv_slam.building_alignment.align_to_building` and
writes ``building_alignment.yaml`` into the map folder: the planar transform B ← M, its score,
and which building map it was made for (path and SHA-256 of the YAML and its image), so the
planner can tell when it is given another building. A map saved again keeps the file.
"""
from __future__ import annotations

import datetime as dt
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from raspv_common.occupancy import MapFormatError, load_map as load_occupancy
from raspv_common.text_files import read_yaml_file
from raspv_slam.building_alignment import AlignmentConfig, AlignmentError, AlignmentGuess, BuildingAlignment, \
    align_to_building
from raspv_slam.map_store import SlamMapError, resolve_map_path

ALIGNMENT_FILE = "building_alignment.yaml"
OCCUPANCY_FILE = "occupancy.yaml"


@dataclass(frozen=True)
class StoredAlignment:
    alignment: BuildingAlignment
    building_map: Path              # the map_server YAML it was made for
    building_sha256: str            # of that YAML and its image, when it was made


def building_map_sha256(yaml_path: str | Path) -> str:
    """SHA-256 of a map_server YAML and the image it names (together)."""
    path = Path(yaml_path)
    meta = read_yaml_file(path, "map file", MapFormatError, str(path))
    image = Path(str(meta.get("image", ""))) if isinstance(meta, dict) else Path()
    image = image if image.is_absolute() else path.parent / image
    digest = hashlib.sha256(path.read_bytes())
    if image.is_file():
        digest.update(image.read_bytes())
    return digest.hexdigest()


def map_occupancy(map_name_or_path: str | Path):
    """The floor occupancy a saved SLAM map holds (``SlamMapError`` when it has none)."""
    path = resolve_map_path(map_name_or_path)
    if not (path / "map.yaml").is_file():
        raise SlamMapError(f"{map_name_or_path}: no such SLAM map (looked in {path})")
    occupancy = path / OCCUPANCY_FILE
    if not occupancy.is_file():
        raise SlamMapError(f"{map_name_or_path}: the map has no floor occupancy (it was never anchored to a floor: "
                           "build it with a scene node or an IMU so its frame is gravity-aligned)")
    try:
        return load_occupancy(occupancy)
    except MapFormatError as exc:
        raise SlamMapError(f"{map_name_or_path}: {exc}") from None


def align_saved_map(map_name_or_path: str | Path, building_yaml: str | Path, guess: AlignmentGuess | None = None,
                    config: AlignmentConfig | None = None) -> BuildingAlignment:
    """Align a saved SLAM map to the building map and store the result in the map folder.
    Raises :class:`AlignmentError` (ambiguous, no match), :class:`SlamMapError` or
    ``MapFormatError`` with one line."""
    slam_grid = map_occupancy(map_name_or_path)
    building = load_occupancy(building_yaml)
    alignment = align_to_building(slam_grid, building, guess, config)
    store_alignment(map_name_or_path, alignment, building_yaml, guess)
    return alignment


def store_alignment(map_name_or_path: str | Path, alignment: BuildingAlignment, building_yaml: str | Path,
                    guess: AlignmentGuess | None = None) -> Path:
    path = resolve_map_path(map_name_or_path) / ALIGNMENT_FILE
    data = {"building_map": str(Path(building_yaml).resolve()),
            "building_map_sha256": building_map_sha256(building_yaml),
            "made": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            "building_from_map": alignment.as_dict(),
            "guess": None if guess is None else {"x": guess.x, "y": guess.y, "yaw_deg": guess.yaw_deg,
                                                 "radius": guess.radius, "yaw_range_deg": guess.yaw_range_deg}}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text("# B <- M: where this SLAM map sits on the building map (raspv slam align)\n"
                   + yaml.safe_dump(data, sort_keys=False))
    os.replace(tmp, path)
    return path


def load_alignment(map_name_or_path: str | Path) -> StoredAlignment:
    """The building alignment stored with a SLAM map (``SlamMapError`` when there is none)."""
    path = resolve_map_path(map_name_or_path)
    file = path / ALIGNMENT_FILE
    if not (path / "map.yaml").is_file():
        raise SlamMapError(f"{map_name_or_path}: no such SLAM map (looked in {path})")
    if not file.is_file():
        raise SlamMapError(f"{map_name_or_path}: the map is not aligned to a building map yet "
                           "(run: raspv slam align MAP --building BUILDING.yaml)")
    data = read_yaml_file(file, "building alignment", SlamMapError, str(file))
    if not isinstance(data, dict) or not isinstance(data.get("building_from_map"), dict):
        raise SlamMapError(f"{file}: expected building_from_map with x, y, yaw_deg")
    try:
        alignment = BuildingAlignment.from_dict(data["building_from_map"])
    except AlignmentError as exc:
        raise SlamMapError(f"{file}: {exc}") from None
    return StoredAlignment(alignment, Path(str(data.get("building_map", ""))), str(data.get("building_map_sha256", "")))
