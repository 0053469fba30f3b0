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
import os
from pathlib import Path

import yaml

from raspv_common.occupancy import MapFormatError, load_map as load_occupancy
from raspv_common.slam_map_files import ALIGNMENT_FILE, SlamMapError, StoredAlignment, building_map_sha256, \
    load_alignment, resolve_map_path  # noqa: F401 (load_alignment, StoredAlignment re-exported)
from raspv_slam.building_alignment import AlignmentConfig, AlignmentError, AlignmentGuess, BuildingAlignment, \
    align_to_building

OCCUPANCY_FILE = "occupancy.yaml"


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
