"""Maps that outlive a run: a map built on a synthetic walk is saved, loaded in localisation
mode and finds frames it never saw as keyframes at their true poses (no initial pose, and again
after the camera was covered and carried elsewhere), without touching the files on disk; bad
maps are one line each, through the launcher's ``slam_map`` file kind too."""
import hashlib
import re

import numpy as np
import pytest

from raspv_bringup.file_kinds import check_file
from raspv_slam.config import SlamConfig
from raspv_slam.map_store import SlamMapError, load_map, resolve_map_path
from raspv_slam.results import TrackingState
from raspv_slam.se3 import inverse
from raspv_slam.slam_system import SlamSystem

from .conftest import K, motion_error, pose, render

CONFIG = SlamConfig(background=False, vocabulary_first=8)


def mapping_walk():
    """Turning in place at one spot, then walking and turning at another: two mapped places."""
    a = [pose(0.3, -0.4, yaw) for yaw in range(-20, 100, 6)]
    b = [pose(0.3 - 0.06 * i, -0.4 - 0.03 * i, 100.0 + 6 * i) for i in range(1, 16)]
    return a + b


@pytest.fixture(scope="module")
def saved_map(tmp_path_factory):
    path = tmp_path_factory.mktemp("maps") / "room"
    truth = mapping_walk()
    with SlamSystem(K, CONFIG) as slam:
        for i, T in enumerate(truth):
            assert slam.process(0.1 * i, *render(T)).state != TrackingState.LOST
        slam.save(path)
        world_from_slam = slam.map.world_from_slam.copy()
    # the map frame M of the saved map: M ← S with S the first camera, so M ← C = M ← S · C0⁻¹ · W ← C
    return path, world_from_slam @ inverse(truth[0]), len(slam.map)


def digest(path) -> str:
    h = hashlib.sha256()
    for f in sorted(path.iterdir()):
        h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()


def test_localisation_finds_unseen_frames_at_their_true_pose_and_leaves_the_map_untouched(saved_map):
    path, map_from_world, n_keyframes = saved_map
    before = digest(path)
    loc = SlamSystem.load(path, K, SlamConfig(background=False))
    assert loc.localisation_only and len(loc.map) == n_keyframes
    # a frame between mapped views, never a keyframe: found with no initial pose
    T = pose(0.33, -0.42, 33.0)
    first = loc.process(0.0, *render(T))
    assert first.state == TrackingState.RELOCALISED
    dt, dr = motion_error(map_from_world @ T, first.map_from_camera)
    assert dt < 0.03 and dr < 1.0, (dt, dr)
    nxt = loc.process(0.1, *render(pose(0.33, -0.42, 37.0)))
    assert nxt.state == TrackingState.TRACKING
    # covered camera (no depth, black image) until lost, then carried to the other mapped place
    blank = (np.zeros((K.height, K.width, 3), np.uint8), np.full((K.height, K.width), np.nan, np.float32))
    covered = [loc.process(0.2 + 0.1 * i, *blank) for i in range(CONFIG.lost_after + 2)]
    assert covered[-1].state == TrackingState.LOST and covered[-1].map_from_camera is None
    T2 = pose(0.3 - 0.06 * 8 + 0.02, -0.4 - 0.03 * 8, 100.0 + 6 * 8 + 3.0)
    back = loc.process(5.0, *render(T2))
    assert back.state == TrackingState.RELOCALISED
    dt, dr = motion_error(map_from_world @ T2, back.map_from_camera)
    assert dt < 0.03 and dr < 1.0, (dt, dr)
    # the odometry frame did not jump when the camera was found again; the correction did
    assert motion_error(covered[-1].odom_from_camera, back.odom_from_camera)[0] < 1e-9
    assert motion_error(covered[-1].map_from_odom, back.map_from_odom)[0] > 0.1
    loc.close()
    assert digest(path) == before and len(loc.map) == n_keyframes


def test_maps_are_found_by_name_in_the_maps_directory(saved_map, monkeypatch):
    path, _, n = saved_map
    monkeypatch.setenv("RASPV_MAPS_DIR", str(path.parent))
    assert resolve_map_path("room") == path
    assert len(load_map("room")) == n
    assert check_file("slam_map", "room") is None


def test_bad_maps_are_one_clear_line(saved_map, tmp_path, monkeypatch):
    import shutil

    monkeypatch.setenv("RASPV_MAPS_DIR", str(tmp_path))
    assert "no such map" in check_file("slam_map", "nowhere")
    (tmp_path / "empty").mkdir()
    assert "not a RASPV SLAM map" in check_file("slam_map", str(tmp_path / "empty"))
    bad = tmp_path / "bad"
    shutil.copytree(saved_map[0], bad)
    (bad / "keyframes.npz").write_bytes(b"not a zip file")
    line = check_file("slam_map", str(bad))
    assert "keyframes.npz is damaged" in line and "\n" not in line
    newer = tmp_path / "newer"
    shutil.copytree(saved_map[0], newer)
    text = re.sub(r"^version: \d+$", "version: 99", (newer / "map.yaml").read_text(), flags=re.M)
    (newer / "map.yaml").write_text(text)
    with pytest.raises(SlamMapError, match="version 99"):
        load_map(newer)


def test_a_map_saved_before_sub_maps_loads_as_one_map(saved_map, tmp_path):
    """Format version 1 (no ``segments`` array): every keyframe in the first map."""
    import shutil

    old = tmp_path / "v1"
    shutil.copytree(saved_map[0], old)
    with np.load(old / "keyframes.npz") as data:
        arrays = {k: data[k] for k in data.files if k != "segments"}
    np.savez(old / "keyframes.npz", **arrays)
    (old / "map.yaml").write_text(re.sub(r"^version: \d+$", "version: 1", (old / "map.yaml").read_text(), flags=re.M))
    m = load_map(old)
    assert len(m) == saved_map[2] and set(m.segments()) == {0}
