"""The bad-file corpus: every file a graph names, broken in every way a user manages to break it,
through `raspv launch --check` and `raspv launch` — one line naming the graph, the parameter and
the file, exit code 2, no traceback, no node started."""
from __future__ import annotations

import subprocess
import sys
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
    ]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad-files")
    out = []
    for case, spec, bad, reason in _corpus(d):
        graph = d / f"{case.replace(' ', '_')}.graph.yaml"
        graph.write_text(yaml.safe_dump(spec, sort_keys=False))
        out.append((case, graph, bad, reason))
    return out


def _launch(graph: Path, *extra: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(graph), *extra],
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_every_case_of_the_corpus_is_one_line_through_check_and_launch(corpus):
    failures = []
    for case, graph, bad, reason in corpus:
        for extra in (("--check",), ()):
            res = _launch(graph, *extra)
            out = res.stdout + res.stderr
            lines = res.stderr.strip().splitlines()
            ok = (res.returncode == 2 and "Traceback" not in out and len(lines) == 1 and str(graph) in lines[0]
                  and bad in lines[0] and reason in lines[0] and "started" not in out)
            if not ok:
                failures.append(f"{case} {' '.join(extra) or '(launch)'}: exit {res.returncode}: {out.strip()[-500:]}")
    assert not failures, "\n".join(failures)


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
