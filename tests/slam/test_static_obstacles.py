"""Floor occupancy keeps what stayed put: a person who walked across the view of five keyframes
is seen at each place once and seen through there by the others, so their trail is left out,
while a wall and a pillar seen by every keyframe stay (depth rendered by ray casting boxes)."""
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.occupancy import OCCUPIED
from raspv_slam.floor_occupancy import occupancy_from_points, occupancy_from_views, points_of_views
from raspv_slam.static_obstacles import DepthView, visibility_evidence

K = CameraIntrinsics(160, 120, 120.0, 120.0, 79.5, 59.5)
CAMERA_Z = 1.5
# M ← C for a level camera looking along +x: optical x = −y, y = −z, z = +x
LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
# faces in the middle of 5-cm cells (x = 3.825, 2.225, 2.525)
WALL = ((3.825, -6.0, 0.0), (4.0, 6.0, 3.0))
PILLAR = ((2.225, 1.5, 0.0), (2.5, 1.8, 2.5))
CAMERAS_Y = (-1.0, -0.5, 0.0, 0.5, 1.0)
WALKER_Y = (-1.2, -0.6, 0.0, 0.6, 1.2)     # where the person stood when each keyframe was taken


def _walker(y: float):
    return (2.525, y - 0.2, 0.0), (2.9, y + 0.2, 1.7)


def _render(origin: np.ndarray, boxes) -> np.ndarray:
    """Depth (optical z) of a level camera at ``origin`` seeing ``boxes`` over the floor z = 0."""
    v, u = np.mgrid[0:K.height, 0:K.width]
    d = K.rays(u, v) @ LEVEL.T                  # ray per pixel in M, optical z = 1
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(d[:, 2] < 0, -origin[2] / d[:, 2], np.inf)
        for lo, hi in boxes:
            t1 = (np.array(lo) - origin) / d
            t2 = (np.array(hi) - origin) / d
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (near <= far) & (near > 0)
            depth = np.where(hit, np.minimum(depth, near), depth)
    depth[~np.isfinite(depth)] = np.nan
    return depth.reshape(K.height, K.width).astype(np.float32)


def _views() -> list[DepthView]:
    views = []
    for cy, wy in zip(CAMERAS_Y, WALKER_Y):
        T = np.eye(4)
        T[:3, :3] = LEVEL
        T[:3, 3] = (0.0, cy, CAMERA_Z)
        views.append(DepthView(T, _render(T[:3, 3], [WALL, PILLAR, _walker(wy)])))
    return views


def _occupied(grid, lo, hi) -> float:
    """Share of the cells of the box's footprint that are occupied."""
    xs = np.arange(lo[0], hi[0] + 1e-9, 0.05)
    ys = np.arange(lo[1] + 0.025, hi[1], 0.05)
    xy = np.array([(x, y) for x in xs for y in ys])
    rc = grid.world_to_cell(xy)
    inside = grid.inside(rc)
    return float(np.mean(grid.cells[rc[inside, 0], rc[inside, 1]] == OCCUPIED)) if inside.any() else 0.0


def test_a_person_walking_by_is_left_out_and_walls_stay():
    views = _views()
    points = points_of_views(views, K, 0.3, 6.0)
    everything = occupancy_from_points(points)               # no evidence: every obstacle point counts
    grid = occupancy_from_views(views, K, 0.3, 6.0)
    wall = (3.825, -1.0), (3.825, 1.0)                       # the wall's face the cameras see
    pillar = (2.225, 1.5), (2.225, 1.8)
    for face in (wall, pillar):                              # (cells between depth samples stay unknown)
        assert _occupied(grid, *face) == _occupied(everything, *face) > 0.5
    for y in WALKER_Y:
        where = (2.525, y - 0.2), (2.525, y + 0.2)
        assert _occupied(everything, *where) >= 0.5, y       # the trail a walker leaves without evidence
        assert _occupied(grid, *where) == 0.0, y


def test_hidden_places_get_no_vote():
    """A point behind a wall is neither seen nor seen through: it stays (no evidence against it)."""
    views = _views()
    behind = np.array([[5.0, 0.0, 1.0]])
    e = visibility_evidence(behind, views, K, 6.0)
    assert e.seen[0] == 0 and e.through[0] == 0 and e.static[0]
    in_front = np.array([[3.0, 0.0, 1.0]])                   # empty air every camera looks through
    e = visibility_evidence(in_front, views, K, 6.0)
    assert e.through[0] >= 4 and not e.static[0]
