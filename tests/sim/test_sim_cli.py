"""`raspv sim` tools (raspv_sim.sim_cli): check, map, render, on shipped and broken worlds."""
from __future__ import annotations

import matplotlib.pyplot as plt
import pytest
import yaml

from raspv_common.occupancy import FREE, OCCUPIED, load_map
from raspv_sim.sim_cli import main as sim_cli


def cell(grid, x, y):
    r, c = grid.world_to_cell([(x, y)])[0]
    return grid.cells[r, c]


def test_check_reports_each_world_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"floor": {"from": [0, 0], "to": [2, 2]}, "spawn": {"position": [1, 1]},
                                   "furniture": [{"type": "table", "name": "t", "position": [1, 1], "size": [1, 1]}]}))
    assert sim_cli(["check", "apartment", str(bad)]) == 2
    out = capsys.readouterr().out.strip().splitlines()
    assert out[0].startswith("ok: apartment") and "18 furniture" in out[0]
    assert out[1].startswith("error: ") and out[1].endswith("furniture[0] (table 't'): 'size' must be 3 positive numbers, got [1, 1]")


def test_map_of_the_stairs_world_marks_walls_steps_and_the_well(tmp_path, capsys):
    assert sim_cli(["map", "stairs", "-o", str(tmp_path), "--resolution", "0.1"]) == 0
    assert "stairs.yaml + stairs.pgm: 170x130 cells at 0.1 m" in capsys.readouterr().out
    grid = load_map(tmp_path / "stairs.yaml")                    # readable by the planner's loader
    assert grid.resolution == pytest.approx(0.1) and grid.origin == pytest.approx((-0.5, -0.5))
    assert cell(grid, 8.0, 0.8) == FREE                         # spawn
    assert cell(grid, 8.0, 0.0) == OCCUPIED                     # south wall (its door is closed)
    assert cell(grid, 5.8, 6.0) == OCCUPIED                     # ascending steps
    assert cell(grid, 10.2, 6.0) == OCCUPIED                    # descending well: no floor
    assert cell(grid, 8.0, 9.5) == OCCUPIED                     # bench
    assert cell(grid, -0.3, 5.0) == -1                          # outside the building: unknown


def test_structure_only_map_leaves_furniture_to_the_camera(tmp_path):
    assert sim_cli(["map", "apartment", "-o", str(tmp_path), "--structure-only"]) == 0
    grid = load_map(tmp_path / "apartment-structure.yaml")
    full_dir = tmp_path / "full"
    assert sim_cli(["map", "apartment", "-o", str(full_dir)]) == 0
    full = load_map(full_dir / "apartment.yaml")
    assert cell(full, 11.45, 4.0) == OCCUPIED and cell(grid, 11.45, 4.0) == FREE      # the sofa
    assert cell(grid, 6.0, 1.0) == OCCUPIED and cell(grid, 2.0, 3.0) == OCCUPIED      # a wall, a closed door
    assert cell(grid, 6.0, 3.8) == FREE                                              # the corridor's mouth
    assert (grid.cells == OCCUPIED).sum() < (full.cells == OCCUPIED).sum()


def test_render_writes_the_view_figure_and_an_overview(tmp_path, capsys):
    out = tmp_path / "view.png"
    assert sim_cli(["render", "office", "-o", str(out), "--size", "160x120", "--renderer", "tiny",
                    "--at", "3", "6", "0", "--head", "0", "10", "0", "--time", "1.5"]) == 0
    view, overview = plt.imread(out), plt.imread(tmp_path / "view-overview.png")
    assert view.shape[1] > view.shape[0] and view[..., :3].std() > 0.1
    assert overview.shape[:2] == (720, 960) and overview[..., :3].std() > 0.05
    assert sim_cli(["render", "office", "-o", str(out), "--size", "big"]) == 2
    assert "--size must be WxH" in capsys.readouterr().err


def test_unknown_world_is_one_line(capsys):
    assert sim_cli(["map", "atlantis"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("raspv sim: unknown world 'atlantis': shipped worlds are apartment, grocery, office, stairs, "
                   "or give the path of a YAML file")


def test_bad_arguments_are_one_line(tmp_path, capsys):
    assert sim_cli(["map", "apartment", "-o", str(tmp_path), "--resolution", "0"]) == 2
    assert capsys.readouterr().err.strip() == "raspv sim: map resolution must be positive, got 0.0"
    assert sim_cli(["map", "apartment", "-o", str(tmp_path), "--resolution", "0.0005"]) == 2
    assert "too large" in capsys.readouterr().err
    assert sim_cli(["render", "apartment", "-o", str(tmp_path / "no" / "such" / "dir.png"), "--size", "32x24"]) == 2
    assert "No such file or directory" in capsys.readouterr().err
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "meta.json").write_text("{not json")
    assert sim_cli(["plot", str(tmp_path / "run")]) == 2
    assert "is not a run's meta.json" in capsys.readouterr().err
    assert sim_cli(["plot", str(tmp_path)]) == 2
    assert "is not a run directory (no meta.json)" in capsys.readouterr().err
