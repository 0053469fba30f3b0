"""A missing SDK or system library is one line naming the fix."""
import subprocess
import sys

import pytest

from raspv_camera import sdk_imports
from raspv_camera.rgbd_frame import SdkMissing
from raspv_common.extras import install_command


def test_missing_pip_sdk_names_the_extra_and_the_package():
    with pytest.raises(SdkMissing) as err:
        sdk_imports._import("raspv_no_such_sdk", "pyrealsense2")
    message = str(err.value)
    assert "\n" not in message and message.startswith("the pyrealsense2 SDK needs pyrealsense2 (the 'cameras' extra): ")
    assert message.endswith(install_command("cameras"))


def test_missing_openni2_library_names_the_apt_package():
    code = ("import raspv_camera.sdk_imports as s\n"
            "s.openni2_library = lambda: None\n"
            "try:\n    s.openni2()\nexcept s.SdkMissing as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == ("the OpenNI2 library (libOpenNI2.so.0) is not installed: "
                                  "sudo apt-get install libopenni2-0"), out.stderr
