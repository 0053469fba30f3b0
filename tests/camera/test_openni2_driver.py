"""OpenNI2 without hardware: Debian's libOpenNI2 dummy device, recorded to .oni by the SDK's
recorder (plus the cropping record the dummy device does not write), played through the driver."""
import shutil

import numpy as np
import pytest

from raspv_camera.camera_driver import CameraSettings
from raspv_camera.rgbd_frame import CameraError, EndOfRecording, NoDevice
from raspv_camera.sdk_recordings import _oni_records, add_oni_cropping

from .conftest import needs_openni2


@pytest.fixture(autouse=True)
def _openni2():
    needs_openni2()


def driver(**settings):
    from raspv_camera.openni2_driver import OpenNI2Driver
    return OpenNI2Driver(CameraSettings(**settings))


def read_all(d, limit=200):
    out = []
    while len(out) < limit:
        try:
            f = d.read(2.0)
        except EndOfRecording:
            return out
        assert f is not None, "the recording stalled"
        out.append(f)
    raise AssertionError("the recording did not end")


def in_order(sent: list, got: list) -> int:
    """How many of ``sent`` appear, bit-exact, in ``got`` in the same order."""
    found, j = 0, 0
    for a in sent:
        k = next((k for k in range(j, len(got)) if np.array_equal(a, got[k])), None)
        if k is not None:
            found, j = found + 1, k + 1
    return found


def test_dummy_recording_plays_back_exactly(openni2_recording):
    path, recorded = openni2_recording
    with driver(file=str(path)) as d:
        frames = read_all(d)
    # The recorder takes every frame the dummy device makes; the frames the recording code read
    # meanwhile are a subset when it falls behind (a loaded machine), and either stream may
    # start one frame later in the file. Every frame read while recording comes back bit-exact,
    # in order (the first and the last may fall outside the recording).
    assert len(frames) >= len(recorded) - 1
    for kind in ("depth", "color"):
        got = [f.depth if kind == "depth" else f.color for f in frames]
        sent = [d if kind == "depth" else c for _, d, c in recorded]
        assert in_order(sent, got) >= len(sent) - 2, kind
    assert all(f.depth_units == 0.001 and f.intrinsics.width == 320 for f in frames)
    # the dummy device reports no field of view: the PrimeSense default focal length, scaled
    assert frames[0].intrinsics.fx == pytest.approx(525.0 * 320 / 640)
    stamps = np.array([f.sensor_time for f in frames])
    assert np.allclose(np.diff(stamps), 1 / 30, atol=2e-3)


def test_without_the_cropping_record_the_player_delivers_nothing(openni2_recording, tmp_path):
    path, _ = openni2_recording
    records = list(_oni_records(path.read_bytes()))
    assert sum(name == "xnCropping" for *_, name in records) == 2        # one per stream, same file length
    broken = tmp_path / "as_recorded.oni"
    data = bytearray(path.read_bytes())
    for off, kind, node, fields, name in records:                      # undo the fix
        if name == "xnCropping":
            data[off + 32:off + 32 + 16] = b"xnNotCropping".ljust(16, b"\0")
    broken.write_bytes(bytes(data))
    with driver(file=str(broken)) as d:
        assert d.read(1.0) is None
    assert add_oni_cropping(broken) == 0             # a renamed record does not count as missing …
    copy = tmp_path / "fixed.oni"
    shutil.copy(path, copy)
    assert add_oni_cropping(copy) == 0               # … and a fixed file is left alone


def test_live_dummy_device_through_the_sdk():
    with driver(device="Dummy", width=320, height=240, fps=30.0) as d:
        assert "Table Tennis" in d.device.name and not d.registered    # the dummy cannot register
        f = d.read(2.0)
        assert f is not None and f.color.shape == (240, 320, 3) and f.depth.dtype == np.uint16
    with pytest.raises(CameraError, match="320x240@30"):
        driver(device="Dummy", width=640, height=480).open()


def test_no_device_is_a_clean_error(tmp_path):
    from raspv_camera.openni2_driver import OpenNI2Driver
    assert OpenNI2Driver.list_devices() == []
    with pytest.raises(NoDevice, match="no OpenNI2 device connected"):
        driver().open()
    with pytest.raises(NoDevice, match="no OpenNI2 device XYZ"):
        driver(device="XYZ").open()
    with pytest.raises(NoDevice, match="no such recording"):
        driver(file=str(tmp_path / "gone.oni")).open()
    junk = tmp_path / "junk.oni"
    junk.write_bytes(b"\0" * 100)
    with pytest.raises(NoDevice, match="cannot open"):
        driver(file=str(junk)).open()
