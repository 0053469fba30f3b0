"""``raspv slam align``: a saved map whose floor occupancy is a cut of a synthetic building is
placed where it was cut from, the transform is stored where the planner reads it, the overlay
picture is written; a missing building map, a map without occupancy and an ambiguous match are
one line each."""
import math

import numpy as np
import pytest

from raspv_bringup.cli import main
from raspv_common.occupancy import save_map as save_occupancy
from raspv_slam.building_map import load_alignment
from raspv_slam.config import SlamConfig
from raspv_slam.slam_system import SlamSystem

from .conftest import K, pose, render
from .test_building_alignment import floor_plan, office_plan, seen_part

PLACEMENT = (4.3, 2.1, 57.0)          # B ← M: x, y [m], yaw [deg]


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    """A real (small) saved SLAM map without a floor, and the building map beside it."""
    root = tmp_path_factory.mktemp("align")
    with SlamSystem(K, SlamConfig(background=False)) as slam:
        for i, yaw in enumerate(range(0, 12, 4)):
            slam.process(0.1 * i, *render(pose(0.3, -0.4, yaw)))
        slam.save(root / "room")
    building = office_plan()
    save_occupancy(building, root / "building.yaml")
    return root


def test_a_map_is_placed_on_the_building_and_the_transform_stored(maps, tmp_path, capsys):
    import shutil

    m = tmp_path / "room"
    shutil.copytree(maps / "room", m)
    slam_grid = seen_part(office_plan(), (0.0, 0.0, 12.0, 10.0), PLACEMENT, noise=0.02)
    save_occupancy(slam_grid, m / "occupancy.yaml")
    picture = tmp_path / "overlay.png"
    assert main(["slam", "align", str(m), "--building", str(maps / "building.yaml"), "-o", str(picture)]) == 0
    out = capsys.readouterr().out
    assert "building <- map: x" in out and "runner-up" in out
    stored = load_alignment(m)
    assert math.hypot(stored.x - PLACEMENT[0], stored.y - PLACEMENT[1]) < 0.05
    assert abs((stored.yaw_deg - PLACEMENT[2] + 180) % 360 - 180) < 1.0
    assert picture.stat().st_size > 10_000
    # a narrow guess round the truth (the map origin's placement, not the raster's) keeps it
    code = main(["slam", "align", str(m), "--building", str(maps / "building.yaml"), "--guess", "4.3", "2.1", "57",
                 "--radius", "0.5", "--yaw-range", "5"])
    assert code == 0 and math.hypot(load_alignment(m).x - 4.3, load_alignment(m).y - 2.1) < 0.05


def test_bad_input_is_one_line(maps, tmp_path, capsys):
    import shutil

    m = tmp_path / "room"
    shutil.copytree(maps / "room", m)
    building = str(maps / "building.yaml")
    assert main(["slam", "align", str(m), "--building", building]) == 2           # never anchored: no occupancy
    assert main(["slam", "align", str(tmp_path / "nowhere"), "--building", building]) == 2
    corridor = floor_plan([(0, 0, 16, 0), (0, 2, 16, 2)], size=(16.0, 2.0))     # a long corridor: any shift fits
    save_occupancy(corridor, tmp_path / "corridor.yaml")
    save_occupancy(seen_part(corridor, (5.0, 0.0, 9.0, 2.0), (0.0, 0.0, 0.0)), m / "occupancy.yaml")
    assert main(["slam", "align", str(m), "--building", str(tmp_path / "missing.yaml")]) == 2
    assert main(["slam", "align", str(m), "--building", str(tmp_path / "corridor.yaml")]) in (1, 2)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("raspv slam align: ") for line in err), err
    assert "occupancy" in err[0] and "no such SLAM map" in err[1] and "missing.yaml" in err[2]
    assert "ambiguous" in err[3] or "no placement" in err[3]
