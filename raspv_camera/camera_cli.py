"""`raspv camera`: real RGB-D cameras and their SDKs' recordings (no ROS needed).

    raspv camera list                        connected devices of every installed SDK
    raspv camera info [SDK] [--device ID]    a device's modes and intrinsics
    raspv camera info --file REC             a recording's streams and intrinsics
    raspv camera import REC -o BAG           an SDK recording → a RASPV bag (colour, depth, camera info)
"""
from __future__ import annotations

import argparse
import sys
import time


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="camera_command", metavar="TOOL", required=True)
    p = sub.add_parser("list", help="list connected cameras of every installed SDK (RealSense, OpenNI2, DepthAI)")
    p.add_argument("--sdk", action="append", choices=("realsense", "openni2", "depthai"),
                   help="only this SDK (repeatable)")
    p = sub.add_parser("info", help="modes and intrinsics of a device, or of a recording (--file)")
    p.add_argument("sdk", nargs="?", choices=("realsense", "openni2", "depthai"),
                   help="SDK of the device (default: the first with a device, or from the file)")
    p.add_argument("--device", default="", help="serial number, URI or device id (default: the first)")
    p.add_argument("--file", default="", help="a recording instead of a device")
    p = sub.add_parser("import", help="convert an SDK recording into a RASPV bag (as `raspv bag from-frames`)")
    p.add_argument("file", metavar="REC", help="RealSense .db3/.bag, OpenNI2 .oni, DepthAI directory of .mcap")
    p.add_argument("-o", "--output", required=True, metavar="BAG", help="bag directory to create")
    p.add_argument("--sdk", choices=("realsense", "openni2", "depthai"), help="default: from the file")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    p.add_argument("--max-frames", type=int, default=0, help="stop after this many frames (0: all)")


def run(args: argparse.Namespace) -> int:
    from raspv_camera.rgbd_frame import CameraError

    try:
        return {"list": _list, "info": _info, "import": _import}[args.camera_command](args)
    except CameraError as exc:
        print(f"raspv camera: {exc}", file=sys.stderr)
        return 1


def _list(args) -> int:
    from raspv_camera.drivers import list_all_devices

    t0 = time.monotonic()
    results = list_all_devices(args.sdk)
    found = 0
    for r in results:
        if r.error:
            print(f"{r.sdk:9s} (not available: {r.error})")
        elif not r.devices:
            print(f"{r.sdk:9s} no device")
        for d in r.devices:
            print(d.line())
            found += 1
    print(f"{found} camera{'s' if found != 1 else ''} found in {time.monotonic() - t0:.1f} s"
          + ("" if found else "; recordings play with: raspv launch camera camera.file:=PATH"))
    return 0


def _pick_sdk(args) -> str:
    from raspv_camera.drivers import driver_for_file, list_all_devices
    from raspv_camera.rgbd_frame import CameraError, NoDevice

    if args.sdk:
        return args.sdk
    if args.file:
        sdk = driver_for_file(args.file)
        if sdk is None:
            raise CameraError(f"{args.file}: cannot tell which SDK recorded it; name it: raspv camera info SDK --file ...")
        return sdk
    for r in list_all_devices():
        if r.devices:
            return r.sdk
    raise NoDevice("no camera connected (raspv camera list shows what each SDK sees)")


def _info(args) -> int:
    from raspv_camera.camera_driver import CameraSettings
    from raspv_camera.drivers import driver_class

    sdk = _pick_sdk(args)
    for line in driver_class(sdk).describe(CameraSettings(device=args.device, file=args.file)):
        print(line)
    return 0


def _import(args) -> int:
    from raspv_bags.from_frames import RgbdBagWriter
    from raspv_bags.writer import BagWriteError
    from raspv_camera.camera_driver import CameraSettings
    from raspv_camera.drivers import make_driver
    from raspv_camera.rgbd_frame import EndOfRecording

    sdk = args.sdk or _pick_sdk(argparse.Namespace(sdk=None, file=args.file))
    driver = make_driver(sdk, CameraSettings(file=args.file))
    driver.open()
    n = 0
    try:
        with RgbdBagWriter(args.output, args.storage) as out:
            while not args.max_frames or n < args.max_frames:
                try:
                    frame = driver.read(5.0)
                except EndOfRecording:
                    break
                if frame is None:
                    break
                out.add(frame.sensor_time, frame.color, frame.depth_metres(), frame.intrinsics)
                n += 1
    except BagWriteError as exc:
        print(f"raspv camera: {exc}", file=sys.stderr)
        return 1
    finally:
        driver.close()
    print(f"{args.output}: {n} frames from {args.file} ({sdk})")
    return 0 if n else 1
