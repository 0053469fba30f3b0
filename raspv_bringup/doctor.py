"""What this machine can do for RASPV (no rclpy import: ``raspv doctor`` answers in well under 3 s).

Each check is a :class:`Check`: a status (``ok``, ``gap`` — works without it, some feature
does not —, ``fail`` — the graphs cannot run), one line of detail, and the command that fixes a
gap. Nothing is imported that is slow to import (torch, depthai, open3d, rclpy): packages are
found with ``importlib.util.find_spec`` and libraries by their files.
"""
from __future__ import annotations

import importlib.util
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

from raspv_bringup.graph import CONFIG_DIR
from raspv_bringup.shm_cleanup import SHM_DIR, stale_segments
from raspv_common.extras import EXTRAS, OPTIONAL_MODULES, REPO_ROOT, in_checkout, install_command, installed_extras

# USB vendor ids of the cameras the `camera` node drives
CAMERA_USB_VENDORS = {"8086": "Intel RealSense", "1d27": "PrimeSense/Asus Xtion (OpenNI2)",
                      "03e7": "Luxonis OAK (DepthAI)"}
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "firefox", "firefox-esr")
MIN_FREE_GB = 5.0       # recordings, sessions and the sprite cache need room [GB]
MIN_SHM_MB = 256.0      # Fast DDS's shared-memory transport: a 16 MB segment per node [MB]


@dataclass(frozen=True)
class Check:
    name: str
    status: str          # ok | gap | fail
    detail: str
    fix: str = ""


def _found(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def check_python() -> Check:
    v = sys.version_info
    text = f"{v.major}.{v.minor}.{v.micro} ({sys.executable})"
    if (3, 10) <= (v.major, v.minor) <= (3, 12):
        return Check("Python", "ok", text)
    return Check("Python", "fail", f"{text}: ROS 2 Jazzy's wheels need 3.10-3.12",
                 "install Python 3.12 and run make install with it: PYTHON=python3.12 make install")


def check_environment() -> Check:
    in_venv = sys.prefix != getattr(sys, "base_prefix", sys.prefix)
    extras = installed_extras()
    how = "make install" if extras is not None else "pip install"
    if not in_venv:
        return Check("environment", "gap", f"not a virtual environment ({sys.prefix})",
                     "make install (creates .venv)" if in_checkout() else "python3 -m venv ENV && ENV/bin/pip install raspv")
    where = f"{sys.prefix} ({how}{', checkout ' + str(REPO_ROOT) if in_checkout() else ', installed package'})"
    unbuilt = [m for m in ("raspv_msgs", "tf2_msgs") if not _found(m)]
    if unbuilt:
        return Check("environment", "fail", f"{where}: the {' and '.join(unbuilt)} messages are not built",
                     "make install" if in_checkout() else "pip install raspv (the wheel carries the messages)")
    return Check("environment", "ok", where)


def check_ros() -> Check:
    if not _found("rclpy"):
        return Check("ROS 2", "fail", "rclpy is not importable", "make install" if in_checkout() else "pip install raspv")
    rmw = os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    lib = Path(sys.prefix) / "lib" / f"lib{rmw}.so"
    libs = list(Path(sys.prefix).glob(f"lib/**/lib{rmw}.so")) if not lib.exists() else [lib]
    if not libs:
        return Check("ROS 2", "fail", f"rclpy found, but the middleware {rmw} is not installed",
                     "pip install ros-jazzy-rmw-fastrtps-cpp (or make install)")
    profile = os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE") or str(CONFIG_DIR / "fastdds_shm.xml")
    scope = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return Check("ROS 2", "ok", f"rclpy (Jazzy wheels), {rmw}, discovery {scope}, "
                                f"ROS_DOMAIN_ID {os.environ.get('ROS_DOMAIN_ID', '0')}, profile {Path(profile).name}")


def check_shared_memory() -> Check:
    try:
        usage = shutil.disk_usage(SHM_DIR)
    except OSError:
        return Check("shared memory", "gap", f"{SHM_DIR} is missing: Fast DDS falls back to UDP (13 ms instead "
                                             "of 2.7 ms per 640x480 image)", "mount a tmpfs on /dev/shm")
    if not os.access(SHM_DIR, os.W_OK):
        return Check("shared memory", "gap", f"{SHM_DIR} is not writable: Fast DDS falls back to UDP",
                     f"sudo chmod 1777 {SHM_DIR}")
    stale = stale_segments()
    free_mb = usage.free / 1e6
    detail = f"{SHM_DIR} {free_mb:,.0f} MB free, {len(stale)} segment(s) left by killed processes"
    if stale:
        return Check("shared memory", "gap", detail, "raspv doctor --clean-shm")
    if free_mb < MIN_SHM_MB:
        return Check("shared memory", "gap", f"{detail}: below {MIN_SHM_MB:.0f} MB",
                     f"sudo mount -o remount,size=1G {SHM_DIR}")
    return Check("shared memory", "ok", detail)


def check_browser() -> Check:
    found = [b for b in BROWSERS if shutil.which(b)] or [p for p in ("/usr/bin/chromium",) if os.path.exists(p)]
    if found:
        return Check("browser", "ok", f"{found[0]} ({shutil.which(found[0]) or found[0]}): the headset client "
                                      "opens here; any browser on another machine works too")
    return Check("browser", "gap", "none found: open the client's address in a browser on another machine or "
                                   "headset; the browser tests and `raspv bench qoe` need chromium here",
                 "sudo apt-get install -y chromium")


def check_camera_sdks() -> Check:
    sdks = {"pyrealsense2": "RealSense", "openni": "OpenNI2", "depthai": "DepthAI"}
    have = [name for mod, name in sdks.items() if _found(mod)]
    missing = [name for mod, name in sdks.items() if not _found(mod)]
    openni_lib = any(Path(d).glob("libOpenNI2.so*") for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib"))
    notes = []
    if "OpenNI2" in have and not openni_lib:
        notes.append("OpenNI2's system library is missing (sudo apt-get install libopenni2-0)")
    detail = f"installed: {', '.join(have) or 'none'}" + (f"; missing: {', '.join(missing)}" if missing else "")
    if notes:
        detail += "; " + "; ".join(notes)
    if missing:
        return Check("camera SDKs", "gap", detail, install_command("cameras"))
    if notes:
        return Check("camera SDKs", "gap", detail, "sudo apt-get install libopenni2-0")
    return Check("camera SDKs", "ok", detail)


def connected_cameras(usb_root: Path = Path("/sys/bus/usb/devices")) -> list[str]:
    """Names of the RGB-D cameras on USB, by vendor id (no SDK needed)."""
    out = []
    for vendor_file in sorted(usb_root.glob("*/idVendor")):
        try:
            vendor = vendor_file.read_text().strip().lower()
        except OSError:
            continue
        if vendor in CAMERA_USB_VENDORS:
            product = vendor_file.with_name("product")
            name = product.read_text().strip() if product.exists() else CAMERA_USB_VENDORS[vendor]
            out.append(f"{name} ({vendor_file.parent.name})")
    return out


def check_cameras() -> Check:
    cams = connected_cameras()
    if cams:
        return Check("cameras", "ok", f"{len(cams)} connected: {', '.join(cams)} (`raspv camera list` for details)")
    return Check("cameras", "gap", "none connected: the virtual world, recordings and SDK recordings work without one",
                 "plug in a RealSense, Asus Xtion or OAK camera; then `raspv camera list`")


def check_extras() -> Check:
    have, missing = [], []
    for extra in EXTRAS:
        modules = [m for m, (e, _) in OPTIONAL_MODULES.items() if e == extra]
        (have if all(_found(m) for m in modules) else missing).append(extra)
    detail = f"installed: {', '.join(have) or 'none'}" + (f"; not installed: {', '.join(missing)}" if missing else "")
    if missing:
        return Check("extras", "gap", detail, "; ".join(f"{e}: {install_command(e)}" for e in missing if e != "dev")
                     or install_command("dev"))
    return Check("extras", "ok", detail)


def check_disk(path: Path | None = None) -> Check:
    path = path or Path.cwd()
    free_gb = shutil.disk_usage(path).free / 1e9
    detail = f"{free_gb:,.1f} GB free in {path}"
    if free_gb < MIN_FREE_GB:
        return Check("disk", "gap", f"{detail}: recordings and sessions need room (≥ {MIN_FREE_GB:.0f} GB)",
                     "free some space, or run from a folder on a larger disk")
    return Check("disk", "ok", detail)


def check_cpu() -> Check:
    cores = os.cpu_count() or 1
    load1, _, _ = os.getloadavg()
    detail = f"{cores} cores, load average {load1:.1f}"
    if cores < 2:
        return Check("CPU", "gap", f"{detail}: a graph runs a process per node; 2 cores or more",
                     "use a machine with 2 or more cores")
    if load1 > cores:
        return Check("CPU", "gap", f"{detail}: busy — the 50 Hz display and timings suffer while it lasts",
                     "stop other work (see `top`) before a session or a benchmark")
    return Check("CPU", "ok", detail)


CHECKS = (check_python, check_environment, check_ros, check_shared_memory, check_browser, check_camera_sdks,
          check_cameras, check_extras, check_disk, check_cpu)


def run_checks() -> list[Check]:
    return [check() for check in CHECKS]
