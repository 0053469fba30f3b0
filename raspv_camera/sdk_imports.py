"""Loading the vendor SDKs, each optional, with one line naming the fix when one is missing
(no ROS).

- RealSense: ``pyrealsense2`` (PyPI; it needs ``libusb-1.0``, which ``make install`` links in
  from the ``libusb-package`` wheel).
- OpenNI2: the ``openni`` bindings (PyPI) and Debian's ``libopenni2-0`` (the library, its
  device drivers — PS1080 for PrimeSense/Asus Xtion/Kinect, the ``.oni`` file player, the dummy
  device — and ``/etc/openni2/OpenNI.ini``). The bindings only look for an unversioned
  ``libOpenNI2.so``, which only the ``-dev`` package installs, so the versioned library is
  loaded directly from the system's library directory and the bindings initialised on it.
- DepthAI: ``depthai`` 3.x (PyPI). Importing it writes telemetry under ``~/.cache/depthai`` and
  logs a warning about USB access; both are turned off here unless the user set the variables.
"""
from __future__ import annotations

import glob
import os
import threading

from raspv_camera.rgbd_frame import SdkMissing
from raspv_common.extras import MissingExtra, install_command, require
from raspv_common.native_libs import ensure_libusb

OPENNI2_APT = "sudo apt-get install libopenni2-0"
OPENNI2_LIBRARY = "libOpenNI2.so.0"
OPENNI2_LIBRARY_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib/arm-linux-gnueabihf",
                        "/usr/lib", "/usr/local/lib")
_lock = threading.Lock()


def _import(module: str, pip_name: str):
    ensure_libusb()   # pyrealsense2 links libusb-1.0
    try:
        return require(module, f"the {pip_name} SDK", extra="cameras", dist=pip_name)
    except MissingExtra as exc:
        raise SdkMissing(str(exc)) from None
    except ImportError as exc:
        if "libusb" in str(exc):
            raise SdkMissing(f"{pip_name} cannot load libusb-1.0 ({exc}); run `make install` again, or "
                             f"sudo apt-get install libusb-1.0-0") from None
        raise SdkMissing(f"the {pip_name} SDK does not import ({exc}); reinstall it: {install_command('cameras')}") from None


def realsense():
    """The ``pyrealsense2`` module."""
    return _import("pyrealsense2", "pyrealsense2")


def openni2_library() -> str | None:
    """Path of the system's OpenNI2 library, or None."""
    for d in ([os.environ["OPENNI2_REDIST64"]] if os.environ.get("OPENNI2_REDIST64") else []) + list(OPENNI2_LIBRARY_DIRS):
        for name in (OPENNI2_LIBRARY, "libOpenNI2.so"):
            path = os.path.join(d, name)
            if os.path.isfile(path):
                return path
    found = sorted(glob.glob("/usr/lib/*/libOpenNI2.so*"))
    return found[0] if found else None


def openni2():
    """The initialised ``openni.openni2`` module."""
    module = _import("openni.openni2", "openni")
    with _lock:
        if module.is_initialized():
            return module
        lib = openni2_library()
        if lib is None:
            raise SdkMissing(f"the OpenNI2 library ({OPENNI2_LIBRARY}) is not installed: {OPENNI2_APT}")
        from openni import _openni2 as c_api

        try:
            c_api.load_dll(lib)
            module.loaded_dll_directory = os.path.dirname(lib)
            module.initialize()
        except Exception as exc:  # the bindings raise OSError, InitializationError or OpenNIError
            raise SdkMissing(f"OpenNI2 ({lib}) could not be initialised: {str(exc).splitlines()[0]}; "
                             f"reinstall it: sudo apt-get install --reinstall libopenni2-0") from None
    return module


def depthai():
    """The ``depthai`` module (3.x), imported quietly."""
    os.environ.setdefault("DEPTHAI_TELEMETRY", "0")
    os.environ.setdefault("DEPTHAI_LEVEL", "error")
    os.environ.setdefault("DEPTHAI_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "raspv", "depthai"))
    module = _import("depthai", "depthai")
    major = str(getattr(module, "__version__", "0")).split(".")[0]
    if major != "3":
        raise SdkMissing(f"depthai {module.__version__} is installed; the camera driver needs 3.x: "
                         f"pip install 'depthai>=3,<4'")
    return module


SDKS = {"realsense": realsense, "openni2": openni2, "depthai": depthai}
