"""`raspv camera list | info | import` with no camera connected."""
import subprocess
import sys

from raspv_bags.reader import BagReader
from raspv_common import topics

from .conftest import needs_openni2


def raspv(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "camera", *args], capture_output=True, text=True,
                          timeout=timeout)


def test_list_with_no_camera_is_a_clean_answer():
    out = raspv("list")
    assert out.returncode == 0 and out.stderr == "", out.stderr
    lines = out.stdout.splitlines()
    assert lines[:3] == ["realsense no device", "openni2   no device", "depthai   no device"] or \
        all(("no device" in l or "not available" in l) for l in lines[:3])
    assert lines[-1].startswith("0 cameras found in ")


def test_info_without_a_camera_is_one_line():
    out = raspv("info")
    assert out.returncode == 1 and out.stdout == ""
    assert out.stderr.strip() == "raspv camera: no camera connected (raspv camera list shows what each SDK sees)"
    out = raspv("info", "realsense", "--device", "123")
    assert out.returncode == 1 and out.stderr.strip() == "raspv camera: no RealSense device with serial number 123"


def test_info_on_recordings(realsense_recording, depthai_recording):
    out = raspv("info", "--file", str(realsense_recording.path))
    assert out.returncode == 0, out.stderr
    assert "Test D435I" in out.stdout and "depth scale 0.001" in out.stdout and "fx 140.0 fy 141.0" in out.stdout
    assert "IMU: yes" in out.stdout
    out = raspv("info", "--file", str(depthai_recording.path))
    assert out.returncode == 0 and "fx 150.0" in out.stdout, out.stderr
    out = raspv("info", "--file", "nothing.xyz")
    assert out.returncode == 1 and "cannot tell which SDK" in out.stderr


def test_import_an_sdk_recording_into_a_bag(openni2_recording, tmp_path):
    needs_openni2()
    path, recorded = openni2_recording
    out = raspv("import", str(path), "-o", str(tmp_path / "bag"))
    assert out.returncode == 0, out.stderr
    with BagReader(tmp_path / "bag") as bag:
        counts = {name: t.count for name, t in bag.topics.items()}
    assert counts[topics.COLOR] == counts[topics.DEPTH] == counts[topics.CAMERA_INFO] >= len(recorded) - 1
