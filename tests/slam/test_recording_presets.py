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
