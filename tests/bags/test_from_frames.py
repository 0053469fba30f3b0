"""Bags from RGB-D image files: layouts, timestamps, depth formats, intrinsics, bad input."""
from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from raspv_bringup.cli import main as raspv
from raspv_bags.from_frames import (CAMERA_DISTORTION, FramesError, associate, discover_frames, intrinsics_for,
                                          load_intrinsics_file, stamp_from_name, write_frames_bag)
from raspv_bags.reader import BagReader
from raspv_common import topics as T
from raspv_common.conversions import camera_info_distortion, camera_info_to_intrinsics, depth_from_image, rgb_from_image
from raspv_common.rgbd_files import read_color, read_depth_scaled

PRIMESENSE = {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}


@pytest.fixture
def tum_sequence(tmp_path, data_dir):
    """A TUM-layout sequence of three frames made from the real TUM sample, with ground truth."""
    seq = tmp_path / "rgbd_dataset_freiburg1_desk"
    (seq / "rgb").mkdir(parents=True)
    (seq / "depth").mkdir()
    stamps = [1305031102.175304, 1305031102.211214, 1305031102.243211]
    dstamps = [1305031102.160407, 1305031102.226738, 1305031102.262886]
    for t, d in zip(stamps, dstamps):
        shutil.copy(data_dir / "rgbd" / "tum_color.png", seq / "rgb" / f"{t:.6f}.png")
        shutil.copy(data_dir / "rgbd" / "tum_depth.png", seq / "depth" / f"{d:.6f}.png")
    (seq / "rgb.txt").write_text("# color images\n# file: 'x'\n# timestamp filename\n" +
                                 "".join(f"{t:.6f} rgb/{t:.6f}.png\n" for t in stamps))
    (seq / "depth.txt").write_text("# depth maps\n" + "".join(f"{t:.6f} depth/{t:.6f}.png\n" for t in dstamps))
    (seq / "groundtruth.txt").write_text("# ground truth trajectory\n"
                                         "1305031102.1000 1.0 0.0 1.5 0 0 0 1\n"
                                         "1305031102.3000 2.0 0.0 1.5 0 0 0.7071068 0.7071068\n")
    return seq


def test_tum_sequence_associates_frames_and_interpolates_poses(tum_sequence, tmp_path):
    frames = discover_frames(tum_sequence)
    assert frames.layout == "tum" and frames.depth_format == "tum" and frames.camera_hint == "tum-fr1"
    assert len(frames.pairs) == 3
    assert all(abs(p.stamp_s - float(p.depth.stem)) <= 0.02 for p in frames.pairs)
    p0 = frames.pairs[0]
    assert p0.pose[0, 3] == pytest.approx(1.0 + (p0.stamp_s - 1305031102.1) / 0.2)
    with pytest.raises(FramesError, match="--camera tum-fr1"):
        write_frames_bag(frames, None, tmp_path / "nointr")
    report = write_frames_bag(frames, {"fx": 517.3, "fy": 516.5, "cx": 318.6, "cy": 255.3}, tmp_path / "bag")
    assert report.frames == 3 and report.with_pose == 3 and report.size == (640, 480)
    with BagReader(tmp_path / "bag") as r:
        assert {t: i.count for t, i in r.topics.items()} == {T.COLOR: 3, T.DEPTH: 3, T.CAMERA_INFO: 3,
                                                             T.CAMERA_POSE: 3}
        depth = depth_from_image(r.decode(next(r.messages([T.DEPTH]))))
        color = rgb_from_image(r.decode(next(r.messages([T.COLOR]))))
        info = camera_info_to_intrinsics(r.decode(next(r.messages([T.CAMERA_INFO]))))
        pose = r.decode(next(r.messages([T.CAMERA_POSE])))
    expected = read_depth_scaled(tum_sequence / "depth" / frames.pairs[0].depth.name, 1 / 5000)
    np.testing.assert_array_equal(depth, expected)
    np.testing.assert_array_equal(color, read_color(frames.pairs[0].color))
    assert (info.fx, info.cy) == (517.3, 255.3)
    assert pose.header.frame_id == "map" and pose.pose.position.z == pytest.approx(1.5)


def test_a_tum_preset_writes_its_lens_distortion_and_slam_reads_it_back(tum_sequence, tmp_path):
    """fr1's images are raw (k1 0.26): the bag's camera info carries TUM's distortion, and the SLAM
    recording of the bag undistorts with it without being told the camera again."""
    from raspv_slam.recordings import open_recording

    out = tmp_path / "bag"
    assert raspv(["bag", "from-frames", str(tum_sequence), "-o", str(out), "--camera", "tum-fr1"]) == 0
    with BagReader(out) as r:
        info = r.decode(next(r.messages([T.CAMERA_INFO])))
    assert camera_info_distortion(info) == pytest.approx(CAMERA_DISTORTION["tum-fr1"])
    assert open_recording(out).distortion == pytest.approx(CAMERA_DISTORTION["tum-fr1"])
    assert raspv(["bag", "from-frames", str(tum_sequence), "-o", str(tmp_path / "b2"), "--camera", "tum-fr1",
                  "--distortion", "0.1", "0", "0", "0"]) == 0
    assert open_recording(tmp_path / "b2").distortion == pytest.approx((0.1, 0, 0, 0, 0))
    assert raspv(["bag", "from-frames", str(tum_sequence), "-o", str(tmp_path / "b3"), "--camera", "tum-fr3"]) == 0
    assert open_recording(tmp_path / "b3").distortion == ()                       # fr3's images are rectified
    assert raspv(["bag", "from-frames", str(tum_sequence), "-o", str(tmp_path / "b4"), "--camera", "tum-fr1",
                  "--distortion", "0.1", "0"]) == 1


def test_flat_folder_pairs_take_timestamps_from_names(data_dir, tmp_path):
    frames = discover_frames(data_dir / "rgbd" / "kinect_table")
    assert frames.layout == "pairs" and frames.depth_format == "mm" and len(frames.pairs) == 3
    gaps = np.diff([p.stamp_s for p in frames.pairs])
    assert gaps == pytest.approx([0.254471, 0.263712], abs=1e-5)
    assert all(p.color.name.replace("_rgb", "_depth") == p.depth.name for p in frames.pairs)
    report = write_frames_bag(frames, PRIMESENSE, tmp_path / "bag", storage="sqlite3")
    assert report.frames == 3
    with BagReader(tmp_path / "bag") as r:
        d = depth_from_image(r.decode(next(r.messages([T.DEPTH]))))
    assert 0.5 < np.nanmedian(d) < 3.0


def test_nyu_disparity_and_frame_rate_for_unstamped_files(data_dir, tmp_path):
    rgbd = data_dir / "rgbd"
    frames = discover_frames(colors=[rgbd / "nyu_color.ppm", rgbd / "tum_color.png"],
                             depths=[rgbd / "nyu_depth.pgm", rgbd / "nyu_depth.pgm"],
                             depth_format="nyu", fps=15.0, start_s=100.0)
    assert [p.stamp_s for p in frames.pairs] == pytest.approx([100.0, 100.0 + 1 / 15])
    assert any("15 frames per second" in n for n in frames.notes)
    write_frames_bag(frames, PRIMESENSE, tmp_path / "bag")
    with BagReader(tmp_path / "bag") as r:
        d = depth_from_image(r.decode(next(r.messages([T.DEPTH]))))
    assert 2.0 < np.nanmedian(d) < 5.0  # the NYU basement: median ≈ 3.3 m


def test_sub_folders_and_size_mismatches(tmp_path, data_dir):
    seq = tmp_path / "seq"
    (seq / "color").mkdir(parents=True)
    (seq / "depth").mkdir()
    color = cv2.imread(str(data_dir / "rgbd" / "tum_color.png"))
    depth = cv2.imread(str(data_dir / "rgbd" / "tum_depth.png"), cv2.IMREAD_UNCHANGED)
    for i in range(3):
        cv2.imwrite(str(seq / "color" / f"{i:04d}.png"), color)
    cv2.imwrite(str(seq / "depth" / "0000.png"), depth)
    cv2.imwrite(str(seq / "depth" / "0001.png"), cv2.resize(depth, (320, 240), interpolation=cv2.INTER_NEAREST))
    cv2.imwrite(str(seq / "depth" / "0002.png"), depth[:, :400])
    frames = discover_frames(seq, depth_format="tum", fps=10.0, start_s=0.0)
    assert frames.layout == "folders" and len(frames.pairs) == 3
    report = write_frames_bag(frames, PRIMESENSE, tmp_path / "bag")
    assert report.frames == 2 and report.skipped == 1
    assert any("resampled" in n for n in report.notes)
    assert any("differ in shape" in n for n in report.notes)


def test_unusable_input_gives_a_clear_error(tmp_path, data_dir):
    with pytest.raises(FramesError, match="no RGB-D frames found"):
        discover_frames(tmp_path)
    with pytest.raises(FramesError, match="not a folder"):
        discover_frames(tmp_path / "missing")
    with pytest.raises(FramesError, match="give them in pairs"):
        discover_frames(colors=[data_dir / "rgbd" / "tum_color.png"], depths=[])
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "a_rgb.png").write_bytes(b"not an image")
    (bad / "a_depth.png").write_bytes(b"not an image either")
    frames = discover_frames(bad)
    with pytest.raises(FramesError, match="no usable frame"):
        write_frames_bag(frames, PRIMESENSE, tmp_path / "out")


def test_intrinsics_files_and_rescaling(tmp_path):
    plain = tmp_path / "cam.yaml"
    plain.write_text("fx: 600\nfy: 601\ncx: 320\ncy: 240\nwidth: 640\nheight: 480\n")
    ros = tmp_path / "ros.yaml"
    ros.write_text("image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                   "  data: [500, 0, 319.5, 0, 500, 239.5, 0, 0, 1]\n")
    assert load_intrinsics_file(plain)["fy"] == 601
    cam = intrinsics_for(load_intrinsics_file(ros), 320, 240)
    assert (cam.fx, cam.cx, cam.cy) == (250.0, 159.5, 119.5)
    broken = tmp_path / "broken.yaml"
    broken.write_text("fx: 1\n")
    with pytest.raises(FramesError, match="missing fy, cx, cy"):
        load_intrinsics_file(broken)


def test_timestamps_from_names_and_association():
    assert stamp_from_name("1305031102.175304.png") == pytest.approx(1305031102.175304)
    assert stamp_from_name("frame_20121214T142255.814212_rgb.tiff") is not None
    assert stamp_from_name("0003.png") is None
    assert associate([0.0, 1.0, 2.0], [1.01, 0.005, 5.0], 0.02) == [(0, 1), (1, 0)]


def test_command_line(tmp_path, data_dir, capsys):
    out = tmp_path / "bag"
    assert raspv(["bag", "from-frames", str(data_dir / "rgbd" / "kinect_table"), "-o", str(out),
                  "--camera", "primesense"]) == 0
    assert "3 frames 640x480" in capsys.readouterr().out
    assert raspv(["bag", "info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "/camera/color/image_raw" in info and "sensor_msgs/msg/CameraInfo" in info
    assert raspv(["bag", "from-frames", str(data_dir / "rgbd" / "kinect_table"), "-o", str(tmp_path / "b2")]) == 1
    assert "no camera intrinsics" in capsys.readouterr().err
    assert raspv(["bag", "from-frames", str(data_dir / "rgbd" / "kinect_table"), "-o", str(tmp_path / "b3"),
                  "--fx", "500"]) == 1
    assert "give all of --fx --fy --cx --cy" in capsys.readouterr().err
