"""The launcher with real node processes on a private ROS domain."""
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import psutil
import pytest
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image

from raspv_bringup.testing import RunningGraph
from raspv_common import topics
from raspv_common.conversions import camera_info_to_intrinsics, depth_from_image, image_to_array

pytestmark = pytest.mark.integration

SOURCE = {"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}]},
          "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}}}


class TestOneSourceGraph:
    """One source graph (started once) for three tests in this order: its topics, its parameters at
    run time, then Ctrl-C stops it and the launcher reports each node's resources."""

    @pytest.fixture(scope="class")
    def source(self, tmp_path_factory, ros_domain):
        g = RunningGraph(SOURCE, tmp_path_factory.mktemp("source"))
        yield g
        stopped_by_test = g.returncode is not None       # the last test stopped it and checked its exit code
        code = g.stop()
        assert stopped_by_test or code == 0, f"the source graph ended with exit code {code}:\n{g.output[-3000:]}"

    def test_source_graph_publishes_consistent_rgbd(self, source, probe):
        g = source
        color = probe.wait_for_message(topics.COLOR, Image, timeout=60)
        depth = probe.wait_for_message(topics.DEPTH, Image)
        info = probe.wait_for_message(topics.CAMERA_INFO, CameraInfo)
        pose = probe.wait_for_message(topics.CAMERA_POSE, PoseStamped)
        assert image_to_array(color).shape == (120, 160, 3)
        d = depth_from_image(depth)
        assert d.shape == (120, 160) and np.nanmin(d) > 0.5
        assert camera_info_to_intrinsics(info).hfov_deg == pytest.approx(60.0)
        assert pose.header.frame_id == "map" and pose.pose.position.z == pytest.approx(1.6)
        assert g.running()

    def test_parameters_change_at_run_time_and_bad_values_are_refused(self, source, probe):
        probe.wait_for_message(topics.COLOR, Image, timeout=60)
        [(name, ok, reason)] = probe.set_params("cam", {"walk_speed": 9.0})
        assert not ok and "walk_speed" in reason
        [(_, ok, reason)] = probe.set_params("cam", {"rate": 2.0})
        assert not ok and "read-only" in reason
        [(_, ok, _)] = probe.set_params("cam", {"walk_speed": 0.0})
        assert ok
        assert probe.get_params("cam", ["walk_speed"]) == {"walk_speed": 0.0}

    def test_ctrl_c_stops_everything_and_reports_resources(self, source, probe):
        g = source
        probe.wait_for_message(topics.COLOR, Image, timeout=60)
        assert g.stop(signal.SIGINT) == 0
        out = g.output
        assert re.search(r"cam\s+synthetic\s+0\s+\d+\s+[\d.]+", out), out
        assert "resources per node" in out


def test_sigterm_also_stops_cleanly(graph, probe):
    g = graph(SOURCE)
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    assert g.stop(signal.SIGTERM) == 0


def _node_pid(g) -> int:
    return int(g.wait_for_output(r"cam \(synthetic, pid (\d+)\)").group(1))


def test_a_dying_node_stops_the_graph_with_its_exit_code(graph, probe):
    g = graph(SOURCE)
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    os.kill(_node_pid(g), signal.SIGKILL)
    g.wait_for_output(r"node 'cam' ended \(killed by signal 9\); stopping the graph")
    g.proc.wait(timeout=30)
    assert g.stop() == 1


def test_a_node_marked_restart_is_restarted(graph, probe):
    spec = {**SOURCE, "launch": {"nodes": [{"kind": "synthetic", "name": "cam", "restart": True}]}}
    g = graph(spec)
    probe.wait_for_message(topics.COLOR, Image, timeout=60)
    os.kill(_node_pid(g), signal.SIGKILL)
    g.wait_for_output(r"node 'cam' ended \(killed by signal 9\); restarting it")
    col = probe.subscribe(topics.COLOR, Image)
    col.wait(2, timeout=60)
    assert g.running()


@pytest.mark.parametrize("yaml_text,fragment", [
    ("launch:\n  nodes: [{kind: synthetic}]\nsynthetic:\n  ros__parameters: {rate: fast}\n",
     "synthetic.ros__parameters.rate: expected float"),
    ("launch:\n  nodes: [{kind: synthetic}]\nsynthetic:\n  ros__parameters: {hfov_deg: 500}\n",
     "hfov_deg: 500.0 is out of range; expected float in [10.0, 150.0]"),
    ("launch:\n  nodes: [{kind: synthetic}]\nsynthetic:\n  ros__parameters: {colour: red}\n",
     "colour: unknown parameter; this node has:"),
    ("launch:\n  nodes: [{kind: warp_drive}]\n", "launch.nodes[0].kind: unknown node kind 'warp_drive'; available:"),
    ("launch:\n  nodes: [{kind: synthetic}\n", "invalid YAML"),
    ("launch:\n  nodes: [{kind: synthetic}]\nspv:\n  ros__parameters: {mode: grey}\n", "no node named 'spv'"),
])
def test_bad_graph_files_get_one_line_errors(tmp_path, yaml_text, fragment):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml_text)
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(path)],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert "Traceback" not in res.stderr + res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and fragment in lines[0], res.stderr


def test_missing_graph_file(tmp_path):
    res = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(tmp_path / "nope.yaml")],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "no such graph file" in res.stderr and "Traceback" not in res.stderr


def test_command_line_overrides_are_validated(tmp_path):
    path = tmp_path / "g.yaml"
    import yaml
    path.write_text(yaml.safe_dump(SOURCE))
    ok = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(path), "cam.walk_speed:=1.0",
                         "--check"], capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0, ok.stderr
    bad = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "launch", str(path), "cam.walk_speed:=fast",
                          "--check"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "walk_speed" in bad.stderr


def test_empty_list_in_a_parameter_file_is_an_empty_list(graph, probe):
    """rcl reads `name: []` as "not set"; the node base makes it an empty list."""
    g = graph({"launch": {"nodes": [{"kind": "spv"}]}, "spv": {"ros__parameters": {"overlays": []}}})
    g.wait_for_output(r"\[spv\].*phosphenes")
    assert probe.get_params("spv", ["overlays"]) == {"overlays": []}
    [(_, ok, reason)] = probe.set_params("spv", {"overlays": ["path"]})
    assert ok, reason
    assert g.running()


def test_a_graph_does_not_outlive_the_process_that_started_it(tmp_path, ros_domain):
    """A benchmark or test killed with SIGKILL (no cleanup runs) leaves no launcher or node behind."""
    script = ("import sys, time; from pathlib import Path; from raspv_bringup.testing import RunningGraph; "
              f"g = RunningGraph({SOURCE!r}, Path({str(tmp_path)!r})); print(g.proc.pid, flush=True); time.sleep(600)")
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain)}
    owner = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=env)
    try:
        launcher = psutil.Process(int(owner.stdout.readline()))
        deadline = time.monotonic() + 60
        while not launcher.children():                   # the launcher started its node
            assert time.monotonic() < deadline, "the launcher started no node"
            time.sleep(0.1)
        node = launcher.children()[0]
        owner.kill()
        owner.wait()
        gone, alive = psutil.wait_procs([launcher, node], timeout=30)
        assert not alive, f"still running after their owner was killed: {[p.pid for p in alive]}"
    finally:
        if owner.poll() is None:
            owner.kill()


def test_a_launcher_started_with_sigint_ignored_stops_on_an_early_sigint(tmp_path, ros_domain):
    """A shell starts a background job (`raspv launch g.yaml &`) with SIGINT ignored: a `kill -INT`
    while the launcher still imported and checked its graph (before its own handler; ~15 s at
    load 20) was lost, and the graph ran on until SIGTERM. The SIGINT is sent when the launcher
    has imported the graph module (its import-time line), before it reads the graph file."""
    import yaml
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump(SOURCE))
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain), "ROS_LOG_DIR": str(tmp_path / "ros_log")}
    proc = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "raspv_bringup.cli", "launch", str(path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))   # as a shell does
    try:
        lines = []
        for line in proc.stderr:
            lines.append(line)
            if line.rstrip().endswith("| raspv_bringup.graph"):
                break
        assert lines and lines[-1].rstrip().endswith("raspv_bringup.graph"), "".join(lines[-20:])
        proc.send_signal(signal.SIGINT)
        rest = proc.communicate(timeout=60)[1]   # (the bug: it ran on, starting the graph)
        out = "".join(line for line in lines + rest.splitlines(keepends=True) if not line.startswith("import time:"))
        # stopped by the interrupt before anything started (130), or — on a machine slow to deliver
        # the signal — by its own handler, which stops the graph it started (0); never a traceback
        assert proc.returncode in (0, 130) and "Traceback" not in out, (proc.returncode, out)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=30)
