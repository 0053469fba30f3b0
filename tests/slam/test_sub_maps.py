"""Sub-maps (ORB-SLAM's atlas at this project's scale): lost in a place the map does not know
for ``new_map_after`` seconds, the system starts a new map in a frame of its own and tracks in
it; when the camera comes back to a mapped place, the loop closer recognises it, merges the two
sub-maps and the new keyframes land at their true poses in the old map's frame. Maps with an
unmerged sub-map and merged ones survive a save and load (checked against the truth)."""
import numpy as np
import pytest

from raspv_slam.config import SlamConfig
from raspv_slam.map_store import load_map
from raspv_slam.results import TrackingState
from raspv_slam.se3 import inverse
from raspv_slam.slam_system import SlamSystem

from .conftest import K, motion_error, pose, render

CONFIG = SlamConfig(background=False, vocabulary_first=8, lost_after=3, new_map_after=0.5)
DT = 0.1                      # s between frames
BLANK = (np.zeros((K.height, K.width, 3), np.uint8), np.full((K.height, K.width), np.nan, np.float32))
COVERED = 12                  # frames (1.2 s): lost after 3, then lost for 0.9 s ≥ new_map_after


def mapped():
    """The first map: turning in place at (0.3, -0.4) from yaw -20° to 94° (the +x and +y walls)."""
    return [pose(0.3, -0.4, yaw) for yaw in range(-20, 100, 6)]


def kidnapped(n: int = 34):
    """Uncovered 0.5 m away looking the other way (yaw 200°: the -x wall, never seen), then
    turning through the -y wall back to yaw 44° while walking back to the mapped spot."""
    out = []
    for i in range(n):
        s = i / (n - 1)
        out.append(pose(0.0 + 0.3 * s, -0.8 + 0.4 * s, 200.0 + 6.0 * i))
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The whole walk through the core; the map saved once before the merge and once after."""
    folder = tmp_path_factory.mktemp("maps")
    truth: dict[float, np.ndarray] = {}
    results = []
    t = 0.0
    with SlamSystem(K, CONFIG) as slam:
        for T in mapped():
            truth[round(t, 6)] = T
            results.append(slam.process(t, *render(T)))
            t += DT
        for _ in range(COVERED):
            results.append(slam.process(t, *BLANK))
            t += DT
        saved_unmerged = False
        for T in kidnapped():
            truth[round(t, 6)] = T
            results.append(slam.process(t, *render(T)))
            t += DT
            if not saved_unmerged and results[-1].state == TrackingState.TRACKING and results[-1].map_id == 1 \
                    and len(slam.map.segments().get(1, ())) >= 2:
                slam.save(folder / "unmerged")
                saved_unmerged = True
        slam.save(folder / "merged")
        world_from_slam = slam.map.world_from_slam.copy()
        poses = slam.map.poses()
        segments = dict(slam.map.segment)
        stamps = {k: kf.stamp for k, kf in slam.map.keyframes.items()}
        counts = dict(slam.counts)
    map_from_world = world_from_slam @ inverse(mapped()[0])       # S is the first camera
    return dict(results=results, truth=truth, map_from_world=map_from_world, poses=poses, segments=segments,
                stamps=stamps, counts=counts, folder=folder, saved_unmerged=saved_unmerged,
                world_from_slam=world_from_slam)


def test_lost_in_an_unmapped_place_starts_a_new_map_that_is_tracked(run):
    results = run["results"]
    n_mapped = len(mapped())
    assert all(r.map_id == 0 and r.state != TrackingState.LOST for r in results[:n_mapped])
    covered = results[n_mapped:n_mapped + COVERED]
    assert covered[-1].state == TrackingState.LOST and covered[-1].map_from_camera is None
    after = results[n_mapped + COVERED:]
    # the first uncovered frame: relocalisation fails (never seen), the timeout has passed
    assert after[0].state == TrackingState.NEW_MAP and after[0].map_id == 1, (after[0].state, after[0].map_id)
    # the new map's frame continues the last pose before LOST: map ← odom does not jump there
    assert motion_error(covered[-1].map_from_odom, after[0].map_from_odom)[0] < 1e-9
    # tracked in the new map, relative to its first frame as the truth says
    truth = kidnapped()
    before_merge = [i for i, r in enumerate(after) if r.map_id == 1]
    assert len(before_merge) >= 5
    for i in before_merge[1:]:
        r = after[i]
        assert r.state == TrackingState.TRACKING and r.map_from_camera is not None
        dt, dr = motion_error(inverse(truth[0]) @ truth[i], inverse(after[0].map_from_camera) @ r.map_from_camera)
        assert dt < 0.03 and dr < 1.0, (i, dt, dr)
    assert run["counts"]["new_maps"] == 1


def test_a_revisit_of_the_old_map_merges_the_new_map_into_its_frame(run):
    after = run["results"][len(mapped()) + COVERED:]
    merged = [i for i, r in enumerate(after) if r.state == TrackingState.MAP_MERGED]
    assert len(merged) == 1 and run["counts"]["merges"] == 1, [r.state.value for r in after]
    i = merged[0]
    assert all(r.map_id == 0 for r in after[i:]) and all(r.map_id == 1 for r in after[:i])
    # the correction jumped at the merge (the kidnap's 0.5 m and 100° were unknown before), odometry did not
    assert motion_error(after[i - 1].map_from_odom, after[i].map_from_odom)[0] > 0.2
    assert motion_error(after[i - 1].odom_from_camera, after[i].odom_from_camera)[0] < 0.1
    # every keyframe, the new map's included, is where the truth puts it in the old map's frame
    assert set(run["segments"].values()) == {0}
    M = run["map_from_world"]
    new = [k for k, s in run["stamps"].items() if s > len(mapped()) * DT]
    assert len(new) >= 3
    for k, stamp in run["stamps"].items():
        dt, dr = motion_error(M @ run["truth"][round(stamp, 6)], run["world_from_slam"] @ run["poses"][k])
        assert dt < 0.04 and dr < 1.0, (k, dt, dr)
    # and so is every frame after the merge
    for r, T in zip(after[i:], kidnapped()[i:]):
        dt, dr = motion_error(M @ T, r.map_from_camera)
        assert dt < 0.04 and dr < 1.0, (dt, dr)


def test_maps_with_sub_maps_load_as_the_truth_says(run):
    """Saved before the merge: the first map and the new one, each in its own frame; after: one."""
    assert run["saved_unmerged"]
    M = run["map_from_world"]
    unmerged = load_map(run["folder"] / "unmerged")
    groups = unmerged.segments()
    assert sorted(groups) == [0, 1] and len(groups[1]) >= 2
    W = unmerged.world_from_slam
    stamp = {k: kf.stamp for k, kf in unmerged.keyframes.items()}
    truth = {k: run["truth"][round(stamp[k], 6)] for k in unmerged.keyframes}
    for k in groups[0]:                                    # the first map: in the map frame
        dt, dr = motion_error(M @ truth[k], W @ unmerged.pose(k))
        assert dt < 0.03 and dr < 1.0, (k, dt, dr)
    first = min(groups[1])                                 # the new map: right relative to its first keyframe
    for k in groups[1]:
        dt, dr = motion_error(inverse(truth[first]) @ truth[k], unmerged.relative(first, k))
        assert dt < 0.03 and dr < 1.0, (k, dt, dr)
    # the new map's frame is not the old one's (placed at the last pose before LOST)
    assert motion_error(M @ truth[first], W @ unmerged.pose(first))[0] > 0.2
    merged = load_map(run["folder"] / "merged")
    assert set(merged.segments()) == {0} and len(merged) == len(run["poses"])
    for k, kf in merged.keyframes.items():
        dt, dr = motion_error(M @ run["truth"][round(kf.stamp, 6)], merged.world_from_slam @ merged.pose(k))
        assert dt < 0.04 and dr < 1.0, (k, dt, dr)


def test_localisation_in_a_map_with_a_sub_map_says_which_map_it_is_in(run):
    """The loaded map is not changed: a view of the new map's place is found in that sub-map
    (map_id 1), a view of the first map in the map frame at its true pose; no new map starts."""
    loc = SlamSystem.load(run["folder"] / "unmerged", K, SlamConfig(background=False, lost_after=3, new_map_after=0.1))
    n = len(loc.map)
    T = pose(0.3, -0.4, 33.0)
    r = loc.process(0.0, *render(T))
    assert r.state == TrackingState.RELOCALISED and r.map_id == 0
    dt, dr = motion_error(run["map_from_world"] @ T, r.map_from_camera)
    assert dt < 0.03 and dr < 1.0, (dt, dr)
    for i in range(6):
        loc.process(0.1 * (i + 1), *BLANK)
    r = loc.process(1.0, *render(kidnapped()[1]))
    assert r.state == TrackingState.RELOCALISED and r.map_id == 1, (r.state, r.map_id)
    r = loc.process(3.0, *render(pose(-2.0, 2.0, 135.0)))      # nowhere mapped: lost, never a new map
    loc.close()
    assert loc.counts["new_maps"] == 0 and len(loc.map) == n


def test_new_map_after_is_checked():
    with pytest.raises(ValueError, match="new_map_after"):
        SlamConfig(new_map_after=-1.0)


def test_a_continued_map_starts_new_maps_after_the_runners_new_map_after(tmp_path):
    """A saved map continued in mapping mode keeps its own settings (``lost_after`` 3 here, not
    the default 10) but ``new_map_after`` is the runner's (the slam node's parameter): with 0 the
    system waits for a mapped place, with the map's own 0.5 s it starts a new map."""
    with SlamSystem(K, CONFIG) as slam:
        for i, T in enumerate(mapped()):
            slam.process(i * DT, *render(T))
        slam.save(tmp_path / "room")

    def lost_in_an_unmapped_place(system: SlamSystem) -> list:
        t = 10.0
        found = system.process(t, *render(mapped()[5]))
        assert found.state == TrackingState.RELOCALISED, found.state
        results = []
        for _ in range(COVERED):
            t += DT
            results.append(system.process(t, *BLANK))
        for T in kidnapped()[:4]:
            t += DT
            results.append(system.process(t, *render(T)))
        system.close()
        return results

    waiting = SlamSystem.load(tmp_path / "room", K, localisation_only=False, run_settings={"new_map_after": 0.0})
    assert waiting.config.new_map_after == 0.0 and waiting.config.lost_after == CONFIG.lost_after
    assert not waiting.config.background              # the map's settings otherwise
    results = lost_in_an_unmapped_place(waiting)
    assert results[-1].state == TrackingState.LOST and waiting.counts["new_maps"] == 0, [r.state.value for r in results]
    assert set(waiting.map.segments()) == {0}
    own = SlamSystem.load(tmp_path / "room", K, localisation_only=False)       # the map's 0.5 s
    results = lost_in_an_unmapped_place(own)
    assert own.counts["new_maps"] == 1 and TrackingState.NEW_MAP in [r.state for r in results]
