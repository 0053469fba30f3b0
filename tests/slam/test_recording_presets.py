"""Which camera preset a recording runs with: the lens distortion and the rolling-shutter readout
come from the same preset — given (--camera), or the one a TUM folder's name suggests — and a
folder with its own intrinsics.yaml (a `raspv sim walk`) gets neither, in `raspv slam` and in
`raspv bench slam`. Frames: three of tests/data/tum_fr1_rpy_subset (provenance in its README)."""
import shutil
from pathlib import Path

import pytest
import yaml

from raspv_bench.slam import _camera
from raspv_bags.from_frames import CAMERA_DISTORTION
from raspv_slam.recordings import ROLLING_SHUTTER_READOUT, open_recording

SUBSET = Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_subset"


def _tum_folder(folder: Path, frames: int = 3) -> Path:
    """A TUM-layout folder with the subset's first ``frames`` colour/depth pairs."""
    folder.mkdir(parents=True)
    for name in ("rgb", "depth"):
        lines = [ln for ln in (SUBSET / f"{name}.txt").read_text().splitlines() if not ln.startswith("#")][:frames]
        (folder / name).mkdir()
        for ln in lines:
            shutil.copy(SUBSET / ln.split()[1], folder / ln.split()[1])
        (folder / f"{name}.txt").write_text("\n".join(lines) + "\n")
    return folder


def test_a_freiburg1_folder_gets_its_distortion_and_its_readout_together(tmp_path):
    rec = open_recording(_tum_folder(tmp_path / "rgbd_dataset_freiburg1_desk"))
    assert rec.camera == "tum-fr1"
    assert rec.distortion == tuple(CAMERA_DISTORTION["tum-fr1"])
    assert rec.rolling_shutter == pytest.approx(ROLLING_SHUTTER_READOUT["tum-fr1"])


def test_a_folder_with_its_own_intrinsics_gets_no_kinect_preset(tmp_path):
    folder = _tum_folder(tmp_path / "walk")
    (folder / "intrinsics.yaml").write_text(yaml.safe_dump({"fx": 500.0, "fy": 500.0, "cx": 320.0, "cy": 240.0}))
    rec = open_recording(folder)
    assert rec.camera is None and rec.distortion == () and rec.rolling_shutter == 0.0
    assert rec.intrinsics.fx == pytest.approx(500.0)
    assert _camera(folder, None) is None                       # bench slam: the walk's own camera
    assert _camera(folder, "tum-fr2") == "tum-fr2"             # unless one is given


def test_bench_slam_reads_an_unnamed_tum_folder_as_tum_fr1(tmp_path):
    folder = _tum_folder(tmp_path / "tum_fr1_rpy")
    assert _camera(folder, None) == "tum-fr1"
    rec = open_recording(folder, camera=_camera(folder, None))
    assert rec.rolling_shutter == pytest.approx(ROLLING_SHUTTER_READOUT["tum-fr1"])


def test_a_bag_from_a_kinect_preset_carries_its_readout_to_the_replays_slam_node(tmp_path):
    """ROS camera info has no rolling-shutter field: `raspv bag from-frames --camera tum-fr1` keeps
    the preset's readout in the bag's metadata, `raspv slam` reads it from the bag, and the
    launcher gives it to config/replay.yaml's slam node unless the graph sets one; a bag of a
    rectified global-shutter preset (tum-fr3) carries none."""
    from raspv_bags.camera_metadata import recorded_rolling_shutter
    from raspv_bringup.cli import main as raspv
    from raspv_bringup.graph import load_graph

    folder = _tum_folder(tmp_path / "rgbd_dataset_freiburg1_desk")
    kinect, other = tmp_path / "fr1_bag", tmp_path / "fr3_bag"
    assert raspv(["bag", "from-frames", str(folder), "-o", str(kinect), "--camera", "tum-fr1"]) == 0
    assert raspv(["bag", "from-frames", str(folder), "-o", str(other), "--camera", "tum-fr3"]) == 0
    assert recorded_rolling_shutter(kinect) == pytest.approx(ROLLING_SHUTTER_READOUT["tum-fr1"])
    assert recorded_rolling_shutter(other) is None
    assert open_recording(kinect).rolling_shutter == pytest.approx(ROLLING_SHUTTER_READOUT["tum-fr1"])
    assert open_recording(other).rolling_shutter == 0.0

    def slam_readout(bag, *overrides):
        graph = load_graph("config/replay.yaml", [f"replay.bag:={bag}", *overrides], check_files=False)
        return next(n for n in graph.nodes if n.kind == "slam").params.get("rolling_shutter_readout", 0.0)

    assert slam_readout(kinect) == pytest.approx(ROLLING_SHUTTER_READOUT["tum-fr1"])
    assert slam_readout(kinect, "slam.rolling_shutter_readout:=0.0") == 0.0      # the graph's own wins
    assert slam_readout(other) == 0.0
    assert raspv(["bag", "from-frames", str(folder), "-o", str(tmp_path / "given"), "--camera", "tum-fr3",
                  "--rolling-shutter", "0.03"]) == 0
    assert slam_readout(tmp_path / "given") == pytest.approx(0.03)
    assert raspv(["bag", "from-frames", str(folder), "-o", str(tmp_path / "bad"), "--camera", "tum-fr1",
                  "--rolling-shutter", "0.5"]) == 1
