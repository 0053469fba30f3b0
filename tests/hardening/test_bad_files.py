"""The bad-file corpus: every file a graph names, broken in every way a user manages to break it,
through `raspv launch --check` and `raspv launch` — one line naming the graph, the parameter and
the file, exit code 2, no traceback, no node started (issues 16 and 27)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import yaml

from raspv_bringup.graph import GraphError, load_graph
from raspv_sim.world_spec import WORLDS_DIR

BINARY = bytes(range(256)) * 4
GOOD_WORLD = """
floor: {from: [-3, -3], to: [3, 3]}
spawn: {position: [0, 0]}
"""


def _corpus(d: Path) -> list[tuple[str, dict, str, str]]:
    """(case, graph dict, the bad file as the message names it, a fragment of the reason)."""
    (d / "garbage.yaml").write_text("floor: {from: [0, 0], to: [1, 1]\nspawn: [\n")
    (d / "schema.yaml").write_text("floor: 3\nspawn: {position: [0, 0]}\n")
    (d / "binary.yaml").write_bytes(BINARY)
    (d / "gaze_header.csv").write_text("time,yaw,pitch\n0,1,2\n")
    (d / "a_directory.yaml").mkdir()
    (d / "no_mesh.yaml").write_text(GOOD_WORLD + "models:\n  - {file: missing.obj, position: [1, 1, 0]}\n")
    (d / "bin_mesh.yaml").write_text(GOOD_WORLD + "models:\n  - {file: junk.obj, position: [1, 1, 0]}\n")
    (d / "junk.obj").write_bytes(BINARY)
    (d / "text_mesh.yaml").write_text(GOOD_WORLD + "models:\n  - {file: words.obj, position: [1, 1, 0]}\n")
    (d / "words.obj").write_text("this is not a mesh\n")
    (d / "device_keys.yaml").write_text("name: x\nnum_phosphenes: 10\nfov_deg: 20\ngrid: hexagonal\n"
                                         "phosphene_fov_deg: 1\nnum_levels: 8\ncolour: red\n")
    (d / "map_no_image.yaml").write_text("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (d / "not_a_bag.mcap").write_bytes(BINARY)
    (d / "empty_dir").mkdir()
    (d / "cert.pem").write_text("not a certificate\n")
    (d / "key.pem").write_text("-----BEGIN PRIVATE KEY-----\nMC4CAQAwBQYDK2VwBCIEIA==\n-----END PRIVATE KEY-----\n")
    (d / "a_file").write_text("x")
    (d / "junk.onnx").write_bytes(BINARY)
    (d / "junk.yaml").write_text("input_size: [64, 64]\nmean: [0, 0, 0]\nstd: [1, 1, 1]\nlabels: [a, b]\n")
    (d / "junk.oni").write_bytes(BINARY[:0])
    # issue 27: recordings that never open, limits, key pairs, meshes, layouts, images
    good_db3 = _realsense_recording(d / "good.db3")
    data = good_db3.read_bytes()
    (d / "half.db3").write_bytes(data[:len(data) // 2])
    (d / "one_kb.db3").write_bytes(data[:1024])
    (d / "text.db3").write_text("this is a text file, not a recording\n")
    (d / "text.oni").write_text("this is a text file, not a recording\n")
    (d / "cut.oni").write_bytes(b"NI10" + bytes(20) + b"NIR\0" + bytes(10))
    (d / "dai_junk").mkdir()
    (d / "dai_junk" / "color.mcap").write_bytes(BINARY)
    (d / "big_device.yaml").write_text("name: big\nnum_phosphenes: 400000\nfov_deg: 20\ngrid: hexagonal\n"
                                       "phosphene_fov_deg: 1\nnum_levels: 8\n")
    (d / "binary_layout.yaml").write_bytes(bytes([0xF2, 0x80, 0x41]) * 100)
    (d / "device_binary_layout.yaml").write_text(f"name: x\nfov_deg: 20\nnum_levels: 8\nlayout: {d / 'binary_layout.yaml'}\n")
    (d / "nan.obj").write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    (d / "nan_mesh.yaml").write_text(GOOD_WORLD + "models:\n  - {file: nan.obj, position: [1, 1, 0]}\n")
    (d / "past.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    (d / "past_mesh.yaml").write_text(GOOD_WORLD + "models:\n  - {file: past.obj, position: [1, 1, 0]}\n")
    (d / "garbage.png").write_bytes(b"\x89PNG\r\n\x1a\n" + BINARY)
    (d / "map_garbage_image.yaml").write_text("image: garbage.png\nresolution: 0.05\norigin: [0, 0, 0]\n")
    unwritable = _unwritable_directory(d / "read_only")

    def sim(world):
        return {"launch": {"nodes": [{"kind": "sim"}, {"kind": "spv"}]}, "sim": {"ros__parameters": {"world": world}}}

    def spv(device):
        return {"launch": {"nodes": [{"kind": "spv"}]}, "spv": {"ros__parameters": {"device": device}}}

    def planner(map_file):
        return {"launch": {"nodes": [{"kind": "planner"}]}, "planner": {"ros__parameters": {"map": map_file}}}

    def replay(bag):
        return {"launch": {"nodes": [{"kind": "replay"}]}, "replay": {"ros__parameters": {"bag": bag}}}

    def segmentation(model, backend="onnx"):
        return {"launch": {"nodes": [{"kind": "segmentation"}]},
                "segmentation": {"ros__parameters": {"backend": backend, "model": model}}}

    def camera(file, driver="auto"):
        return {"launch": {"nodes": [{"kind": "camera"}]}, "camera": {"ros__parameters": {"file": file, "driver": driver}}}

    p = str
    tls_mismatch = _mismatched_tls_pair(d)
    return [
        ("missing world", sim(p(d / "missing.yaml")), "missing.yaml", "no such world file"),
        ("garbage world YAML", sim(p(d / "garbage.yaml")), "garbage.yaml", "invalid YAML"),
        ("wrong world schema", sim(p(d / "schema.yaml")), "schema.yaml", "floor"),
        ("binary world", sim(p(d / "binary.yaml")), "binary.yaml", "not a text file"),
        ("world is a directory", sim(p(d / "a_directory.yaml")), "a_directory.yaml", "is a directory"),
        ("world names a missing mesh", sim(p(d / "no_mesh.yaml")), "missing.obj", "not found"),
        ("world names a binary mesh", sim(p(d / "bin_mesh.yaml")), "junk.obj", "not a text file"),
        ("world names a text file as mesh", sim(p(d / "text_mesh.yaml")), "words.obj", "not a Wavefront OBJ mesh"),
        ("unknown shipped world", sim("atlantis"), "atlantis", "shipped worlds are"),
        ("missing device", spv(p(d / "missing_device.yaml")), "missing_device.yaml", "does not exist"),
        ("device is a directory", spv("/tmp"), "/tmp", "is a directory"),
        ("garbage device YAML", spv(p(d / "garbage.yaml")), "garbage.yaml", "invalid YAML"),
        ("binary device", spv(p(d / "binary.yaml")), "binary.yaml", "not a text file"),
        ("device with unknown keys", spv(p(d / "device_keys.yaml")), "device_keys.yaml", "unknown key(s) colour"),
        ("missing map", planner(p(d / "missing_map.yaml")), "missing_map.yaml", "no such map file"),
        ("map without its image", planner(p(d / "map_no_image.yaml")), "nowhere.pgm", "not a readable image"),
        ("binary map", planner(p(d / "binary.yaml")), "binary.yaml", "not a text file"),
        ("missing bag", replay(p(d / "missing_bag")), "missing_bag", "no such bag"),
        ("bag file that is not a bag", replay(p(d / "not_a_bag.mcap")), "not_a_bag.mcap", "not an MCAP file"),
        ("bag directory without a bag", replay(p(d / "empty_dir")), "empty_dir", "not a bag"),
        ("TLS certificate that is not PEM", {"launch": {"nodes": [{"kind": "bridge"}]},
                                             "bridge": {"ros__parameters": {"tls_cert": p(d / "cert.pem"),
                                                                            "tls_key": p(d / "key.pem")}}},
         "cert.pem", "not a PEM file"),
        ("missing segmentation model", segmentation(p(d / "nowhere.onnx")), "nowhere.onnx", "no such model file"),
        ("segmentation model that is not ONNX", segmentation(p(d / "junk.onnx")), "junk.onnx", "ONNX"),
        ("missing camera recording", camera(p(d / "nowhere.bag")), "nowhere.bag", "no such recording"),
        ("camera recording of no known SDK", camera(p(d / "a_file")), "a_file", "cannot tell which SDK"),
        ("camera recording of another SDK", camera(p(d / "junk.oni"), "realsense"), "junk.oni", "not a realsense"),
        ("missing implant layout", {"launch": {"nodes": [{"kind": "spv"}]},
                                    "spv": {"ros__parameters": {"layout": p(d / "no_layout.yaml")}}},
         "no_layout.yaml", "no"),
        ("log directory below a file", {"launch": {"nodes": [{"kind": "sim"}]},
                                        "sim": {"ros__parameters": {"log_dir": p(d / "a_file" / "runs")}}},
         "a_file", "not writable"),
        ("RealSense recording cut in half", camera(p(d / "half.db3")), "half.db3", "not a readable RealSense recording"),
        ("RealSense recording cut to 1 kB", camera(p(d / "one_kb.db3")), "one_kb.db3", "not a readable RealSense"),
        ("text file as a RealSense recording", camera(p(d / "text.db3")), "text.db3", "not a database"),
        ("text file as an OpenNI recording", camera(p(d / "text.oni")), "text.oni", "not an OpenNI recording"),
        ("OpenNI recording cut off", camera(p(d / "cut.oni")), "cut.oni", "cut off"),
        ("DepthAI recording of garbage", camera(p(d / "dai_junk")), "color.mcap", "not an MCAP file"),
        ("device beyond the phosphene limit", spv(p(d / "big_device.yaml")), "big_device.yaml",
         "num_phosphenes 400000 is above the limit of 20000"),
        ("binary implant layout", {"launch": {"nodes": [{"kind": "spv"}]},
                                   "spv": {"ros__parameters": {"layout": p(d / "binary_layout.yaml")}}},
         "binary_layout.yaml", "not a UTF-8 text file"),
        ("device naming a binary layout", spv(p(d / "device_binary_layout.yaml")), "binary_layout.yaml",
         "not a UTF-8 text file"),
        ("binary gaze trace", {"launch": {"nodes": [{"kind": "subject"}]},
                               "subject": {"ros__parameters": {"gaze": "trace", "gaze_trace": p(d / "binary.yaml")}}},
         "binary.yaml", "not a text file"),
        ("gaze trace with another header", {"launch": {"nodes": [{"kind": "subject"}]},
                                            "subject": {"ros__parameters": {"gaze": "trace",
                                                                            "gaze_trace": p(d / "gaze_header.csv")}}},
         "gaze_header.csv", "expected t,x,y,z,valid"),
        ("mesh with a NaN vertex", sim(p(d / "nan_mesh.yaml")), "nan.obj", "vertex 2 is not finite"),
        ("mesh face index past the vertex count", sim(p(d / "past_mesh.yaml")), "past.obj",
         "face index 4 is past the vertex count (3)"),
        ("map image that is garbage", planner(p(d / "map_garbage_image.yaml")), "garbage.png", "not a readable image"),
        ("log directory that exists but cannot be written", {"launch": {"nodes": [{"kind": "sim"}]},
                                                             "sim": {"ros__parameters": {"log_dir": unwritable}}},
         unwritable, "is not writable"),
        *([("TLS certificate and key that do not match", {"launch": {"nodes": [{"kind": "bridge"}]},
                                                          "bridge": {"ros__parameters": tls_mismatch}},
            "a.crt", "does not match the private key")] if tls_mismatch else []),
    ]


def _realsense_recording(path: Path) -> Path:
    """A small RealSense recording written by the SDK's own recorder (3 frames, 64×48)."""
    import numpy as np

    from raspv_camera.sdk_recordings import SourceFrame, write_realsense_recording
    from raspv_common.intrinsics import CameraIntrinsics

    frames = [SourceFrame(np.full((48, 64, 3), 40 * i, np.uint8), np.full((48, 64), 1000 + i, np.uint16), 1.0 + i / 30)
              for i in range(3)]
    return write_realsense_recording(path, frames, CameraIntrinsics(64, 48, 60.0, 60.0, 31.5, 23.5))


def _unwritable_directory(path: Path) -> str:
    """A directory that exists and cannot be written: its mode bits for a user; for root (whom
    mode bits do not stop) an immutable directory where chattr works, else /sys."""
    path.mkdir()
    path.chmod(0o500)
    try:
        (path / "probe").touch()
    except OSError:
        return str(path)                               # the mode bits hold
    (path / "probe").unlink()
    if shutil.which("chattr") and subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0:
        return str(path)
    return "/sys"


def _mismatched_tls_pair(d: Path) -> dict | None:
    """tls_cert of one openssl key pair with tls_key of another (None without openssl)."""
    if shutil.which("openssl") is None:
        return None
    for name in ("a", "b"):
        subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes",
                        "-keyout", str(d / f"{name}.key"), "-out", str(d / f"{name}.crt"), "-days", "2",
                        "-subj", "/CN=localhost"], check=True, capture_output=True, timeout=60)
    return {"tls_cert": str(d / "a.crt"), "tls_key": str(d / "b.key")}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad-files")
    out = []
    try:
        for case, spec, bad, reason in _corpus(d):
            graph = d / f"{case.replace(' ', '_')}.graph.yaml"
            graph.write_text(yaml.safe_dump(spec, sort_keys=False))
            out.append((case, graph, bad, reason))
        yield out
    finally:
        if shutil.which("chattr"):                       # the immutable directory, if one was made
            subprocess.run(["chattr", "-i", str(d / "read_only")], capture_output=True)


def _launch(graph: Path, *extra: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(graph), *extra],
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_every_case_of_the_corpus_is_one_line_through_check_and_launch(corpus, capfd, monkeypatch):
    """`raspv launch --check` as a user runs it (a process per case, three at a time: each is
    mostly interpreter start-up), and `raspv launch` itself in this process — the same lines,
    exit code 2, and the supervisor that starts nodes never built."""
    from raspv_bringup import launch_cli

    def check(item):
        case, graph, bad, reason = item
        res = _launch(graph, "--check")
        return case, res.returncode, res.stdout, res.stderr

    def verdict(case, how, code, stdout, stderr, graph, bad, reason):
        out = stdout + stderr
        lines = stderr.strip().splitlines()
        ok = (code == 2 and "Traceback" not in out and len(lines) == 1 and str(graph) in lines[0]
              and bad in lines[0] and reason in lines[0] and "started" not in out)
        return None if ok else f"{case} {how}: exit {code}: {out.strip()[-500:]}"

    class NoSupervisor:
        def __init__(self, *_, **__):
            raise AssertionError("the launch went on to start nodes")

    monkeypatch.setattr(launch_cli, "Supervisor", NoSupervisor)
    failures = []
    with ThreadPoolExecutor(max_workers=3) as pool:
        checked = pool.map(check, corpus)
        for case, graph, bad, reason in corpus:
            capfd.readouterr()
            code = launch_cli.launch(str(graph), [])
            out, err = capfd.readouterr()
            failures.append(verdict(case, "(launch)", code, out, err, graph, bad, reason))
        for (case, code, out, err), (_, graph, bad, reason) in zip(checked, corpus):
            failures.append(verdict(case, "--check", code, out, err, graph, bad, reason))
    failures = [f for f in failures if f]
    assert not failures, "\n".join(failures)


def test_a_world_with_several_broken_entries_reports_each_on_its_line(tmp_path):
    world = tmp_path / "three.yaml"
    world.write_text(GOOD_WORLD + "furniture:\n  - {type: table, position: [1, 1], colour: red}\n"
                     "  - {type: chiar, position: [1, 2]}\ngoals:\n  - {name: g, position: [1, 1], radius: big}\n")
    graph = tmp_path / "g.yaml"
    graph.write_text(yaml.safe_dump({"launch": {"nodes": [{"kind": "sim"}]}, "sim": {"ros__parameters": {"world": str(world)}}}))
    res = _launch(graph, "--check")
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and "Traceback" not in res.stderr and len(lines) == 3, res.stderr
    assert all(str(graph) in line and "three.yaml" in line for line in lines)
    assert "furniture[0]" in lines[0] and "did you mean 'color'" in lines[0]
    assert "furniture[1]" in lines[1] and "chiar" in lines[1]
    assert "goals[0]" in lines[2] and "'radius' must be a number, got big" in lines[2]


def test_a_protocol_with_a_misspelt_key_and_a_word_for_a_number(tmp_path):
    experiments = Path(__file__).resolve().parents[2] / "experiments"
    protocol = tmp_path / "typos.yaml"
    protocol.write_text((experiments / "example.yaml").read_text()
                        .replace("worlds/hallway.yaml", str(experiments / "worlds" / "hallway.yaml"))
                        .replace("goal: {position: [8.6, 1.5], radius: 0.8}", "goal: {positon: [8.6, 1.5], radius: big}"))
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "experiment", "check", str(protocol)],
                         capture_output=True, text=True, timeout=120)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and "Traceback" not in res.stderr and len(lines) == 2, res.stderr
    assert all(line.startswith(f"{protocol}: tasks.hallway.goal.") for line in lines)
    assert "positon: unknown key" in lines[0] and "did you mean 'position'" in lines[0]
    assert "radius: expected a positive number, got 'big', which is text, not a number" in lines[1]


def test_a_binary_graph_file_and_a_good_graph(tmp_path):
    bad = tmp_path / "graph.yaml"
    bad.write_bytes(BINARY)
    res = _launch(bad, "--check")
    assert res.returncode == 2 and "not a text file" in res.stderr and str(bad) in res.stderr
    good = tmp_path / "good.yaml"
    world = tmp_path / "world.yaml"
    world.write_text(GOOD_WORLD + f"models:\n  - {{file: {WORLDS_DIR / 'meshes' / 'plant.obj'}, position: [1, 1, 0]}}\n")
    good.write_text(yaml.safe_dump({"launch": {"nodes": [{"kind": "sim"}]}, "sim": {"ros__parameters": {"world": str(world)}}}))
    res = _launch(good, "--check")
    assert res.returncode == 0 and "OK (sim)" in res.stdout, res.stdout + res.stderr


def test_file_checks_follow_overrides_and_empty_means_unset(tmp_path):
    graph = tmp_path / "g.yaml"
    graph.write_text(yaml.safe_dump({"launch": {"nodes": [{"kind": "replay"}, {"kind": "spv"}]}}))
    assert load_graph(graph)                                   # bag "" is "not set": the node says it is required
    with pytest.raises(GraphError, match=r"spv\.ros__parameters\.device: device file nowhere/x\.yaml does not exist"):
        load_graph(graph, ["spv.device:=nowhere/x.yaml"])


def test_a_file_kind_can_be_registered_and_can_read_the_other_parameters(tmp_path):
    from raspv_bringup.file_kinds import FILE_KINDS, check_file, register_file_kind

    def check_model(value, params):
        if params.get("backend") == "onnx" and not value.endswith(".onnx"):
            raise ValueError(f"{value}: the onnx backend needs an .onnx model")

    try:
        register_file_kind("test_model", check_model, "model file", with_params=True)
        assert check_file("test_model", "net.pt", {"backend": "onnx"}) == "net.pt: the onnx backend needs an .onnx model"
        assert check_file("test_model", "net.pt", {"backend": "torchscript"}) is None
        assert "unknown file kind 'nope'" in check_file("nope", "x")
    finally:
        FILE_KINDS.pop("test_model", None)


PEM = "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n"


def test_half_a_tls_pair_and_other_parameters_that_only_work_together_are_one_line(tmp_path):
    """Issue 36: `--check` passed tls_cert without tls_key (the bridge then restarted five times
    and the graph stopped); so did slam's localisation without a map, and a planner given both a
    map and a world. Each is one line naming the parameter and what it needs."""
    (tmp_path / "cert.pem").write_text(PEM)
    graph = tmp_path / "bridge.yaml"
    graph.write_text(yaml.safe_dump({"launch": {"nodes": [{"kind": "bridge"}, {"kind": "slam"}, {"kind": "planner"}]}}))
    res = _launch(graph, f"bridge.tls_cert:={tmp_path / 'cert.pem'}", "--check")
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and "Traceback" not in res.stderr and len(lines) == 1, res.stderr
    assert f"{graph}: bridge.ros__parameters.tls_cert: set without tls_key" in lines[0], lines
    for overrides, line in [
        ([f"bridge.tls_key:={tmp_path / 'cert.pem'}"], "bridge.ros__parameters.tls_key: set without tls_cert: "
                                                       "tls_key and tls_cert only work together (set both or neither)"),
        (["slam.mode:=localisation"], "slam.ros__parameters.mode: 'localisation' needs map, which is not set"),
        ([f"planner.map:={tmp_path / 'room.yaml'}", "planner.world:=office"],
         "planner.ros__parameters.map: map and world are both set: give one of them"),
    ]:
        with pytest.raises(GraphError) as err:
            load_graph(graph, overrides, check_files=False)
        assert err.value.errors == [f"{graph}: {line}"]
    pair = [f"bridge.tls_cert:={tmp_path / 'cert.pem'}", f"bridge.tls_key:={tmp_path / 'cert.pem'}"]
    assert load_graph(graph, pair + ["slam.mode:=localisation", "slam.map:=office"], check_files=False)
