"""Where SLAM maps live on disk and the building alignment stored with one (no ROS, no SLAM).

Shared by the ``slam`` package (which writes maps and alignments) and the planner (which only
reads where a saved map sits on a building map), so the navigation package does not depend on
the SLAM package. Names without a slash are looked up in the maps directory:
``$RASPV_MAPS_DIR``, else ``~/.local/share/raspv/maps``.
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from raspv_common.occupancy import MapFormatError
from raspv_common.text_files import read_yaml_file

MAPS_DIR_ENV = "RASPV_MAPS_DIR"
ALIGNMENT_FILE = "building_alignment.yaml"


class SlamMapError(ValueError):
    """A map that cannot be found, read or used (one line naming the map and the reason)."""


def maps_dir() -> Path:
    return Path(os.environ.get(MAPS_DIR_ENV) or Path.home() / ".local" / "share" / "raspv" / "maps").expanduser()


def resolve_map_path(name_or_path: str | Path) -> Path:
    """A path as given (it has a slash, or exists), else ``maps_dir() / name``."""
    text = str(name_or_path)
    p = Path(text).expanduser()
    if "/" in text or p.exists():
        return p
    return maps_dir() / text


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


@dataclass(frozen=True)
class StoredAlignment:
    """B ← M as stored by ``raspv slam align``: the SLAM map's frame on the building map."""

    x: float                        # m, building-map frame
    y: float                        # m
    yaw_deg: float
    score: float
    matched: float                  # share of the SLAM map's walls on the building's walls
    runner_up_score: float
    building_map: Path              # the map_server YAML it was made for
    building_sha256: str            # of that YAML and its image, when it was made

    def as_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "yaw_deg": self.yaw_deg, "score": self.score, "matched": self.matched,
                "runner_up_score": self.runner_up_score}


def load_alignment(map_name_or_path: str | Path) -> StoredAlignment:
    """The building alignment stored with a SLAM map (:class:`SlamMapError` when there is none)."""
    path = resolve_map_path(map_name_or_path)
    file = path / ALIGNMENT_FILE
    if not (path / "map.yaml").is_file():
        raise SlamMapError(f"{map_name_or_path}: no such SLAM map (looked in {path})")
    if not file.is_file():
        raise SlamMapError(f"{map_name_or_path}: the map is not aligned to a building map yet "
                           "(run: raspv slam align MAP --building BUILDING.yaml)")
    data = read_yaml_file(file, "building alignment", SlamMapError, str(file))
    b = data.get("building_from_map") if isinstance(data, dict) else None
    if not isinstance(b, dict):
        raise SlamMapError(f"{file}: expected building_from_map with x, y, yaw_deg")
    try:
        numbers = [float(b[k]) for k in ("x", "y", "yaw_deg")] + \
                  [float(b.get(k, 0.0)) for k in ("score", "matched", "runner_up_score")]
    except (KeyError, TypeError, ValueError) as exc:
        raise SlamMapError(f"{file}: building alignment needs numbers x, y, yaw_deg ({exc})") from None
    return StoredAlignment(*numbers, Path(str(data.get("building_map", ""))), str(data.get("building_map_sha256", "")))


def check_aligned_map(value: str) -> None:
    """The ``aligned_slam_map`` file kind's check: the map has a readable building alignment."""
    load_alignment(value)
