"""Offline rendering of bags: the live simulator's output, frame counts, video and PNGs, bad input."""
from __future__ import annotations

import sys

import cv2
import numpy as np
import pytest

from raspv_bringup.cli import main as raspv
from raspv_bringup.testing import dev_requirement
from raspv_bags.from_frames import discover_frames, write_frames_bag
from raspv_bags.reader import BagError
from raspv_bags.render import RenderError, RenderSettings, render_bag
from raspv_bags.writer import BagWriter
from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.simulator import render_frame

from .conftest import make_rgbd_bag

SMALL = {"width": 200}  # a 200×200 phosphene image keeps the tests fast


def _video_frames(path):
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    return frames


def test_mp4_has_one_frame_per_display_tick_and_plays_back(rgbd_bag, tmp_path):
    report = render_bag(rgbd_bag, tmp_path / "out.mp4", settings=RenderSettings(spv=SMALL))
    # 12 frames at 10 Hz span 1.1 s; display ticks every 20 ms from the first frame: 56 ticks
    assert report.frames == 56 and report.camera_frames == 12
    frames = _video_frames(tmp_path / "out.mp4")
    assert len(frames) == 56 and frames[0].shape == (200, 200, 3)
    assert frames[-1].max() > 60  # phosphenes lit once the temporal model has risen


def test_frames_are_the_live_simulators_images(rgbd_bag, tmp_path):
    """Without the temporal model, tick 0 is exactly what the spv core makes of frame 0."""
    from raspv_bags.reader import BagReader
    from raspv_common import topics as T
    from raspv_common.conversions import rgb_from_image

    report = render_bag(rgbd_bag, None, tmp_path / "png", RenderSettings(spv={**SMALL, "temporal": False}))
    pngs = sorted((tmp_path / "png").glob("*.png"))
    assert len(pngs) == report.frames == 56
    with BagReader(rgbd_bag) as r:
        color = rgb_from_image(r.decode(next(r.messages([T.COLOR]))))
    cam = CameraIntrinsics.from_hfov(64, 48, 60.0)
    expected = render_frame(color, None, cam, temporal=False, width=200)
    np.testing.assert_array_equal(cv2.imread(str(pngs[0]), cv2.IMREAD_UNCHANGED), expected)


def test_side_by_side_shows_colour_and_depth_next_to_the_phosphenes(rgbd_bag, tmp_path):
    report = render_bag(rgbd_bag, tmp_path / "s.mp4", settings=RenderSettings(spv={**SMALL, "mode": "depth"},
                                                                              side_by_side=True, duration_s=0.2))
    # colour 64x48 and depth scaled to 200 px high (267 px wide each) + 200 px of phosphenes
    assert report.size == (267 + 267 + 200, 200)
    assert _video_frames(tmp_path / "s.mp4")[0].shape == (200, 734, 3)


def test_real_frames_render_through_from_frames(data_dir, tmp_path):
    frames = discover_frames(data_dir / "rgbd" / "kinect_table")
    write_frames_bag(frames, {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}, tmp_path / "bag")
    report = render_bag(tmp_path / "bag", tmp_path / "real.mp4", settings=RenderSettings(spv={**SMALL, "mode": "depth"}))
    assert report.frames == len(_video_frames(tmp_path / "real.mp4")) == 26  # 0.518 s at 50 Hz


def test_scene_modes_run_the_scene_nodes_core_offline(tmp_path):
    """Wall-Obstacles needs the scene classes: render runs scene perception on each depth frame."""
    from raspv_bags.from_frames import RgbdBagWriter
    from raspv_camera.synthetic_scene import SyntheticRoom
    from raspv_perception.scene_labels import COLORS, FLOOR, WALL

    cam = CameraIntrinsics.from_hfov(160, 120, 60.0)
    room = SyntheticRoom(cam)
    with RgbdBagWriter(tmp_path / "room") as out:
        for i in range(4):
            color, depth = room.render(room.pose_at(i * 0.1))
            out.add(100.0 + i * 0.1, color, depth, cam)
    report = render_bag(tmp_path / "room", None, tmp_path / "png",
                        RenderSettings(spv={**SMALL, "mode": "wall_obstacles", "temporal": False}, side_by_side=True))
    assert report.camera_frames == 4
    frame = cv2.imread(str(sorted((tmp_path / "png").glob("*.png"))[-1]))
    labels = frame[40:, 267:534]  # colour | scene classes | phosphenes, each 200 px high
    for cls in (FLOOR, WALL):
        assert (np.abs(labels.astype(int) - COLORS[cls][::-1]).sum(axis=2) < 10).mean() > 0.05
    assert frame[:, 534:].max() > 100  # walls and obstacles light phosphenes


def test_path_overlay_takes_the_recorded_navigation_path(tmp_path):
    from raspv_bags.from_frames import RgbdBagWriter
    from raspv_bags.message_types import typestore

    cam = CameraIntrinsics.from_hfov(64, 48, 60.0)
    ty = typestore().types
    with RgbdBagWriter(tmp_path / "nav", with_pose=True) as out:
        out.writer.add_topic("/nav/path", "nav_msgs/msg/Path")
        for i in range(3):
            pose = np.eye(4)
            pose[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]  # optical axis along world x, at 1.5 m height
            pose[2, 3] = 1.5
            header = out.ser.header(10**9 * (100 + i), "world")
            if i:  # no path yet for the first frame
                points = [ty["geometry_msgs/msg/PoseStamped"](header=header, pose=ty["geometry_msgs/msg/Pose"](
                    position=ty["geometry_msgs/msg/Point"](x=float(x), y=0.0, z=1.5),  # at eye height: centre row
                    orientation=ty["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
                    for x in np.linspace(0.5, 4.0, 8)]
                path = ty["nav_msgs/msg/Path"](header=header, poses=points)
                out.writer.write("/nav/path", 10**9 * (100 + i) - 1, typestore().serialize_cdr(path, "nav_msgs/msg/Path"))
            out.add(100.0 + i, np.full((48, 64, 3), 80, np.uint8), np.full((48, 64), 5.0, np.float32), cam, pose)
    report = render_bag(tmp_path / "nav", None, tmp_path / "png",
                        RenderSettings(spv={**SMALL, "mode": "depth", "overlays": ["path"], "temporal": False}))
    assert report.camera_frames == 2  # frames after the first path message
    plain = render_bag(tmp_path / "nav", None, tmp_path / "plain_png",
                       RenderSettings(spv={**SMALL, "mode": "depth", "temporal": False}))
    with_path = cv2.imread(str(tmp_path / "png" / "frame_000000.png"), cv2.IMREAD_UNCHANGED)
    without = cv2.imread(str(tmp_path / "plain_png" / f"frame_{plain.frames - report.frames:06d}.png"),
                         cv2.IMREAD_UNCHANGED)
    assert with_path[100].max() > without[100].max()  # the path's phosphenes at full level
    with pytest.raises(RenderError, match="overlay 'path' needs (camera pose|navigation path) messages"):
        render_bag(make_rgbd_bag(tmp_path / "plain", frames=2),
                   tmp_path / "x.mp4", settings=RenderSettings(spv={"overlays": ["path"]}))


def test_missing_camera_info_needs_intrinsics(tmp_path):
    from raspv_bags.from_frames import _Serialiser

    ser = _Serialiser()
    with BagWriter(tmp_path / "noinfo") as w:
        w.add_topic("/camera/color/image_raw", "sensor_msgs/msg/Image")
        for i in range(5):
            w.write("/camera/color/image_raw", 10**9 + i * 10**8,
                    ser.image(np.full((48, 64, 3), 100, np.uint8), "rgb8", ser.header(10**9 + i * 10**8, "c")))
    with pytest.raises(RenderError, match="no camera info.*intrinsics"):
        render_bag(tmp_path / "noinfo", tmp_path / "a.mp4", settings=RenderSettings(spv=SMALL))
    report = render_bag(tmp_path / "noinfo", tmp_path / "b.mp4",
                        settings=RenderSettings(spv=SMALL, intrinsics={"fx": 60, "fy": 60, "cx": 31.5, "cy": 23.5}))
    assert report.frames == 21
    with pytest.raises(RenderError, match="needs depth messages but the bag has no /camera/depth/image_raw"):
        render_bag(tmp_path / "noinfo", tmp_path / "c.mp4",
                   settings=RenderSettings(spv={"mode": "depth"}, intrinsics={"fx": 60, "fy": 60, "cx": 31.5, "cy": 23.5}))


def test_mismatched_depth_size_is_resampled_or_skipped(tmp_path):
    from raspv_bags.from_frames import RgbdBagWriter

    cam = CameraIntrinsics.from_hfov(64, 48, 60.0)
    with RgbdBagWriter(tmp_path / "mix") as out:
        out.add(1.0, np.full((48, 64, 3), 90, np.uint8), np.full((24, 32), 1.0, np.float32), cam)   # half size
        out.add(1.1, np.full((48, 64, 3), 90, np.uint8), np.full((48, 20), 1.0, np.float32), cam)   # other shape
        out.add(1.2, np.full((48, 64, 3), 90, np.uint8), np.full((48, 64), 1.0, np.float32), cam)
    report = render_bag(tmp_path / "mix", tmp_path / "m.mp4",
                        settings=RenderSettings(spv={**SMALL, "mode": "depth"}, side_by_side=True))
    assert report.camera_frames == 2
    assert any("resampled" in n for n in report.notes) and any("differ in shape" in n for n in report.notes)


def test_bad_requests_are_refused(rgbd_bag, tmp_path):
    with pytest.raises(RenderError, match="give an output"):
        render_bag(rgbd_bag)
    with pytest.raises(RenderError, match="mode: 'nonsense' is not allowed"):
        render_bag(rgbd_bag, tmp_path / "x.mp4", settings=RenderSettings(spv={"mode": "nonsense"}))
    with pytest.raises(RenderError, match="unknown parameter"):
        render_bag(rgbd_bag, tmp_path / "x.mp4", settings=RenderSettings(spv={"colour": 1}))
    with pytest.raises(RenderError, match="past the end"):
        render_bag(rgbd_bag, tmp_path / "x.mp4", settings=RenderSettings(spv=SMALL, start_s=10.0))
    with pytest.raises(BagError, match="no such bag"):
        render_bag(tmp_path / "missing", tmp_path / "x.mp4")


def test_h264_video_plays_back_with_every_frame_at_an_odd_size(rgbd_bag, tmp_path):
    """--codec h264 (the video extra): an H.264 mp4, padded to even sides, one frame per tick."""
    dev_requirement("imageio_ffmpeg", "imageio-ffmpeg")   # the video extra
    report = render_bag(rgbd_bag, tmp_path / "h.mp4", settings=RenderSettings(spv={"width": 201}, codec="h264"))
    cap = cv2.VideoCapture(str(tmp_path / "h.mp4"))
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode(errors="replace")
    cap.release()
    assert fourcc.lower() in ("avc1", "h264"), fourcc
    frames = _video_frames(tmp_path / "h.mp4")
    assert len(frames) == report.frames > 0
    assert frames[0].shape[:2] == (report.size[1] + report.size[1] % 2, report.size[0] + report.size[0] % 2)
    assert report.size[0] == 201


def test_h264_without_the_video_extra_is_one_line_naming_its_install(rgbd_bag, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)   # as if not installed
    assert raspv(["render", str(rgbd_bag), "-o", str(tmp_path / "x.mp4"), "--codec", "h264"]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "'video' extra" in err and "EXTRAS=video" in err, err
    assert not (tmp_path / "x.mp4").exists()


def test_command_line(tmp_path, capsys):
    bag = make_rgbd_bag(tmp_path / "bag", frames=5)
    assert raspv(["render", str(bag), "-o", str(tmp_path / "o.mp4"), "--width", "160", "--mode", "depth",
                  "--green", "--side-by-side"]) == 0
    out = capsys.readouterr().out
    assert "21 frames" in out and "x real time" in out
    params = tmp_path / "graph.yaml"
    params.write_text("spv:\n  ros__parameters: {device: argus_ii, width: 120, mode: depth}\n")
    assert raspv(["render", str(bag), "--png-dir", str(tmp_path / "png"), "--params", str(params),
                  "--set", "num_levels=4", "--no-temporal"]) == 0
    assert "21 frames 120x72" in capsys.readouterr().out  # argus_ii: aspect 0.6
    assert raspv(["render", str(bag), "--png-dir", str(tmp_path / "png2"), "--set", "num_levels=1000"]) == 1
    assert "num_levels" in capsys.readouterr().err
    assert raspv(["render", str(bag), "-o", str(tmp_path / "o.avi")]) == 1
    assert "must be an .mp4 file" in capsys.readouterr().err
    assert raspv(["render", str(tmp_path / "nope"), "-o", str(tmp_path / "n.mp4")]) == 1
    assert "raspv render:" in capsys.readouterr().err
